"""Where a sweep's runs are made: in this process, in threads, in worker processes, or in
any executor; each run ends as one row, whatever the function does.

The runners call ``call(function, run) -> row`` (:func:`controlkit.sweep._call`, which
turns an exception of the function into a row with its error) and hand every row to
``record`` as it arrives. What :func:`~controlkit.sweep._call` cannot catch is caught here:

- :class:`ProcessRunner` keeps one run per worker process, so it knows which run a worker
  was making when it died (``os._exit``, a segfault, the OOM killer): that run is a failed
  row and a new worker takes the dead one's place. With ``timeout`` a run that takes longer
  is a failed row too, its worker killed and replaced. No worker outlives its sweep
  (``concurrent.futures``' pool workers wait for work forever once their parent is killed):
  a small reaper process (:data:`REAPER`, standard library only) reads the workers' pids on
  a pipe from the sweep's process and kills them when that pipe ends - which the kernel
  does when the sweep's process ends, however it ends (SIGKILL included), and even while a
  worker is deep in compiled code that holds the GIL. Each worker also checks the sweep's
  process every :data:`PARENT_POLL_S` from a thread of its own, should the reaper be gone.
  Workers ignore SIGINT: a Ctrl-C reaches the whole terminal's process group, and the
  sweep's process decides.
- :class:`ThreadRunner` runs in daemon threads: Python cannot stop a thread, so after a
  Ctrl-C a run in progress goes on in the background until it returns, but neither the
  sweep nor the interpreter's exit waits for it.
- :func:`call_in_child` makes one run in a fresh interpreter and kills it after
  ``timeout``: how a timeout is kept on executors that cannot stop a task (Dask, any
  ``concurrent.futures.Executor``).
"""

from __future__ import annotations

import collections
import io
import multiprocessing.connection
import os
import pickle
import signal
import subprocess
import sys
import threading
import time

from ._lock import process_alive, process_start_ticks

#: How often a worker process checks that the sweep's process still runs, s.
PARENT_POLL_S = 0.5
#: Workers that die before their first run, one after the other, before the sweep stops
#: (a worker that cannot even start, e.g. the function's module fails to import there).
MAX_START_FAILURES = 3
#: How long a child interpreter (:func:`call_in_child`) may take to start, s.
CHILD_START_TIMEOUT_S = 120.0


#: The reaper: reads ``PID START_TICKS`` lines until the pipe from the sweep's process ends,
#: then kills those processes that still run (the same pid and start time: not a process
#: that got a reused pid). Ctrl-C is for the sweep's process to handle, not for it.
REAPER = """
import os, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
def ticks(pid):
    try:
        text = open(f"/proc/{pid}/stat").read()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()[19]
pids = {}
for line in sys.stdin:
    pid, start = line.split()
    pids[int(pid)] = start
for pid, start in pids.items():
    if start == "-" or ticks(pid) == start:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
"""


class Reaper:
    """Kills the processes it is told about once this process ends (see :data:`REAPER`).

    Examples
    --------
    >>> import subprocess, sys
    >>> child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    >>> reaper = Reaper()
    >>> reaper.watch(child.pid)
    >>> reaper.close()  # as if this process had ended
    >>> child.wait(10) == -9
    True
    """

    def __init__(self):
        self.process = subprocess.Popen([sys.executable, "-I", "-S", "-c", REAPER],
                                        stdin=subprocess.PIPE, close_fds=True)

    def watch(self, pid: int) -> None:
        """Kill ``pid`` when this process (or :meth:`close`) ends the pipe."""
        ticks = process_start_ticks(pid)
        try:
            self.process.stdin.write(f"{pid} {'-' if ticks is None else ticks}\n".encode())
            self.process.stdin.flush()
        except OSError:  # the reaper is gone: the workers' own checks remain
            pass

    def close(self) -> None:
        """End the pipe: the reaper kills what is left and ends."""
        try:
            self.process.stdin.close()
        except OSError:
            pass
        self.process.wait(10)


def _watch_parent(pid: int, start_ticks: int | None) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if not process_alive(pid, start_ticks):
            os._exit(70)  # the sweep is gone: nobody will read this run's row


def _describe(exc: BaseException) -> str:
    try:
        message = str(exc)
    except Exception:
        message = "(its message cannot be shown)"
    return f"{type(exc).__name__}: {message}" if message else type(exc).__name__


def _exit_description(code) -> str:
    if code is None:
        return "ended"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        return f"was killed by {name}"
    return f"ended with exit code {code}"


