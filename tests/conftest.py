import os

import matplotlib

matplotlib.use("Agg")
# A diagram's own module compiles in 1-6 s: the suite runs every diagram on the generic
# driver (compiled once) unless a test asks for the module (tests/test_engine_paths.py),
# and starts no background compilation (subprocesses inherit this)
os.environ.setdefault("CONTROLKIT_MODULES", "never")


def pytest_collection_finish(session):
    """Start the documentation build (tests/test_docs.py) as soon as a test that reads its
    pages is collected: it runs in a thread, on the machine's other core, while the tests
    before it run (the suite is otherwise one process, one core at a time)."""
    if session.config.option.collectonly:
        return
    for item in session.items:
        if item.path.name == "test_docs.py" and "html" in getattr(item, "fixturenames", ()):
            module = item.module
            if not module.STARTED:
                module.STARTED.append(module.DocsBuild(
                    session.config._tmp_path_factory.mktemp("fresh")))
            return
