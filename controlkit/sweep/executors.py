"""Where the runs go: the executor argument checked, worker processes started, a Dask
scheduler reached (or refused), runs handed to any ``concurrent.futures`` executor."""

from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing
import os
import pickle
import sys

import numpy as np

from .._checks import install_hint
from .._workers import call_in_child
from .rows import _call_elsewhere, _failed_row

#: Executors by name (``executor=`` of :func:`sweep`, ``--executor`` of the CLI).
EXECUTORS = ("processes", "threads", "serial", "dask")
#: Most threads of ``executor="threads"``.
MAX_THREADS = 1024
#: How long a Dask scheduler may take to answer before the sweep is refused, s.
SCHEDULER_TIMEOUT_S = 5.0


def max_processes() -> int:
    """Most worker processes of one sweep on this machine: 4 per core, at least 8.

    Examples
    --------
    >>> max_processes() >= 8
    True
    """
    return max(8, 4 * (os.cpu_count() or 1))


def process_context():
    """The start method of worker processes: ``forkserver`` where there is one, else ``spawn``.

    ``fork`` would copy a parent that may already hold numba's compiler state and
    threads (not fork-safe); a fresh interpreter imports controlkit and loads the
    loops from numba's disk cache instead.

    Examples
    --------
    >>> process_context().get_start_method() in ("forkserver", "spawn")
    True
    """
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def prestart(context, function) -> None:
    """Start the forkserver now, preloading what every worker imports (controlkit's worker,
    the swept function's module, numba when it is installed), so that this happens once,
    beside the sweep's warm-up, and each worker forked from it starts with it done:
    1.5-2 s of imports per worker otherwise. Nothing for ``spawn``.

    Only :mod:`multiprocessing`'s public calls (``set_forkserver_preload``,
    ``forkserver.ensure_running``); the forkserver is the one multiprocessing starts
    for the sweep's workers anyway, and it ends with the session as before.

    Examples
    --------
    >>> prestart(multiprocessing.get_context("spawn"), print) is None  # nothing to do
    True
    """
    if context.get_start_method() != "forkserver":
        return
    from multiprocessing import forkserver

    modules = ["__main__", "controlkit._workers.processes", "controlkit.sweep.rows"]
    module = getattr(function, "__module__", None)
    if isinstance(module, str) and module != "__main__" and not isinstance(function, _ByValue):
        modules.append(module)
    modules.append("controlkit._workers.numba_ready")
    context.set_forkserver_preload(modules)
    forkserver.ensure_running()


def _check_executor(executor, workers, scheduler, timeout) -> str:
    """The executor's kind (a name of :data:`EXECUTORS`, or ``"given"``), all checked."""
    if isinstance(executor, cf.Executor):
        kind = "given"
    elif executor is None:
        kind = "processes"
    elif isinstance(executor, str) and executor in EXECUTORS:
        kind = executor
    else:
        raise ValueError(f"executor must be one of {EXECUTORS} or a concurrent.futures."
                         f"Executor, got {executor!r}")
    if workers is not None:
        if isinstance(workers, bool) or not isinstance(workers, int | np.integer) or \
                workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        if kind in ("given", "serial"):
            raise ValueError(f"workers= does not apply to executor={executor!r} ("
                             + ("it runs one run at a time" if kind == "serial" else
                                "the executor you pass has its own workers") + "); omit it")
        if kind == "dask" and scheduler is not None:
            raise ValueError("workers= does not apply with scheduler= (the cluster's workers "
                             "are started with `dask worker`); omit it")
        most = MAX_THREADS if kind == "threads" else max_processes()
        if workers > most:
            raise ValueError(f"workers must be <= {most} for executor={kind!r} on this "
                             f"machine ({os.cpu_count()} cores), got {workers}")
    if scheduler is not None:
        if kind != "dask":
            raise ValueError(f"scheduler= goes with executor='dask', not {executor!r}")
        if not isinstance(scheduler, str) or not scheduler.strip():
            raise ValueError(f"scheduler must be the address of a running Dask scheduler, "
                             f"e.g. 'tcp://10.0.0.5:8786', got {scheduler!r} (omit it for a "
                             "local cluster)")
    if kind == "dask":
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise ValueError('executor="dask" needs Dask: '
                             f'{install_hint("dask[distributed]", "cluster")}') from None
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(
            timeout, int | float | np.integer | np.floating) or not math.isfinite(timeout)
            or timeout <= 0):
        raise ValueError(f"timeout must be a finite number of seconds > 0, got {timeout!r}")
    if kind == "given":
        _check_open(executor)
    return kind


