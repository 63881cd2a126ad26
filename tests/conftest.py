import os

import matplotlib

matplotlib.use("Agg")
# A diagram's own module compiles in 1-6 s: the suite runs every diagram on the generic
# driver (compiled once) unless a test asks for the module (tests/test_engine_paths.py),
# and starts no background compilation (subprocesses inherit this)
os.environ.setdefault("CONTROLKIT_MODULES", "never")
