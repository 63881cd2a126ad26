"""One study run: its cases simulated one after the other, each written (CSV, metrics)
as it finishes, a failed case recorded while the others go on, and its figures handed to
the drawing workers."""

from __future__ import annotations

import contextlib
import sys
import threading
import time

from ...blocks.spacecraft import SingularDecouplingError
from ...outputs.export import write_csv, write_json
from .checks import _steps
from .manifest import MANIFEST, _stale

#: Seconds between two redraws of a progress line on a terminal while no report comes.
TICK = 0.5


class ProgressLine:
    r"""One case's progress on one line: the fraction done and the seconds since it began.

    The simulation reports its fraction after each chunk of the run. The first run of a
    new wiring compiles first, which can hold the first report back for tens of seconds
    and then let all of them through at once; so on a terminal the line is also redrawn
    every ``tick`` seconds, its time moving while the fraction waits. In a file (a log),
    where a redraw is one more line, it is written at the reports only.

    Parameters
    ----------
    label : str
        What runs, e.g. ``"spacecraft/proposed"``.
    stream : file-like, optional
        Where the line goes (default stderr).
    tick : float, None or "auto"
        Seconds between redraws, None for none; ``"auto"``: :data:`TICK` on a terminal,
        none elsewhere.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> line = ProgressLine("cmg/thesis", out)
    >>> line(0.5); line(1.0)
    >>> out.getvalue().replace("\r", "|")
    '|  cmg/thesis:  50.0 %  (   0.0 s)|  cmg/thesis: 100.0 %  (   0.0 s)\n'
    """

    def __init__(self, label: str, stream=None, *, tick: float | None | str = "auto"):
        self.label, self.stream = label, stream or sys.stderr
        self.start, self.fraction, self._drawn = time.perf_counter(), 0.0, False
        self._lock, self._stop = threading.Lock(), threading.Event()
        if tick == "auto":
            tick = TICK if _is_terminal(self.stream) else None
        if tick is not None:
            threading.Thread(target=self._redraw_every, args=(tick,), daemon=True,
                             name="controlkit-progress").start()

    def __call__(self, fraction: float) -> None:
        with self._lock:
            if self._stop.is_set():
                return
            self.fraction = fraction
            self._draw()
            if fraction >= 1:
                self.stream.write("\n")
                self.stream.flush()
                self._stop.set()

    def close(self) -> None:
        """Stop redrawing (the case ended, finished or not), and end the line if it is
        open, so that what is printed next (an error, "interrupted") starts a line."""
        with self._lock:
            if not self._stop.is_set() and self._drawn:
                self.stream.write("\n")
                self.stream.flush()
            self._stop.set()

    def _draw(self):
        elapsed = time.perf_counter() - self.start
        self._drawn = True
        self.stream.write(f"\r  {self.label}: {100 * self.fraction:5.1f} %  "
                          f"({elapsed:6.1f} s)")
        self.stream.flush()

    def _redraw_every(self, tick):
        while not self._stop.wait(tick):
            with self._lock:
                if not self._stop.is_set():
                    self._draw()


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed file
        return False


#: Samples per curve the figures are drawn from (independent of the CSV's --stride).
FIGURE_POINTS = 20_000


#: Errors that end one case (its loop diverged or met a singular point) but not the run.
#: Any other error of a case ends its case too, and the run goes on, unless
#: ``raise_errors`` (the command line's ``--debug``) asks for it to be raised.
CASE_FAILURES = (FloatingPointError, ArithmeticError, SingularDecouplingError)



def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}"