def _check_open(executor) -> None:
    """ValueError if ``executor`` takes no more work (shut down, or its workers gone): found
    now, before a store exists, rather than at the first run."""
    try:
        executor.submit(int).result(timeout=SCHEDULER_TIMEOUT_S)
    except (RuntimeError, cf.BrokenExecutor, cf.TimeoutError) as exc:
        raise ValueError(f"executor {executor!r} takes no work ({type(exc).__name__}: {exc}); "
                         "pass one that is open, or a name such as 'processes'") from None


class _ByValue:
    """A function sent to other processes as its code and the values it reads
    (``cloudpickle``), for one that cannot be imported there by name: defined in a notebook
    or an interactive session, a lambda, a closure. Called as the function; loaded once
    per process."""

    def __init__(self, function):
        import cloudpickle

        self.payload = cloudpickle.dumps(function)
        self.shown = repr(function)
        self._function = function

    def __getstate__(self):
        return {"payload": self.payload, "shown": self.shown}

    def __setstate__(self, state):
        self.payload, self.shown, self._function = state["payload"], state["shown"], None

    def __call__(self, *args, **kwargs):
        if self._function is None:
            self._function = pickle.loads(self.payload)
        return self._function(*args, **kwargs)

    def __repr__(self):
        return self.shown


def _sendable(function, kind, executor, timeout):
    """The function as the executor will send it: itself when other processes can import it
    by name (or no other process is involved), else sent by value (:class:`_ByValue`).

    Raises
    ------
    ValueError
        The function must go to other processes, cannot be imported there and cannot be
        sent by value (cloudpickle is not installed, or it fails on the function).
    """
    given_processes = kind == "given" and isinstance(executor, cf.ProcessPoolExecutor)
    if kind != "processes" and timeout is None and not given_processes:
        return function  # threads and this process take any callable; Dask uses cloudpickle
    main = sys.modules.get("__main__")
    interactive = getattr(function, "__module__", None) == "__main__" and \
        not getattr(main, "__file__", None)
    if not interactive:
        try:
            pickle.dumps(function)
            return function
        except Exception:  # noqa: BLE001 - not importable by name: try by value below
            pass
    why = ("timeout= makes each run in another process (a thread cannot be stopped)"
           if timeout is not None and kind != "processes" else
           f"executor={kind if kind != 'given' else executor!r} makes the runs in other "
           "processes")
    other = "use executor='threads' or 'serial'" + (
        " without timeout=" if timeout is not None else "")
    try:
        return _ByValue(function)
    except ImportError:
        raise ValueError(f"{why}, which cannot import {function!r} by name (a function of "
                         "a notebook or interactive session, a lambda or a closure); "
                         f'sending it by value needs cloudpickle: '
                         f'{install_hint("cloudpickle", "sweep")}; or {other}') from None
    except Exception as exc:
        raise ValueError(f"{why}, which cannot import {function!r} by name, nor send it by "
                         f"value ({type(exc).__name__}: {exc}); define it at the top of a "
                         f"module (a .py file) and import it, or {other}") from None


def _unreachable(scheduler: str, why: str) -> ValueError:
    return ValueError(f"scheduler {scheduler!r} {why}; start one with `dask scheduler`, check "
                      "the address, or omit scheduler= for a local cluster")


