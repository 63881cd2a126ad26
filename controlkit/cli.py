"""The ``controlkit`` command line: ``controlkit reproduce`` writes the papers' results.

Each study is one :class:`Study` entry of :data:`STUDIES`; each case is one
entry of its scenario's ``CASES``. Adding a study or a case adds no code here.
"""

from __future__ import annotations

import argparse
import gc
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

# Importing python-control (with scipy, matplotlib and numba) creates ~200 000 objects that
# live as long as the process; the garbage collector's passes over them while they are
# created find nothing to free and took a tenth of the import (0.1 s of the command's
# 1.2 s floor). It is switched back on, if it was on, at the end of this module.
_COLLECTING = gc.isenabled()
gc.disable()
try:
    from .blocks.spacecraft import SingularDecouplingError
    from .outputs import cmg as cmg_out
    from .outputs import frit as frit_out
    from .outputs import spacecraft as sc_out
    from .outputs.export import write_csv, write_json
    from .outputs.workers import FigureWorkers
    from .scenarios import cmg as cmg_scenario
    from .scenarios import frit as frit_scenario
    from .scenarios import spacecraft as sc_scenario
except BaseException:
    if _COLLECTING:
        gc.enable()
    raise


@dataclass(frozen=True)
class Study:
    """What ``controlkit reproduce <study>`` runs and writes.

    Attributes
    ----------
    name : str
        Study name on the command line and output sub-folder.
    cases : tuple of str
        Every case the study knows.
    default_cases : tuple of str
        Cases run when none is named.
    run : callable
        ``run(case, horizon, progress, engine) -> TimeResponseData``; ``horizon=None``
        means the published one.
    table : callable
        Response to CSV columns (dict of arrays).
    metrics : callable
        CSV columns (of :attr:`table`) to a JSON-ready dict.
    figures : callable
        ``figures({case: table}, outdir) -> list of paths``.
    default_stride : int
        CSV row stride when ``--stride`` is not given.
    csv_stem : callable
        Case name to CSV file stem.
    csv_columns : callable
        Table to the columns written to CSV (default: all).
    figure_stems : tuple of str
        The figures ``figures`` can draw one at a time (``stems=[stem]``), so that they
        are drawn in parallel worker processes; empty: ``figures`` is called once.
    draw_first : tuple of str
        Figures handed to the workers before the others because they take longest, so
        that the workers finish together.
    figure_columns : callable, optional
        ``figure_columns(stem)``: the table columns a figure reads (the workers are sent
        only those); default all.
    simulation_cost : float
        Relative time to simulate the study's cases; cheaper studies run first, so their
        figures are drawn by the workers while the costlier simulations run.
    write : callable, optional
        For a study whose cases are not single runs: ``write({case: result}, folder)
        -> (metrics, paths)`` writes all its files; ``table``, ``metrics`` and
        ``figures`` are then unused.
    in_all : bool
        Whether ``controlkit reproduce all`` runs it (the papers' results do; the
        sensitivity study is asked for by name).
    Ts : float
        Sampling period of its loops (to check a horizon before anything runs).
    horizon : float
        Its published horizon, s.
    signals : int
        About how many numbers one sample holds (states and outputs), to size a run.
    streaming : callable, optional
        ``streaming(case, horizon) -> accumulator`` for studies whose runs can be
        streamed: the run then holds no more than the figures' samples, the CSV rows are
        written as they are computed, and ``accumulator.metrics()`` gives the metrics
        from every sample.
    loop : callable, optional
        ``loop(case) -> interconnect``: a case's published loop. For a study shorter
        than :data:`controlkit.engine.COMPILE_AFTER_STEPS`, which the fast engine runs as
        Python until its loop is compiled, a worker compiles the loop into the disk
        cache during the first ``reproduce``, so that later ones load it compiled.

    Examples
    --------
    >>> STUDIES["spacecraft"].default_cases
    ('ideal', 'without_mec', 'proposed')
    """

    name: str
    cases: tuple[str, ...]
    default_cases: tuple[str, ...]
    run: Callable
    table: Callable
    metrics: Callable
    figures: Callable
    default_stride: int = 1
    csv_stem: Callable[[str], str] = str
    csv_columns: Callable[[dict], dict] = lambda columns: columns
    figure_stems: tuple[str, ...] = ()
    draw_first: tuple[str, ...] = ()
    figure_columns: Callable[[str], tuple[str, ...]] | None = None
    simulation_cost: float = 1.0
    write: Callable | None = None
    in_all: bool = True
    Ts: float = 0.1
    horizon: float = 20_000.0
    signals: int = 60
    streaming: Callable | None = None
    loop: Callable | None = None


