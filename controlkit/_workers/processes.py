"""Worker processes, one run each at a time: a run whose worker dies or overstays its
``timeout`` is a failed row, and a new worker takes the old one's place.
"""

from __future__ import annotations

import collections
import multiprocessing.connection
import os
import pickle
import signal
import threading
import time

from .._lock import process_alive, process_start_ticks
from .endings import describe, exit_description
from .reaper import Reaper, watch_parent

#: Workers that die before their first run, one after the other, before the sweep stops
#: (a worker that cannot even start, e.g. the function's module fails to import there).
MAX_START_FAILURES = 3


def _worker_main(conn, call, fail, function, parent_pid, parent_ticks) -> None:
    """A worker process: make the runs sent on ``conn`` one at a time, send back rows."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=watch_parent, args=(parent_pid, parent_ticks), daemon=True,
                     name="controlkit-parent-watch").start()
    while True:
        try:
            message = conn.recv_bytes()
        except (EOFError, OSError):
            return
        try:
            run = pickle.loads(message)
        except Exception as exc:  # e.g. a parameter's class that cannot be imported here
            conn.send(("unreadable", describe(exc)))
            continue
        if run is None:
            return
        conn.send(("started", run.index))
        started = time.perf_counter()
        try:
            row = call(function, run)
        except BaseException as exc:  # noqa: B036 - in a worker, even a KeyboardInterrupt
            row = fail(run, describe(exc), time.perf_counter() - started)
        try:
            payload = pickle.dumps(("row", row))
        except Exception as exc:  # a row is plain data; this is a last guard
            payload = pickle.dumps(("row", fail(run, f"the row cannot be sent back from the "
                                                     f"worker: {describe(exc)}",
                                                time.perf_counter() - started)))
        conn.send_bytes(payload)


class _Worker:
    def __init__(self, context, call, fail, function):
        self.conn, child_conn = context.Pipe()
        parent = os.getpid()
        self.process = context.Process(
            target=_worker_main, name="controlkit-sweep-worker",
            args=(child_conn, call, fail, function, parent, process_start_ticks(parent)))
        self.process.start()
        self.ticks = process_start_ticks(self.process.pid)
        child_conn.close()
        self.run = None  # the run it is making
        self.sent_at = None
        self.started_at = None  # when it said it started the run (its own start-up excluded)
        self.ever_started = False

    def give(self, run) -> None:
        """Send ``run``; raises what pickling its parameters raises, or OSError if the
        worker is gone."""
        message = pickle.dumps(run)
        self.conn.send_bytes(message)
        self.run, self.sent_at, self.started_at = run, time.monotonic(), None

    def lost(self) -> bool:
        """multiprocessing says it ended, but it still runs: its forkserver was lost (a
        forkserver's worker reports its end through the forkserver)."""
        return self.process.exitcode is not None and process_alive(self.process.pid,
                                                                    self.ticks)

    def kill(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        elif self.lost():
            os.kill(self.process.pid, signal.SIGKILL)
        self.process.join(5)
        self.conn.close()


class ProcessRunner:
    """Runs in worker processes, one run per worker at a time; see the module's notes.

    Parameters
    ----------
    call, fail : callable
        ``call(function, run) -> row`` and ``fail(run, error, wall_time_s) -> row``.
    function : callable
        Sent once to each worker (it must pickle).
    workers : int
        Number of worker processes.
    context : multiprocessing context
        Their start method.
    timeout : float or None
        Longest run, s, counted from when the worker starts it.

    Examples
    --------
    >>> import multiprocessing
    >>> from controlkit.sweep import plan
    >>> from controlkit.sweep.rows import _call, _failed_row
    >>> rows = []
    >>> ProcessRunner(_call, _failed_row, round, 2, multiprocessing.get_context("spawn"),
    ...               None).map(plan(grid={"number": [1.25]}), rows.append)
    >>> rows[0]["error"][:10]
    'TypeError:'
    """

    def __init__(self, call, fail, function, workers, context, timeout):
        self.call, self.fail, self.function = call, fail, function
        self.workers, self.context, self.timeout = workers, context, timeout
        self._pool: list[_Worker] = []
        self._start_failures = 0
        self._given_again: set[int] = set()
        self._reaper = None

    def _start(self) -> _Worker:
        if self._reaper is None:
            self._reaper = Reaper()
        worker = _Worker(self.context, self.call, self.fail, self.function)
        self._pool.append(worker)
        self._reaper.watch(worker.process.pid)
        return worker

    def _replace(self, worker: _Worker) -> _Worker:
        worker.kill()
        self._pool.remove(worker)
        return self._start()

    def _drain(self, worker: _Worker, record) -> None:
        """Read what ``worker`` sent; a row frees it."""
        while worker.run is not None and worker.conn.poll():
            try:
                kind, value = pickle.loads(worker.conn.recv_bytes())
            except (EOFError, OSError, pickle.UnpicklingError):
                return  # it died mid-message: its sentinel says so next
            if kind == "started":
                worker.started_at = time.monotonic()
                worker.ever_started = True
                self._start_failures = 0
            elif kind == "unreadable":
                run, worker.run = worker.run, None
                worker.ever_started = True
                record(self.fail(run, "the worker process could not read this run's "
                                      f"parameters: {value}", 0.0))
            else:
                worker.run = None
                record(value)

    def _give(self, idle, run, record) -> None:
        worker = idle.pop()
        try:
            worker.give(run)
        except OSError:  # the idle worker is gone (killed from outside): a new one
            worker = self._replace(worker)
            worker.give(run)
        except Exception as exc:  # the run's parameters do not pickle
            idle.append(worker)
            record(self.fail(run, "the run's parameters cannot be sent to a worker process: "
                                  f"{describe(exc)}", 0.0))

    def map(self, runs, record) -> None:
        """Make every run of ``runs``; ``record(row)`` each row as it arrives."""
        todo = collections.deque(runs)
        try:
            idle = [self._start() for _ in range(min(self.workers, len(todo)))]
            while todo or any(w.run is not None for w in self._pool):
                while idle and todo:
                    self._give(idle, todo.popleft(), record)
                busy = [w for w in self._pool if w.run is not None]
                now = time.monotonic()
                wait_s = None
                if self.timeout is not None:
                    deadlines = [w.started_at + self.timeout for w in busy
                                 if w.started_at is not None]
                    if deadlines:
                        wait_s = max(0.0, min(deadlines) - now)
                    elif any(w.started_at is None for w in busy):
                        wait_s = 1.0
                multiprocessing.connection.wait(
                    [w.conn for w in busy] + [w.process.sentinel for w in busy], wait_s)
                for worker in busy:
                    self._drain(worker, record)
                    if worker.run is None:
                        idle.append(worker)
                        continue
                    run, now = worker.run, time.monotonic()
                    if not worker.process.is_alive():
                        self._drain(worker, record)  # a row sent just before it ended
                        if worker.run is None:
                            idle.append(self._replace(worker))
                            continue
                        if worker.lost() and run.index not in self._given_again:
                            self._given_again.add(run.index)  # not its fault: once more
                            todo.appendleft(run)
                        elif not worker.ever_started:
                            self._start_failures += 1
                            if self._start_failures >= MAX_START_FAILURES:
                                raise RuntimeError(
                                    f"{MAX_START_FAILURES} worker processes in a row "
                                    f"{exit_description(worker.process.exitcode)} before "
                                    "their first run (see their errors above); is the "
                                    "function importable in a fresh interpreter?")
                            todo.appendleft(run)  # not its fault: give it to a new worker
                        else:
                            took = now - (worker.started_at or worker.sent_at)
                            record(self.fail(run, "WorkerDied: the worker process making "
                                             "this run "
                                             f"{exit_description(worker.process.exitcode)}",
                                             took))
                        idle.append(self._replace(worker))
                    elif (self.timeout is not None and worker.started_at is not None
                          and now - worker.started_at >= self.timeout):
                        worker.process.kill()
                        worker.process.join(5)
                        self._drain(worker, record)  # it may have finished meanwhile
                        if worker.run is not None:
                            record(self.fail(run, f"TimeoutError: the run took longer than "
                                                  f"timeout={self.timeout:g} s; its worker "
                                                  "process was stopped",
                                             now - worker.started_at))
                        idle.append(self._replace(worker))
        finally:
            self.close()

    def close(self) -> None:
        """Stop every worker: idle ones are told to end, busy ones are killed."""
        for worker in self._pool:
            if worker.run is None and worker.process.is_alive():
                try:
                    worker.conn.send(None)
                except OSError:
                    pass
        deadline = time.monotonic() + 2.0
        for worker in self._pool:
            if worker.run is None:
                worker.process.join(max(0.0, deadline - time.monotonic()))
            worker.kill()
        self._pool.clear()
        if self._reaper is not None:
            self._reaper.close()
            self._reaper = None
