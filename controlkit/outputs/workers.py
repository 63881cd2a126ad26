"""Draw result figures in worker processes while the caller goes on simulating.

Drawing the papers' ten figures (PNG at 200 dpi and SVG) takes longer than simulating
them on the fast engine. :class:`FigureWorkers` hands each figure to a process pool as
soon as its study's cases are simulated, so the figures of one study are drawn while
the next study runs, and the figures of a study share the cores among themselves.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
from concurrent.futures import Future, ProcessPoolExecutor
from pathlib import Path

import numpy as np


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
    >>> from controlkit.outputs import spacecraft as out
    >>> from controlkit.scenarios.spacecraft import run
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
        self._pool = (ProcessPoolExecutor(workers, mp_context=_context())
                      if workers > 0 else None)
        self._futures: list[Future] = []

    def submit(self, figures, tables, outdir, stems) -> None:
        """Draw ``figures(tables, outdir, stems=[stem])`` for each stem, one task each.

        Parameters
        ----------
        figures : callable
            A module-level function such as :func:`controlkit.outputs.spacecraft.figures`.
        tables : dict
            Case name to table columns.
        outdir : str or pathlib.Path
            Folder of the files.
        stems : sequence of str
            Figures to draw.
        """
        # plain arrays: python-control's NamedSignal does not survive a trip through pickle
        tables = {case: {name: np.asarray(values) for name, values in columns.items()}
                  for case, columns in tables.items()}
        for stem in stems:
            if self._pool is None:
                done = Future()
                done.set_result(figures(tables, outdir, stems=[stem]))
                self._futures.append(done)
            else:
                self._futures.append(self._pool.submit(figures, tables, outdir, stems=[stem]))

    def results(self) -> list[Path]:
        """Wait for every submitted figure; the files in submission order.

        A figure that failed raises its error here.
        """
        written = []
        for future in self._futures:
            written += future.result()
        self._futures = []
        return written

    def close(self) -> None:
        """Stop the worker processes (pending figures are cancelled)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False