def _handshake(address: str) -> BaseException | None:
    """Open and close one Dask connection to ``address`` within SCHEDULER_TIMEOUT_S; the
    error, if any. (Dask's own connect waits for the peer's greeting without a limit, so a
    port that accepts and says nothing would hold it forever: the whole attempt is bounded
    here, in a thread of its own so that a running event loop, e.g. Jupyter's, is left
    alone.)"""
    import asyncio
    import threading

    from distributed.comm import connect

    outcome = {"error": TimeoutError(f"no answer within {SCHEDULER_TIMEOUT_S:g} s")}

    async def attempt():
        comm = await asyncio.wait_for(connect(address, timeout=SCHEDULER_TIMEOUT_S),
                                      SCHEDULER_TIMEOUT_S)
        comm.abort()

    def run():
        try:
            asyncio.run(attempt())
            outcome["error"] = None
        except BaseException as exc:  # noqa: B036 - reported to the caller
            outcome["error"] = exc

    thread = threading.Thread(target=run, daemon=True, name="controlkit-scheduler-check")
    thread.start()
    thread.join(SCHEDULER_TIMEOUT_S + 2)
    return outcome["error"]


def _connect(scheduler: str):
    """A Dask client of the scheduler, or a ValueError within about SCHEDULER_TIMEOUT_S.

    A TCP address is tried first with a plain connection (a refused one fails at once;
    Dask's client would keep trying until its timeout), then with one Dask handshake.
    """
    import socket
    import urllib.parse

    from distributed import Client

    address = scheduler if "://" in scheduler else f"tcp://{scheduler}"
    parts = urllib.parse.urlsplit(address)
    try:
        port = parts.port
    except ValueError as exc:
        raise ValueError(f"scheduler {scheduler!r} is not an address ({exc}); e.g. "
                         "'tcp://10.0.0.5:8786'") from None
    if parts.scheme == "tcp" and not (parts.hostname and port):
        raise ValueError(f"scheduler {scheduler!r} is not an address: it needs a host and a "
                         "port, e.g. 'tcp://10.0.0.5:8786'")
    if parts.scheme == "tcp":
        try:
            socket.create_connection((parts.hostname, port), SCHEDULER_TIMEOUT_S).close()
        except OSError as exc:
            raise _unreachable(scheduler, f"cannot be reached ({type(exc).__name__}: {exc})"
                               ) from None
        error = _handshake(address)
        if isinstance(error, TimeoutError):  # asyncio's too, since Python 3.11
            raise _unreachable(scheduler, f"did not answer within {SCHEDULER_TIMEOUT_S:g} s "
                                          "(is it a Dask scheduler?)")
        if error is not None:
            raise _unreachable(scheduler, f"did not answer as a Dask scheduler "
                                          f"({type(error).__name__}: {error})")
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
    except Exception as exc:  # OSError, TimeoutError, ValueError, ... all mean "not there"
        why = (f"did not answer within {SCHEDULER_TIMEOUT_S:g} s" if isinstance(
            exc, TimeoutError | OSError) else "cannot be used")
        raise _unreachable(scheduler, f"{why} ({type(exc).__name__}: {exc})") from None


def _on_executor(pool, function, todo, timeout, record, fail):
    """The runs on a concurrent.futures executor (Dask's, or one the user passed)."""
    by_future = {}
    try:
        for run in todo:
            if timeout is None:
                future = pool.submit(_call_elsewhere, function, run)
            else:
                future = pool.submit(call_in_child, _call_elsewhere, _failed_row, function,
                                     run, timeout)
            by_future[future] = run
        lost = []
        for future in cf.as_completed(by_future):
            run = by_future[future]
            try:
                row = future.result()
            except KeyboardInterrupt:
                raise
            except BaseException as exc:  # noqa: B036 - the executor failed this run
                if type(exc).__name__ == "KilledWorker":  # it killed every Dask worker tried
                    row = fail(run, f"WorkerDied: {exc}", 0.0)
                else:
                    lost.append((run, exc))
                    continue
            record(row)
        if lost:
            run, exc = lost[0]
            hint = ("; a worker process died, and this executor cannot tell which run killed "
                    "it: executor='processes' makes that run a failed row and goes on"
                    if isinstance(exc, cf.BrokenExecutor) else "")
            raise RuntimeError(f"{len(lost)} run(s) were lost by the executor (run {run.index}: "
                               f"{type(exc).__name__}: {exc}); the others are kept (in the "
                               f"store, if any: resume to make the lost ones){hint}")
    finally:
        for future in by_future:
            future.cancel()


