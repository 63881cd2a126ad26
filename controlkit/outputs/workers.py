"""Draw result figures in worker processes while the caller goes on simulating.

Drawing the papers' ten figures (PNG at 200 dpi and SVG) takes longer than simulating
them on the fast engine. :class:`FigureWorkers` hands each figure to a process pool as
soon as its study's cases are simulated, so the figures of one study are drawn while
the next study runs, and the figures of a study share the cores among themselves.

While the caller is still simulating, the workers leave it a core: they draw on the
other cores only (at least one figure at a time), and on every core once the caller
waits for them in :meth:`FigureWorkers.results`. The caller's simulations are what the
last figures wait for, so slowing them down to draw sooner makes the whole run longer.

The workers end with the caller, however it ends: they ignore Ctrl-C (the terminal sends
it to every process of the command; the caller decides, and its :meth:`FigureWorkers.close`
ends them), and each checks every :data:`PARENT_POLL_S` that the caller still runs, so a
caller killed with SIGKILL leaves no idle worker behind (``concurrent.futures``' workers
would wait for work forever). A figure that fails does not stop the others:
:meth:`FigureWorkers.results` waits for every figure and then raises :class:`FigureError`
naming each one that failed.
"""

from __future__ import annotations

import concurrent.futures as cf
import gc
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

import numpy as np

#: In a worker: the semaphore that bounds how many workers draw at once.
_SLOTS = None
#: How often a worker checks that the process that started it still runs, s.
PARENT_POLL_S = 0.5


class FigureError(RuntimeError):
    """Figures that could not be drawn or written; :attr:`failures` lists
    ``(folder, stem, "Type: message")`` for each.

    Examples
    --------
    >>> error = FigureError([("out", "fig1", "OSError: disk full")])
    >>> print(error)
    figure fig1 in out: OSError: disk full
    """

    def __init__(self, failures):
        self.failures = list(failures)
        shown = "; ".join(f"figure {stem} in {folder}: {why}"
                          for folder, stem, why in self.failures[:3])
        more = len(self.failures) - 3
        super().__init__(shown + (f"; and {more} more" if more > 0 else ""))


def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}"


def _watch_parent(pid: int, start_ticks) -> None:
    from .._lock import process_alive

    while True:
        time.sleep(PARENT_POLL_S)
        if not process_alive(pid, start_ticks):
            os._exit(70)  # the caller is gone: nobody will read this worker's figures


def _start_worker(slots, parent_pid=None, parent_ticks=None) -> None:
    global _SLOTS
    _SLOTS = slots
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller handles Ctrl-C
    if parent_pid is not None:
        threading.Thread(target=_watch_parent, args=(parent_pid, parent_ticks), daemon=True,
                         name="controlkit-parent-watch").start()


def _started() -> None:
    """A task that does nothing: submitted first, it starts every worker at once."""


def _draw(figures, tables, outdir, stems):
    """In a worker: ``figures(tables, outdir, stems=stems)`` once a drawing slot is free."""
    with _SLOTS:
        return figures(tables, outdir, stems=stems)


def _context():
    # on Linux, fork starts a worker in milliseconds with matplotlib and controlkit already
    # imported; elsewhere (macOS, Windows) the platform's safe default is kept
    if sys.platform.startswith("linux"):
        return multiprocessing.get_context("fork")
    return multiprocessing.get_context()


