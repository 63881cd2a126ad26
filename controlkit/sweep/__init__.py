"""Many runs of a scenario or of your own function: grids, seeded draws, any executor.

:func:`sweep` calls a function of named parameters once per run and gathers
what each run returns into a :class:`pandas.DataFrame`, one row per run. The
runs come from a grid (every combination of named values) or from seeded
random draws (named distributions), optionally crossed with a list of cases.
They run on any :class:`concurrent.futures.Executor`: local processes on all
cores by default, threads, in this process, or a Dask cluster through
``distributed.Client.get_executor()`` - the same call on a laptop or a
cluster, and the same rows whichever runs it (each run's parameters and seed
are fixed before any run starts; rows are sorted by run index).

A run that fails is a row with its ``error``, whatever the function does
(raises, calls ``sys.exit``, kills its worker process, takes longer than
``timeout``, returns something that is not a dict of plain values); the sweep
goes on. With ``store=``, each finished run is appended to ``runs.jsonl`` in
that folder as it completes, so an interrupted sweep keeps what it finished
and ``resume=True`` runs only what is missing; the store is only ever appended
to, read back row by row with checks, and locked against a second writer
(see :mod:`controlkit._store`). Every argument is checked before the store or
any process is created.

:func:`spacecraft_study` is the built-in robustness study of the spacecraft
paper: how often each case keeps the 0.05 deg requirement over draws of the
inertia error, the amplitude of ``H0`` and the initial attitude.

The package's rooms: :mod:`.points` (the runs, fixed before any starts), :mod:`.rows`
(one run made, one row), :mod:`.executors` (where the runs go), :mod:`.function`
(:func:`sweep` itself), :mod:`.system` (:func:`sweep_system`, a diagram's runs in one
compiled call) and :mod:`.confidence` (:func:`wilson_interval`). The runners that keep
a run's failure to its row live in :mod:`controlkit._workers`, the store in
:mod:`controlkit._store`.
"""

from .._store import RUNS_FILE, SPEC_FILE, StoreWarning
from . import executors, points
from .confidence import wilson_interval
from .executors import max_processes, process_context
from .function import check_folder, sweep
from .points import Run, draw_points, grid_points, plan
from .system import sweep_system as sweep_system  # importable here; not in __all__, as before

__all__ = ["EXECUTORS", "MAX_RUNS", "MAX_THREADS", "RESERVED", "RUNS_FILE",
           "SCHEDULER_TIMEOUT_S", "SPEC_FILE", "Run", "StoreWarning", "check_folder",
           "draw_points", "grid_points", "max_processes", "plan", "process_context", "sweep",
           "wilson_interval"]

# The public constants, bound here with their descriptions so that the API page shows them
# (each is defined once, in the room that uses it).

#: Executors by name (``executor=`` of :func:`sweep`, ``--executor`` of the CLI).
EXECUTORS = executors.EXECUTORS
#: Columns every row has, that parameters and metrics cannot be named.
RESERVED = points.RESERVED
#: Most runs in one sweep: its plan and rows stay within memory (about 1 kB a run).
MAX_RUNS = points.MAX_RUNS
#: Most threads of ``executor="threads"``.
MAX_THREADS = executors.MAX_THREADS
#: How long a Dask scheduler may take to answer before the sweep is refused, s.
SCHEDULER_TIMEOUT_S = executors.SCHEDULER_TIMEOUT_S
