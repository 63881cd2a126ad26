"""Where a sweep's runs are made: in this process, in threads, in worker processes, or in
any executor; each run ends as one row, whatever the function does.

The runners call ``call(function, run) -> row`` (:func:`controlkit.sweep.rows._call`, which
turns an exception of the function into a row with its error) and hand every row to
``record`` as it arrives. What :func:`~controlkit.sweep.rows._call` cannot catch is caught here:

- :class:`ProcessRunner` keeps one run per worker process, so it knows which run a worker
  was making when it died (``os._exit``, a segfault, the OOM killer): that run is a failed
  row and a new worker takes the dead one's place. With ``timeout`` a run that takes longer
  is a failed row too, its worker killed and replaced. No worker outlives its sweep
  (``concurrent.futures``' pool workers wait for work forever once their parent is killed):
  a small reaper process (:data:`.reaper.REAPER`, standard library only) reads the workers' pids on
  a pipe from the sweep's process and kills them when that pipe ends - which the kernel
  does when the sweep's process ends, however it ends (SIGKILL included), and even while a
  worker is deep in compiled code that holds the GIL. Each worker also checks the sweep's
  process every :data:`.reaper.PARENT_POLL_S` from a thread of its own, should the reaper be gone.
  Workers ignore SIGINT: a Ctrl-C reaches the whole terminal's process group, and the
  sweep's process decides.
- :class:`ThreadRunner` runs in daemon threads: Python cannot stop a thread, so after a
  Ctrl-C a run in progress goes on in the background until it returns, but neither the
  sweep nor the interpreter's exit waits for it.
- :func:`call_in_child` makes one run in a fresh interpreter and kills it after
  ``timeout``: how a timeout is kept on executors that cannot stop a task (Dask, any
  ``concurrent.futures.Executor``).
"""

from .child import CHILD_START_TIMEOUT_S, call_in_child, child_main
from .processes import MAX_START_FAILURES, ProcessRunner
from .reaper import PARENT_POLL_S, REAPER, Reaper
from .threads import ThreadRunner

__all__ = ["CHILD_START_TIMEOUT_S", "MAX_START_FAILURES", "PARENT_POLL_S", "REAPER",
           "ProcessRunner", "Reaper", "ThreadRunner", "call_in_child", "child_main"]