def _runner(scenario):
    """``run(case, horizon, progress, engine, **options)`` of a scenarios module.

    ``horizon=None`` means the published one (``scenario.HORIZON``); an option the
    scenario's ``run`` does not take is refused with the ones it does.
    """
    import inspect

    accepted = set(inspect.signature(scenario.run).parameters) - {"case", "horizon",
                                                                 "progress", "engine"}

    def check(options):
        unknown = sorted(set(options) - accepted - {"record_every", "on_chunk"})
        if unknown:
            raise UsageError(f"unknown option {unknown} for {scenario.__name__}.run; "
                             f"options: {sorted(accepted)}")

    def run(case, horizon, progress, engine, **options):
        check(options)
        return scenario.run(case, horizon=horizon or scenario.HORIZON, progress=progress,
                            engine=engine, **options)

    run.check = check
    return run


def _spacecraft_watch(case, horizon):
    return sc_out.StreamingMetrics(sc_scenario.build_loop(case).output_labels, horizon)


STUDIES: dict[str, Study] = {
    "spacecraft": Study(
        "spacecraft", tuple(sc_scenario.CASES), sc_scenario.DEFAULT_CASES, _runner(sc_scenario),
        sc_out.table, sc_out.metrics_from_table, sc_out.figures, default_stride=10,
        figure_stems=tuple(spec[0] for spec in sc_out.FIGURES),
        draw_first=("fig07_pointing_error",),  # a log axis: 1.5-2x the others
        figure_columns=sc_out.figure_columns,
        Ts=sc_scenario.sc.TS_PAPER, horizon=sc_scenario.HORIZON, signals=60,
        streaming=_spacecraft_watch,
    ),
    "cmg": Study(
        "cmg", tuple(cmg_scenario.CASES), cmg_scenario.DEFAULT_CASES, _runner(cmg_scenario),
        cmg_out.table, cmg_out.metrics_from_table, cmg_out.figures,
        csv_stem=lambda case: "run" if case == "thesis" else case,
        csv_columns=cmg_out.csv_columns,
        figure_stems=tuple(spec[0] for spec in cmg_out.FIGURES),
        figure_columns=cmg_out.figure_columns,
        simulation_cost=0.05,  # 12 000 steps of a 10-state loop vs 3 x 200 000 steps
        Ts=cmg_scenario.cmg.TS_CMG, horizon=cmg_scenario.HORIZON, signals=32,
        loop=cmg_scenario.build_loop,
    ),
    "frit": Study(
        "frit", frit_scenario.CASES, frit_scenario.DEFAULT_CASES, _runner(frit_scenario),
        None, None, None, write=frit_out.write, in_all=False, signals=0,
        simulation_cost=16.0,  # 16 readings of the proposed loop per tuner
    ),
}


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


class UsageError(ValueError):
    """A bad argument of ``reproduce`` (the command line exits with status 2).

    Examples
    --------
    >>> try:
    ...     reproduce("moon")
    ... except UsageError as error:
    ...     print(error)
    unknown study 'moon'; choose from ['all', 'spacecraft', 'cmg', 'frit']
    """


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
    from .sampling import time_grid

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
    from .simulation import ENGINES

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
        if engine == "fast" and not options:
            _compile_ahead(studies, selection, horizons, pool)
        for s in sorted(studies, key=lambda study: study.simulation_cost):
            if not selection[s.name]:
                continue
            summary[s.name] = _run_study(s, selection[s.name], out / s.name,
                                         horizons[s.name], stride, engine, log, pool, options)
        for path in pool.results():
            log.write(f"  wrote {path}\n")
    return {s.name: summary[s.name] for s in studies if s.name in summary}


