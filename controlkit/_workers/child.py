"""One run in a fresh interpreter, killed after ``timeout``: how a timeout is kept on
executors that cannot stop a task once started.
"""

from __future__ import annotations

import io
import os
import pickle
import subprocess
import sys
import threading
import time

from .._lock import process_start_ticks
from .endings import describe, exit_description
from .reaper import watch_parent

#: How long a child interpreter (:func:`call_in_child`) may take to start, s.
CHILD_START_TIMEOUT_S = 120.0


def child_main() -> None:
    """The child interpreter of :func:`call_in_child`: one run, its row on the result pipe."""
    result = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # what the function prints goes to stderr, not into the result
    parent = os.getppid()
    threading.Thread(target=watch_parent, args=(parent, process_start_ticks(parent)),
                     daemon=True, name="controlkit-parent-watch").start()
    data = io.BytesIO(sys.stdin.buffer.read())
    sys.path[:0] = [p for p in pickle.load(data) if p not in sys.path]
    call, fail, function, run = pickle.load(data)
    result.write(b"S")
    result.flush()
    started = time.perf_counter()
    try:
        row = call(function, run)
    except BaseException as exc:  # noqa: B036 - a row whatever happens
        row = fail(run, describe(exc), time.perf_counter() - started)
    result.write(pickle.dumps(row))
    result.flush()


def call_in_child(call, fail, function, run, timeout: float) -> dict:
    """Make one run in a fresh interpreter; a failed row if it takes over ``timeout`` s.

    The time counts from when the child starts the run (its start-up and imports
    excluded). The child is killed on timeout, so nothing of the run goes on. Used for
    executors that cannot stop a task once started (Dask, any
    ``concurrent.futures.Executor``); it runs wherever the executor runs it, with that
    process's ``sys.path``.

    Examples
    --------
    >>> from controlkit.sweep import plan
    >>> from controlkit.sweep.rows import _call, _failed_row
    >>> call_in_child(_call, _failed_row, divmod, plan(grid={"x": [1]})[0], 10)["error"]
    'TypeError: divmod() takes no keyword arguments'
    """
    payload = pickle.dumps(list(sys.path)) + pickle.dumps((call, fail, function, run))
    # -P: the working folder is not searched for modules (a numpy.py planted in a shared
    # folder would be imported instead of numpy); this process's own path is sent after
    child = subprocess.Popen(
        [sys.executable, "-P", "-c",
         "from controlkit._workers import child_main; child_main()"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE)
    received = {"bytes": b"", "started": False}
    first_read, ended = threading.Event(), threading.Event()

    def read():
        received["started"] = child.stdout.read(1) == b"S"
        first_read.set()
        if received["started"]:
            received["bytes"] = child.stdout.read()
        ended.set()

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    sent_at = time.perf_counter()
    try:
        child.stdin.write(payload)
        child.stdin.close()
    except BrokenPipeError:
        pass
    try:
        if not first_read.wait(CHILD_START_TIMEOUT_S) or not received["started"]:
            child.kill()
            child.wait()
            return fail(run, f"WorkerDied: the child process for this run "
                             f"{exit_description(child.returncode)} before starting it "
                             "(see its error above)", time.perf_counter() - sent_at)
        started_at = time.perf_counter()
        if not ended.wait(timeout):
            child.kill()
            child.wait()
            return fail(run, f"TimeoutError: the run took longer than timeout={timeout:g} s; "
                             "its child process was stopped", time.perf_counter() - started_at)
        child.wait()
        try:
            return pickle.loads(received["bytes"])
        except Exception:
            return fail(run, f"WorkerDied: the child process making this run "
                             f"{exit_description(child.returncode)}",
                        time.perf_counter() - started_at)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        reader.join(5)