def _run_study(s, cases, folder, horizon, stride, engine, log, pool, options, unread,
               manifests, raise_errors) -> dict:
    """Run one study's cases, writing files and the manifest as each finishes.

    The manifest is registered in ``manifests`` (by folder) for :func:`reproduce` to
    finish once the figures are drawn.
    """
    folder.mkdir(parents=True, exist_ok=True)
    step = stride if stride is not None else s.default_stride
    manifest = {"study": s.name, "horizon_s": horizon or s.horizon, "stride": step,
                "engine": engine, "options": options, "complete": False,
                "cases": {case: {"status": "pending"} for case in cases}, "files": []}
    _stale(folder, s)
    write_json(folder / MANIFEST, manifest)
    manifests[str(folder)] = manifest

    def done(name, **entry):
        if unread.get(name):
            entry["unused_options"] = unread[name]
        manifest["cases"][name] = entry
        manifest["files"] = sorted({f for c in manifest["cases"].values()
                                    for f in c.get("files", [])} | set(manifest["files"]))
        write_json(folder / MANIFEST, manifest)

    for case, names in unread.items():
        log.write(f"  note: {s.name}/{case} does not read option(s) {names}; it runs "
                  "without them\n")
    study_metrics, tables, results = {}, {}, {}
    try:
        for case in cases:
            log.write(f"{s.name}/{case}\n")
            manifest["cases"][case] = {"status": "running"}
            write_json(folder / MANIFEST, manifest)
            started = time.perf_counter()
            progress = ProgressLine(f"{s.name}/{case}", log)
            csv_name = f"{s.csv_stem(case)}.csv"
            try:
                if s.write is not None:
                    results[case] = s.run(case, horizon, progress, engine, **options)
                    done(case, status="done")
                    continue
                if s.streaming is not None and engine == "fast":
                    columns, metrics = _streamed(s, case, horizon or s.horizon, step,
                                                 folder / csv_name, progress, options)
                else:
                    resp = s.run(case, horizon, progress, engine, **options)
                    columns = s.table(resp)
                    write_csv(folder / csv_name, s.csv_columns(columns), stride=step)
                    metrics = s.metrics(columns)
            except Exception as error:  # the case's own failure: recorded, the run goes on
                progress.close()  # (ends its line)
                message = _describe(error)
                log.write(f"  {s.name}/{case} failed: {message}\n")
                study_metrics[case] = {"error": message}
                done(case, status="failed", error=message)
                if raise_errors and not isinstance(error, CASE_FAILURES):
                    raise
                continue
            finally:  # finished, failed or interrupted: the line stops moving
                progress.close()
            elapsed = time.perf_counter() - started
            every = max(1, len(next(iter(columns.values()))) // FIGURE_POINTS)
            tables[case] = {name: values[::every] for name, values in columns.items()}
            study_metrics[case] = {**metrics, "wall_time_s": round(elapsed, 3)}
            done(case, status="done", files=[csv_name])
        if s.write is not None:
            written, paths = s.write(results, folder) if results else ({}, [])
            study_metrics = {**{c: m for c, m in study_metrics.items() if c not in written},
                             **written}
            log.writelines(f"  wrote {path}\n" for path in paths)
            manifest["files"] = sorted({p.name for p in paths})
        else:
            write_json(folder / "metrics.json", study_metrics)
            manifest["files"] = sorted(set(manifest["files"]) | {"metrics.json"})
            if tables:
                names = _figure_files(s, tables)
                manifest["files"] = sorted(set(manifest["files"]) | set(names))
                if s.figure_stems:  # drawn by the workers while the next study runs
                    pool.submit(s.figures, tables, folder, s.stems(tuple(tables)),
                                first=s.draw_first, columns=s.figure_columns)
                else:
                    for path in s.figures(tables, folder):
                        log.write(f"  wrote {path}\n")
            if s.extra is not None and tables:  # while the workers draw the figures
                write_json(folder / MANIFEST, manifest)  # a run killed now lists them
                _extra(s, study_metrics, folder, engine, options, log, pool, manifest)
    except KeyboardInterrupt:
        for entry in manifest["cases"].values():
            if entry["status"] in ("pending", "running"):
                entry["status"] = "interrupted"
        manifest["interrupted"] = True
        raise
    except Exception as error:  # writing the study's files failed
        if not any(c.get("error") == _describe(error) for c in manifest["cases"].values()):
            manifest["error"] = _describe(error)
        raise
    finally:
        with contextlib.suppress(OSError):
            write_json(folder / MANIFEST, manifest)
    return study_metrics


def _extra(s, study_metrics, folder, engine, options, log, pool, manifest) -> None:
    """The study's files written from all its cases (:attr:`Study.extra`), listed in the
    manifest; their figures go to the workers."""
    started = time.perf_counter()
    paths, drawing = s.extra(study_metrics, folder, engine, options)
    log.writelines(f"  wrote {path}\n" for path in paths)
    names = {path.name for path in paths}
    if drawing is not None:
        from ...outputs.style import VECTOR_FORMATS

        figures, tables, stems = drawing
        pool.submit(figures, tables, folder, stems)
        names |= {f"{stem}.{ext}" for stem in stems for ext in ("png", *VECTOR_FORMATS)}
    manifest["files"] = sorted(set(manifest["files"]) | names)
    manifest["extra_wall_time_s"] = round(time.perf_counter() - started, 3)
    write_json(folder / MANIFEST, manifest)


def _streamed(s, case, horizon, stride, csv_path, progress, options):
    """Run one case streamed: CSV rows written as computed, metrics from every sample.

    Returns the figures' columns (about :data:`FIGURE_POINTS` samples) and the metrics.
    """
    from types import SimpleNamespace

    import numpy as np

    from ...outputs.export import atomic, write_rows

    watch = s.streaming(case, horizon)
    steps = _steps(s, horizon)
    seen = [0]
    with atomic(csv_path) as partial, partial.open("w") as handle:
        header = None

        def on_chunk(t, y, x):
            nonlocal header
            watch(t, y, x)
            cols = s.csv_columns(s.table(SimpleNamespace(
                time=t, outputs=y, states=x, output_labels=watch.labels)))
            if header is None:
                header = ",".join(cols)
                handle.write(header + "\n")
            first = (-seen[0]) % stride  # rows 0, stride, 2 stride, ... of the whole run
            rows = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
            write_rows(handle, rows[first::stride])
            seen[0] += t.size

        resp = s.run(case, horizon, progress, "fast", on_chunk=on_chunk,
                     record_every=max(1, steps // FIGURE_POINTS), **options)
    return s.table(resp), watch.metrics()


def _figure_files(s, tables) -> list[str]:
    """The figure files a study will write for these tables (PNG and vector copies)."""
    from ...outputs.style import VECTOR_FORMATS

    stems = s.stems(tuple(tables)) if s.figure_stems else ()
    return [f"{stem}.{ext}" for stem in stems for ext in ("png", *VECTOR_FORMATS)]