class FigureWorkers:
    """A pool of processes that draw figures; a context manager.

    Parameters
    ----------
    workers : int, optional
        Number of processes (default: the number of CPUs, at most 4); 0 draws every
        figure in the calling process when it is submitted.

    Examples
    --------
    >>> import tempfile
    >>> from controlkit.studies.spacecraft import outputs as out
    >>> from controlkit.studies.spacecraft.scenario import run
    >>> tables = {"ideal": out.table(run("ideal", horizon=1.0))}
    >>> with FigureWorkers(workers=0) as pool:
    ...     pool.submit(out.figures, tables, tempfile.mkdtemp(), ["fig05_h1", "fig06_h2"])
    ...     [p.name for p in pool.results()]
    ['fig05_h1.png', 'fig05_h1.svg', 'fig06_h2.png', 'fig06_h2.svg']
    """

    def __init__(self, workers=None):
        if workers is None:
            workers = min(os.cpu_count() or 1, 4)
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
            raise ValueError(f"workers must be an integer >= 0, got {workers!r}")
        self.workers = workers
        context = _context()
        self._pool = self._slots = None
        self._reserved = 0
        if workers > 0:
            # the caller keeps a core while it simulates: it holds the slots of the
            # workers beyond the other cores until results() (see the module's docstring)
            self._slots = context.Semaphore(workers)
            self._reserved = workers - max(1, min(workers, (os.cpu_count() or 1) - 1))
            for _ in range(self._reserved):
                self._slots.acquire()
            from .._lock import process_start_ticks

            self._pool = ProcessPoolExecutor(
                workers, mp_context=context, initializer=_start_worker,
                initargs=(self._slots, os.getpid(), process_start_ticks(os.getpid())))
        self._futures: list[Future] = []
        self._labels: list[tuple[str, str]] = []  # (folder, stem) of each future
        self._background: list[Future] = []
        # A forked worker shares the caller's memory until it writes to it, and the cyclic
        # garbage collector writes to every object it visits: the first full collection
        # in a worker walked the ~200 000 objects of python-control, scipy, numba and
        # matplotlib it inherited, copying their pages, for 0.4-0.7 s of a worker's
        # ~1.5 s. Frozen objects are skipped by the collector (still freed by reference
        # counting); they are handed back to it by close().
        # Objects someone else froze are left as they are (close() would thaw them).
        self._frozen = (self._pool is not None and context.get_start_method() == "fork"
                        and gc.get_freeze_count() == 0)
        if self._frozen:
            gc.freeze()
        if self._pool is not None:
            # with fork, the pool starts all its workers at its first task: this one, so
            # they are forked now, with the objects frozen above
            self._background.append(self._pool.submit(_started))

    def submit(self, figures, tables, outdir, stems, *, first=(), columns=None) -> None:
        """Draw ``figures(tables, outdir, stems=[stem])`` for each stem, one task each.

        Parameters
        ----------
        figures : callable
            A module-level function such as :func:`controlkit.studies.spacecraft.outputs.figures`.
        tables : dict
            Case name to table columns.
        outdir : str or pathlib.Path
            Folder of the files.
        stems : sequence of str
            Figures to draw.
        first : sequence of str
            Stems handed to the workers before the others: the slowest figures, so
            that the workers finish together. :meth:`results` keeps the order of
            ``stems``.
        columns : callable, optional
            ``columns(stem)``: the table columns that figure reads; a worker is sent
            only those (all the columns of the three spacecraft cases were 6.7 MB to
            pickle and pipe per figure).
        """
        # plain arrays: python-control's NamedSignal does not survive a trip through pickle
        tables = {case: {name: np.asarray(values) for name, values in columns.items()}
                  for case, columns in tables.items()}
        self._labels += [(str(outdir), stem) for stem in stems]
        if self._pool is None:
            for stem in stems:
                done = Future()
                try:
                    done.set_result(figures(tables, outdir, stems=[stem]))
                except Exception as error:  # raised by results(), as from a worker
                    done.set_exception(error)
                self._futures.append(done)
            return
        stems = list(stems)
        futures = [None] * len(stems)
        for i in sorted(range(len(stems)), key=lambda i: stems[i] not in first):
            sent = tables
            if columns is not None:
                names = columns(stems[i])
                sent = {case: {name: table[name] for name in names}
                        for case, table in tables.items()}
            futures[i] = self._pool.submit(_draw, figures, sent, outdir, [stems[i]])
        self._futures += futures

    def run_in_background(self, function, *args) -> None:
        """Run ``function(*args)`` in a worker for what it leaves on disk (a cache).

        It draws nothing, so it needs no drawing slot; its result and any error are
        ignored. Leaving the ``with`` block normally waits for it; :meth:`close` or an
        error cancels it if it has not started. Nothing happens without worker
        processes (``workers=0``).
        """
        if self._pool is None:
            return
        self._background.append(self._pool.submit(function, *args))

    def results(self) -> list[Path]:
        """Wait for every submitted figure; the files in submission order.

        From now on the workers draw on every core: the caller only waits. Figures that
        failed raise :class:`FigureError` here, once every other figure is drawn.
        """
        self._release()
        cf.wait(self._futures)
        written, failures = [], []
        for future, (folder, stem) in zip(self._futures, self._labels, strict=True):
            error = (cf.CancelledError("cancelled before it was drawn") if future.cancelled()
                     else future.exception())
            if error is None:
                written += future.result()
            else:
                failures.append((folder, stem, _describe(error)))
        self._futures, self._labels = [], []
        if failures:
            raise FigureError(failures)
        return written

    def _release(self) -> None:
        """Hand the caller's drawing slots to the workers."""
        for _ in range(self._reserved):
            self._slots.release()
        self._reserved = 0

    def close(self) -> None:
        """Stop the worker processes (pending figures are cancelled)."""
        if self._pool is not None:
            self._release()  # a worker waiting for a slot would never end
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        if self._frozen:
            gc.unfreeze()
            self._frozen = False

    def __enter__(self):
        return self

    def __exit__(self, exc_type, *exc):
        if exc_type is None:  # a clean exit lets the background work finish (close cancels it)
            for future in self._background:
                future.exception()  # waits; an error of background work is ignored
        self.close()
        return False