def _worker_main(conn, call, fail, function, parent_pid, parent_ticks) -> None:
    """A worker process: make the runs sent on ``conn`` one at a time, send back rows."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    threading.Thread(target=_watch_parent, args=(parent_pid, parent_ticks), daemon=True,
                     name="controlkit-parent-watch").start()
    while True:
        try:
            message = conn.recv_bytes()
        except (EOFError, OSError):
            return
        try:
            run = pickle.loads(message)
        except Exception as exc:  # e.g. a parameter's class that cannot be imported here
            conn.send(("unreadable", _describe(exc)))
            continue
        if run is None:
            return
        conn.send(("started", run.index))
        started = time.perf_counter()
        try:
            row = call(function, run)
        except BaseException as exc:  # noqa: B036 - in a worker, even a KeyboardInterrupt
            row = fail(run, _describe(exc), time.perf_counter() - started)
        try:
            payload = pickle.dumps(("row", row))
        except Exception as exc:  # a row is plain data; this is a last guard
            payload = pickle.dumps(("row", fail(run, f"the row cannot be sent back from the "
                                                     f"worker: {_describe(exc)}",
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
    >>> from controlkit.sweep import _call, _failed_row, plan
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
                                  f"{_describe(exc)}", 0.0))

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
                                    f"{_exit_description(worker.process.exitcode)} before "
                                    "their first run (see their errors above); is the "
                                    "function importable in a fresh interpreter?")
                            todo.appendleft(run)  # not its fault: give it to a new worker
                        else:
                            took = now - (worker.started_at or worker.sent_at)
                            record(self.fail(run, "WorkerDied: the worker process making "
                                             "this run "
                                             f"{_exit_description(worker.process.exitcode)}",
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


class ThreadRunner:
    """Runs in daemon threads of this process; see the module's notes.

    Examples
    --------
    >>> from controlkit.sweep import _call, plan
    >>> rows = []
    >>> ThreadRunner(_call, round, 2).map(plan(grid={"number": [1.25, 2.5]}), rows.append)
    >>> sorted(row["run"] for row in rows), rows[0]["error"][:48]
    ([0, 1], 'TypeError: the swept function must return a dict')
    """

    def __init__(self, call, function, workers):
        self.call, self.function, self.workers = call, function, workers

    def map(self, runs, record) -> None:
        """Make every run of ``runs``; ``record(row)`` each row as it arrives.

        An exception that escapes ``call`` (a KeyboardInterrupt raised by the function)
        stops the sweep and is raised here; runs not yet started are dropped.
        """
        import queue

        todo, done = queue.SimpleQueue(), queue.SimpleQueue()
        for run in runs:
            todo.put(run)
        stop = threading.Event()

        def work():
            while not stop.is_set():
                try:
                    run = todo.get_nowait()
                except queue.Empty:
                    return
                try:
                    done.put(("row", self.call(self.function, run)))
                except BaseException as exc:  # noqa: B036 - handed to the sweep's thread
                    done.put(("raise", exc))
                    return

        threads = [threading.Thread(target=work, daemon=True, name="controlkit-sweep-thread")
                   for _ in range(min(self.workers, len(runs)))]
        for thread in threads:
            thread.start()
        try:
            for _ in range(len(runs)):
                kind, value = done.get()
                if kind == "raise":
                    raise value
                record(value)
        finally:
            stop.set()


def child_main() -> None:
    """The child interpreter of :func:`call_in_child`: one run, its row on the result pipe."""
    result = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)  # what the function prints goes to stderr, not into the result
    parent = os.getppid()
    threading.Thread(target=_watch_parent, args=(parent, process_start_ticks(parent)),
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
        row = fail(run, _describe(exc), time.perf_counter() - started)
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
    >>> from controlkit.sweep import _call, _failed_row, plan
    >>> call_in_child(_call, _failed_row, divmod, plan(grid={"x": [1]})[0], 10)["error"]
    'TypeError: divmod() takes no keyword arguments'
    """
    payload = pickle.dumps(list(sys.path)) + pickle.dumps((call, fail, function, run))
    child = subprocess.Popen(
        [sys.executable, "-c", "from controlkit._workers import child_main; child_main()"],
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
                             f"{_exit_description(child.returncode)} before starting it "
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
                             f"{_exit_description(child.returncode)}",
                        time.perf_counter() - started_at)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        reader.join(5)
