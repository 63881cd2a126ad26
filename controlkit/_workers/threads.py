"""Runs in daemon threads of the sweep's process."""

from __future__ import annotations

import threading


class ThreadRunner:
    """Runs in daemon threads of this process; see the module's notes.

    Examples
    --------
    >>> from controlkit.sweep import plan
    >>> from controlkit.sweep.rows import _call
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