def _compile_ahead(studies, selection, horizons, pool) -> None:
    """Have a worker compile the published loops that the fast engine would run as Python.

    The engine runs a loop that is not in its disk cache as Python for its first
    :data:`controlkit.engine.COMPILE_AFTER_STEPS` steps in a process, so that a diagram
    being tried starts at once; the CMG study's 12 001 steps therefore ran as Python in
    every ``reproduce`` (0.9 s with loading each kernel's cache; 0.05 s compiled). Its
    loop is compiled (3-5 s) by a worker while this run goes on as before, so later
    runs load it compiled and this one takes no longer. Looking the loop up costs this
    process a few milliseconds: the kernels it loads are the ones its run needs.
    """
    from . import engine
    from ._jit import HAVE_NUMBA

    if not HAVE_NUMBA or pool.workers == 0:
        return
    for s in studies:
        if s.loop is None or _steps(s, horizons[s.name]) >= engine.COMPILE_AFTER_STEPS:
            continue
        for case in selection[s.name]:
            run, _ = engine.compile_system(s.loop(case), steps=0)
            if not hasattr(run, "py_func"):  # not a numba function: not compiled yet
                pool.run_in_background(_compile_case, s.name, case)


def _compile_case(study: str, case: str) -> None:
    """In a worker: compile a case's loop into the disk cache (see :func:`_compile_ahead`).

    A run of two steps with the fast engine told to compile whatever the length gives
    the loop the argument types of a full run.
    """
    from . import engine

    s = STUDIES[study]
    engine.COMPILE_AFTER_STEPS = 0  # this worker process only
    s.run(case, 2 * s.Ts, None, "fast")


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
                    pool.submit(s.figures, tables, folder, s.figure_stems,
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

    from .outputs.export import atomic, write_rows

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
    from .outputs.style import VECTOR_FORMATS

    stems = s.figure_stems or ()
    if s.name == "spacecraft" and not any(
            sc_scenario.CASES[c].compensator != "none" for c in tables):
        stems = tuple(x for x in stems if x != "fig08_K")
    return [f"{stem}.{ext}" for stem in stems for ext in ("png", *VECTOR_FORMATS)]


HELP = """Reproduce the papers' results and study their robustness.

  controlkit reproduce [spacecraft|cmg|frit|all] [--case NAME]... [--horizon SECONDS]
  controlkit sweep spacecraft --samples N --out DIR

Each study writes CSV tables, metrics.json, run.json (what the run wrote) and
slide-ready figures into its own folder. Add --help after a command for its options.
"""


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line on stderr (exit status 2)."""

    def error(self, message):
        self.exit(2, f"{self.prog}: error: {message}\n")


def _horizon_arg(text):
    """``SECONDS`` for every study, or ``STUDY=SECONDS`` for one."""
    name, sep, value = text.rpartition("=")
    try:
        seconds = float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected SECONDS or STUDY=SECONDS, got {text!r}") from None
    return (name if sep else None, seconds)


def _set_arg(text):
    name, sep, value = text.partition("=")
    if not sep or not name.isidentifier():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    try:
        return name, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{name}: expected a number, got {value!r}") from None


def main(argv=None) -> int:
    """Entry point of the ``controlkit`` command.

    Exit status: 0 on success, 1 when a run failed (one line naming the cause; a case
    that failed while the others completed also gives 1), 2 for a usage error, 130
    when interrupted. ``--debug`` shows the traceback instead of the one line.

    Examples
    --------
    >>> main(["reproduce", "--horizon", "-3"])  # says why on stderr, in one line
    2
    """
    if argv is None:  # the command line: this process ends when main returns
        _freeze_objects()  # those of the imports
    try:
        return _main(argv)
    finally:
        if argv is None:
            _freeze_objects()  # and those of the run, before the interpreter exits


def _freeze_objects() -> None:
    """Keep the collector off the objects the command has made so far (``gc.freeze``).

    Importing python-control, scipy, numba and matplotlib leaves ~300 000 objects that
    live as long as the process, and a full collection walks all of them:

    - before the run: numba's first use (loading its typing registries to call a cached
      loop) allocates enough to start several, 0.34-0.46 s after the imports instead of
      0.12-0.17 s with them frozen;
    - at exit: Python clears every module and runs the collector over what is left,
      0.3 s after ``import control`` alone and 0.7-0.9 s after ``controlkit reproduce
      all``, to free memory the process is about to give back.

    Frozen objects are skipped by the collector and, should one become garbage, freed by
    reference counting or with the process. atexit handlers and the flush of stdout and
    stderr still run.
    """
    gc.freeze()


def _main(argv) -> int:
    parser = _Parser(prog="controlkit", description=HELP,
                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--debug", action="store_true",
                        help="show the full traceback of an error")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    rep = sub.add_parser(
        "reproduce", help="run the papers' cases and write CSV, metrics.json and figures",
        description="Run the papers' cases and write CSV tables, metrics.json, run.json and "
                    "figures into OUT/<study>/.")
    rep.add_argument("study", nargs="?", default="all", choices=["all", *STUDIES],
                     help="which study (default: all = the papers' studies; frit = the "
                          "sensitivity of the FRIT claim, asked for by name)")
    rep.add_argument("--out", default="results", help="output folder (default: results)")
    known = "; ".join(f"{name}: {', '.join(study.cases)}" for name, study in STUDIES.items())
    rep.add_argument("--case", action="append", dest="cases", metavar="NAME",
                     help="case to run (repeatable; default: each study's published cases). "
                          f"Known cases - {known}")
    rep.add_argument("--horizon", action="append", type=_horizon_arg,
                     metavar="[STUDY=]SECONDS",
                     help="simulated time for every study, or for one study "
                          "(repeatable, e.g. --horizon spacecraft=2000); default: the "
                          "published horizons")
    rep.add_argument("--stride", type=int, metavar="N",
                     help="keep every N-th sample in the CSV (default: 10 = 1 s for the "
                          "spacecraft, 1 for the CMG)")
    rep.add_argument("--engine", choices=["fast", "python-control"], default="fast",
                     help="simulator: fast (compiled, default) or python-control (the "
                          "reference; same numbers, minutes instead of seconds)")
    rep.add_argument("--set", action="append", type=_set_arg, dest="options", default=[],
                     metavar="NAME=VALUE",
                     help="a keyword of every case's run, e.g. --set F=0.002 (the outer "
                          "gain of the spacecraft cases)")
    from . import robustness

    robustness.add_cli(sub)
    args = parser.parse_args(argv)
    try:
        if args.command == "sweep":
            try:
                robustness.run_cli(args)
            except ValueError as error:  # failed runs are rows: what escapes is an argument
                raise UsageError(str(error)) from error
            return 0
        horizon = None
        for study, seconds in args.horizon or []:
            if study is None:
                horizon = seconds if not isinstance(horizon, dict) else {
                    **{s: seconds for s in STUDIES}, **horizon}
            else:
                horizon = {**({s: horizon for s in STUDIES} if isinstance(horizon, float)
                              else horizon or {}), study: seconds}
        summary = reproduce(args.study, out=args.out, cases=args.cases, horizon=horizon,
                            stride=args.stride, engine=args.engine,
                            options=dict(args.options))
    except KeyboardInterrupt:
        print("controlkit: interrupted; finished files are kept and run.json lists what is "
              "missing", file=sys.stderr)
        return 130
    except Exception as error:  # one line, unless --debug
        if args.debug:
            raise
        kind = "error" if isinstance(error, UsageError | argparse.ArgumentTypeError) else \
            f"failed ({type(error).__name__})"
        print(f"controlkit: {kind}: {error}", file=sys.stderr)
        return 2 if isinstance(error, UsageError) else 1
    failed = []
    for study, per_case in summary.items():
        for case, m in per_case.items():
            if isinstance(m, dict) and "error" in m and len(m) == 1:
                failed.append(f"{study}/{case}: {m['error']}")
                continue
            shown = {k: v for k, v in m.items() if isinstance(v, int | float)}
            print(f"{study}/{case}: " + ", ".join(f"{k}={v:.6g}" if isinstance(v, float)
                                                  else f"{k}={v}" for k, v in shown.items()))
    if failed:
        print(f"controlkit: {len(failed)} case(s) failed; " + "; ".join(failed),
              file=sys.stderr)
        return 1
    return 0


# Not before: with the imported objects all in the youngest generation, the definitions
# of this module allocated enough to start collections that walked every one of them
# (0.09 s of the command's floor). The command freezes them first thing (main); a
# program importing this module gets its collector back as it was.
if _COLLECTING:
    gc.enable()

if __name__ == "__main__":
    raise SystemExit(main())
