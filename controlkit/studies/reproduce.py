"""``controlkit reproduce``: run studies and write their CSV, metrics, figures and manifest.

Each study is one :class:`~controlkit.studies.registry.Study` entry of
:data:`controlkit.studies.STUDIES`; each case is one entry of its scenario's
``CASES``. Adding a study or a case adds no code here.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from ..blocks.spacecraft import SingularDecouplingError
from ..outputs.export import write_csv, write_json
from ..outputs.workers import FigureWorkers
from . import STUDIES
from .registry import Study, UsageError


def _progress_printer(label: str, stream=None):
    stream = stream or sys.stderr
    start = time.perf_counter()

    def report(fraction):
        elapsed = time.perf_counter() - start
        stream.write(f"\r  {label}: {100 * fraction:5.1f} %  ({elapsed:6.1f} s)")
        if fraction >= 1:
            stream.write("\n")
        stream.flush()

    return report


#: Memory a run may hold (bytes); a request that needs more is refused before it starts.
MEMORY_LIMIT = 4_000_000_000


#: Samples per curve the figures are drawn from (independent of the CSV's --stride).
FIGURE_POINTS = 20_000


#: The manifest of a study's folder: what this run wrote, with its settings.
MANIFEST = "run.json"


#: Errors that end one case (its loop diverged or met a singular point) but not the run.
CASE_FAILURES = (FloatingPointError, ArithmeticError, SingularDecouplingError)


def _steps(s: Study, horizon) -> int:
    """Samples of a ``s`` run over ``horizon`` seconds (``None``: its published horizon)."""
    return round((horizon or s.horizon) / s.Ts) + 1


def _select_cases(studies: list[Study], requested) -> dict[str, list[str]]:
    if requested is None:
        return {s.name: list(s.default_cases) for s in studies}
    if isinstance(requested, str):  # one case given as a string, not its letters
        requested = [requested]
    requested = list(requested)
    if not requested:
        raise UsageError("cases must name at least one case (or be None for the defaults)")
    known = {c for s in studies for c in s.cases}
    unknown = [c for c in requested if c not in known]
    if unknown:
        allowed = {s.name: list(s.cases) for s in studies}
        raise UsageError(f"unknown case {unknown}; known cases: {allowed}")
    return {s.name: [c for c in requested if c in s.cases] for s in studies}


def _horizons(studies, horizon) -> dict[str, float | None]:
    """``horizon`` as one value for all studies, or ``{study: seconds}`` (checked now)."""
    from ..blocks.sampling import time_grid

    if horizon is None or isinstance(horizon, dict):
        given = dict(horizon or {})
        unknown = sorted(set(given) - {s.name for s in STUDIES.values()})
        if unknown:
            raise UsageError(f"horizon names unknown studies {unknown}; studies: "
                             f"{list(STUDIES)}")
    else:
        given = {s.name: horizon for s in studies}
    out = {}
    for s in studies:
        value = given.get(s.name)
        if value is None:
            out[s.name] = None
            continue
        if isinstance(value, bool):
            raise UsageError(f"horizon must be a number of seconds, got {value!r}")
        try:
            time_grid(value, s.Ts)
        except ValueError as error:
            raise UsageError(f"horizon for {s.name}: {error}") from None
        out[s.name] = float(value)
    return out


def _writable(out) -> Path:
    """Create ``out`` and prove it writable before anything is simulated."""
    import tempfile

    out = Path(out)
    if out.exists() and not out.is_dir():
        raise UsageError(f"out {str(out)!r} is a file, not a folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".write-test-"):
            pass
    except OSError as error:
        raise UsageError(f"cannot write to out {str(out)!r}: "
                         f"{error.strerror or error}") from None
    return out


def _stale(folder: Path, keep: set[str]) -> None:
    """Remove the files an earlier run listed in its manifest that this run does not write."""
    import json

    manifest = folder / MANIFEST
    if not manifest.exists():
        return
    try:
        earlier = json.loads(manifest.read_text())
    except (OSError, ValueError):
        return
    for name in earlier.get("files", []):
        if name not in keep and "/" not in name and (folder / name).is_file():
            (folder / name).unlink()


def reproduce(study="all", *, out="results", cases=None, horizon=None, stride=None,
              engine="fast", log=None, workers=None, options=None) -> dict:
    """Run studies and write their CSV, metrics and figures (the CLI's main job).

    Every argument is checked, and the output folder created and written to, before
    anything is simulated. Each file is written under a temporary name and renamed when
    complete; each study's folder gets a manifest, ``run.json``, listing the files of
    this run with its settings and the status of every case (an interrupted run says
    which cases are missing), and files that an earlier run listed there are removed.
    A case that fails (a loop that diverges) is recorded with its error while the
    other cases complete.

    Parameters
    ----------
    study : str
        A key of :data:`STUDIES` or ``"all"`` (the studies with ``in_all``).
    out : str or pathlib.Path
        Output folder; each study writes to ``out/<study>/``.
    cases : str or list of str, optional
        Cases to run (default: each study's default cases).
    horizon : float or dict, optional
        Simulated time in seconds for every study, or ``{study: seconds}`` (default:
        each study's published horizon).
    stride : int, optional
        Keep every ``stride``-th sample in the CSV (default 10 for the spacecraft,
        i.e. 1 s; 1 for the CMG). The figures are drawn from enough samples whatever
        the stride, and the metrics from every sample.
    engine : {"fast", "python-control"}
        Simulator; both give the same numbers, the fast one in seconds.
    log : file-like, optional
        Where progress goes (default stderr).
    workers : int, optional
        Processes drawing the figures while the next study is simulated (default: one
        per CPU, at most 4; 0 draws them in this process).
    options : dict, optional
        Keyword arguments passed to every case's ``run`` (e.g. ``{"F": 0.002}``).

    Returns
    -------
    dict
        ``{study: {case: metrics}}``; a failed case has ``{"error": message}``.

    Raises
    ------
    UsageError
        A bad argument or an unusable output folder (nothing simulated, nothing written).

    Examples
    --------
    >>> import io, tempfile
    >>> m = reproduce("spacecraft", out=tempfile.mkdtemp(), cases=["ideal"], horizon=1.0,
    ...               log=io.StringIO())
    >>> sorted(m["spacecraft"])
    ['ideal']
    """
    from ..engines import ENGINES

    log = log or sys.stderr
    if study != "all" and study not in STUDIES:
        raise UsageError(f"unknown study {study!r}; choose from {['all', *STUDIES]}")
    studies = ([s for s in STUDIES.values() if s.in_all] if study == "all"
               else [STUDIES[study]])
    selection = _select_cases(studies, cases)
    horizons = _horizons(studies, horizon)
    if stride is not None and (isinstance(stride, bool) or not isinstance(stride, int)
                               or stride < 1):
        raise UsageError(f"stride must be an integer >= 1, got {stride!r}")
    if engine not in ENGINES:
        raise UsageError(f"engine must be one of {ENGINES}, got {engine!r}")
    options = dict(options or {})
    for s in studies:
        if not selection[s.name]:
            continue
        if options and hasattr(s.run, "check"):
            s.run.check(options)
        steps = _steps(s, horizons[s.name])
        step = stride if stride is not None else s.default_stride
        if stride is not None and steps // step < 2:
            raise UsageError(f"stride {step} keeps {1 + (steps - 1) // step} sample(s) of the "
                             f"{steps} of a {s.name} run; choose a stride below {steps // 2}")
        held = steps if s.streaming is None or engine != "fast" else FIGURE_POINTS
        need = held * s.signals * 8 * 3  # the run, its table and the CSV's copy
        if need > MEMORY_LIMIT:
            raise UsageError(
                f"a {s.name} run of {steps} steps would hold about {need / 1e9:.1f} GB in "
                f"memory (limit {MEMORY_LIMIT / 1e9:.0f} GB); shorten the horizon to at "
                f"most {MEMORY_LIMIT // (s.signals * 24) * s.Ts:g} s")
    out = _writable(out)
    summary = {}
    with FigureWorkers(workers) as pool:
        for s in sorted(studies, key=lambda study: study.simulation_cost):
            if not selection[s.name]:
                continue
            summary[s.name] = _run_study(s, selection[s.name], out / s.name,
                                         horizons[s.name], stride, engine, log, pool, options)
        for path in pool.results():
            log.write(f"  wrote {path}\n")
    return {s.name: summary[s.name] for s in studies if s.name in summary}


def _run_study(s, cases, folder, horizon, stride, engine, log, pool, options) -> dict:
    """Run one study's cases, writing files and the manifest as each finishes."""
    folder.mkdir(parents=True, exist_ok=True)
    step = stride if stride is not None else s.default_stride
    manifest = {"study": s.name, "horizon_s": horizon or s.horizon, "stride": step,
                "engine": engine, "options": options, "complete": False,
                "cases": {case: {"status": "pending"} for case in cases}, "files": []}
    _stale(folder, keep=set())
    write_json(folder / MANIFEST, manifest)

    def done(name, **entry):
        manifest["cases"][name] = entry
        manifest["files"] = sorted({f for c in manifest["cases"].values()
                                    for f in c.get("files", [])} | set(manifest["files"]))
        write_json(folder / MANIFEST, manifest)

    study_metrics, tables, results = {}, {}, {}
    try:
        for case in cases:
            log.write(f"{s.name}/{case}\n")
            manifest["cases"][case] = {"status": "running"}
            started = time.perf_counter()
            progress = _progress_printer(f"{s.name}/{case}", log)
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
            except CASE_FAILURES as error:
                log.write(f"  {s.name}/{case} failed: {error}\n")
                study_metrics[case] = {"error": str(error)}
                done(case, status="failed", error=str(error))
                continue
            elapsed = time.perf_counter() - started
            every = max(1, len(next(iter(columns.values()))) // FIGURE_POINTS)
            tables[case] = {name: values[::every] for name, values in columns.items()}
            study_metrics[case] = {**metrics, "wall_time_s": round(elapsed, 3)}
            done(case, status="done", files=[csv_name])
        if s.write is not None:
            study_metrics, paths = s.write(results, folder) if results else ({}, [])
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
        manifest["complete"] = all(c["status"] == "done" for c in manifest["cases"].values())
    except KeyboardInterrupt:
        for entry in manifest["cases"].values():
            if entry["status"] in ("pending", "running"):
                entry["status"] = "interrupted"
        manifest["interrupted"] = True
        raise
    finally:
        write_json(folder / MANIFEST, manifest)
    return study_metrics


def _streamed(s, case, horizon, stride, csv_path, progress, options):
    """Run one case streamed: CSV rows written as computed, metrics from every sample.

    Returns the figures' columns (about :data:`FIGURE_POINTS` samples) and the metrics.
    """
    from types import SimpleNamespace

    import numpy as np

    from ..outputs.export import atomic, write_rows

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
    from ..outputs.style import VECTOR_FORMATS

    stems = s.stems(tuple(tables)) if s.figure_stems else ()
    return [f"{stem}.{ext}" for stem in stems for ext in ("png", *VECTOR_FORMATS)]
