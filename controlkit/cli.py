"""The ``controlkit`` command line: ``controlkit reproduce`` writes the papers' results.

Each study is one :class:`Study` entry of :data:`STUDIES`; each case is one
entry of its scenario's ``CASES``. Adding a study or a case adds no code here.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from .outputs import cmg as cmg_out
from .outputs import frit as frit_out
from .outputs import spacecraft as sc_out
from .outputs.export import write_csv, write_json
from .outputs.workers import FigureWorkers
from .scenarios import cmg as cmg_scenario
from .scenarios import frit as frit_scenario
from .scenarios import spacecraft as sc_scenario


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
        Response to a JSON-ready dict.
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
    simulation_cost: float = 1.0
    write: Callable | None = None
    in_all: bool = True


def _runner(scenario):
    """``run(case, horizon, progress, engine)`` of a scenarios module (``HORIZON`` if None)."""
    def run(case, horizon, progress, engine):
        return scenario.run(case, horizon=horizon or scenario.HORIZON, progress=progress,
                            engine=engine)

    return run


STUDIES: dict[str, Study] = {
    "spacecraft": Study(
        "spacecraft", tuple(sc_scenario.CASES), sc_scenario.DEFAULT_CASES, _runner(sc_scenario),
        sc_out.table, sc_out.metrics, sc_out.figures, default_stride=10,
        figure_stems=tuple(spec[0] for spec in sc_out.FIGURES),
    ),
    "cmg": Study(
        "cmg", tuple(cmg_scenario.CASES), cmg_scenario.DEFAULT_CASES, _runner(cmg_scenario),
        cmg_out.table, cmg_out.metrics, cmg_out.figures,
        csv_stem=lambda case: "run" if case == "thesis" else case,
        csv_columns=cmg_out.csv_columns,
        figure_stems=tuple(spec[0] for spec in cmg_out.FIGURES),
        simulation_cost=0.05,  # 12 000 steps of a 10-state loop vs 3 x 200 000 steps
    ),
    "frit": Study(
        "frit", frit_scenario.CASES, frit_scenario.DEFAULT_CASES, _runner(frit_scenario),
        None, None, None, write=frit_out.write, in_all=False,
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


def _select_cases(studies: list[Study], requested: list[str] | None) -> dict[str, list[str]]:
    if not requested:
        return {s.name: list(s.default_cases) for s in studies}
    known = {c for s in studies for c in s.cases}
    unknown = [c for c in requested if c not in known]
    if unknown:
        allowed = {s.name: list(s.cases) for s in studies}
        raise SystemExit(f"controlkit reproduce: unknown --case {unknown}; known cases: {allowed}")
    return {s.name: [c for c in requested if c in s.cases] for s in studies}


def reproduce(study="all", *, out="results", cases=None, horizon=None, stride=None,
              engine="fast", log=None, workers=None) -> dict:
    """Run studies and write their CSV, metrics and figures (the CLI's main job).

    Parameters
    ----------
    study : str
        A key of :data:`STUDIES` or ``"all"``.
    out : str or pathlib.Path
        Output folder; each study writes to ``out/<study>/``.
    cases : list of str, optional
        Cases to run (default: each study's default cases).
    horizon : float, optional
        Simulated time in seconds (default: each study's published horizon).
    stride : int, optional
        Keep every ``stride``-th sample in the CSV (default 10 for the
        spacecraft, i.e. 1 s; 1 for the CMG).
    engine : {"fast", "python-control"}
        Simulator; both give the same numbers, the fast one in seconds.
    log : file-like, optional
        Where progress goes (default stderr).
    workers : int, optional
        Processes drawing the figures while the next study is simulated (default: one
        per CPU, at most 4; 0 draws them in this process).

    Returns
    -------
    dict
        ``{study: {case: metrics}}``.

    Examples
    --------
    >>> import io, tempfile
    >>> m = reproduce("spacecraft", out=tempfile.mkdtemp(), cases=["ideal"], horizon=1.0,
    ...               log=io.StringIO())
    >>> sorted(m["spacecraft"])
    ['ideal']
    """
    log = log or sys.stderr
    if study != "all" and study not in STUDIES:
        raise SystemExit(f"controlkit reproduce: unknown study {study!r}; "
                         f"choose from {['all', *STUDIES]}")
    studies = ([s for s in STUDIES.values() if s.in_all] if study == "all"
               else [STUDIES[study]])
    selection = _select_cases(studies, cases)
    summary = {}
    with FigureWorkers(workers) as pool:
        for s in sorted(studies, key=lambda study: study.simulation_cost):
            if not selection[s.name]:
                continue
            folder = Path(out) / s.name
            if s.write is not None:  # a study of many runs per case writes its own files
                results = {}
                for case in selection[s.name]:
                    log.write(f"{s.name}/{case}\n")
                    results[case] = s.run(case, horizon,
                                          _progress_printer(f"{s.name}/{case}", log), engine)
                summary[s.name], paths = s.write(results, folder)
                log.writelines(f"  wrote {path}\n" for path in paths)
                continue
            tables, study_metrics = {}, {}
            for case in selection[s.name]:
                log.write(f"{s.name}/{case}\n")
                started = time.perf_counter()
                resp = s.run(case, horizon, _progress_printer(f"{s.name}/{case}", log), engine)
                elapsed = time.perf_counter() - started
                step = stride if stride is not None else s.default_stride
                columns = s.table(resp)
                # figures are drawn from the CSV's samples: 20 001 points per curve is plenty
                tables[case] = {name: values[::step] for name, values in columns.items()}
                write_csv(folder / f"{s.csv_stem(case)}.csv", s.csv_columns(columns),
                          stride=step)
                study_metrics[case] = {**s.metrics(resp), "wall_time_s": round(elapsed, 3)}
            write_json(folder / "metrics.json", study_metrics)
            # drawn by the workers while the next study runs
            if s.figure_stems:
                pool.submit(s.figures, tables, folder, s.figure_stems)
            else:
                for path in s.figures(tables, folder):
                    log.write(f"  wrote {path}\n")
            summary[s.name] = study_metrics
        for path in pool.results():
            log.write(f"  wrote {path}\n")
    summary = {s.name: summary[s.name] for s in studies if s.name in summary}
    return summary


def main(argv=None) -> int:
    """Entry point of the ``controlkit`` command.

    Examples
    --------
    >>> main(["--help"])  # doctest: +SKIP
    """
    parser = argparse.ArgumentParser(prog="controlkit", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    rep = sub.add_parser(
        "reproduce", help="run the papers' cases and write CSV, metrics.json and figures"
    )
    rep.add_argument("study", nargs="?", default="all", choices=["all", *STUDIES],
                     help="which study (default: all = the papers' studies; frit = the "
                          "sensitivity of the FRIT claim, asked for by name)")
    rep.add_argument("--out", default="results", help="output folder (default: results)")
    known = "; ".join(f"{name}: {', '.join(study.cases)}" for name, study in STUDIES.items())
    rep.add_argument("--case", action="append", dest="cases", metavar="NAME",
                     help="case to run (repeatable; default: each study's published cases). "
                          f"Known cases - {known}")
    rep.add_argument("--horizon", type=float, metavar="SECONDS",
                     help="simulated time (default: the published horizon)")
    rep.add_argument("--stride", type=int, metavar="N",
                     help="keep every N-th sample in the CSV (default: 10 = 1 s for the "
                          "spacecraft, 1 for the CMG)")
    rep.add_argument("--engine", choices=["fast", "python-control"], default="fast",
                     help="simulator: fast (compiled, default) or python-control (the "
                          "reference; same numbers, minutes instead of seconds)")
    from . import robustness

    robustness.add_cli(sub)
    args = parser.parse_args(argv)
    if args.command == "sweep":
        robustness.run_cli(args)
        return 0
    if args.stride is not None and args.stride < 1:
        parser.error("--stride must be >= 1")
    if args.horizon is not None and args.horizon <= 0:
        parser.error("--horizon must be > 0")
    summary = reproduce(args.study, out=args.out, cases=args.cases, horizon=args.horizon,
                        stride=args.stride, engine=args.engine)
    for study, per_case in summary.items():
        for case, m in per_case.items():
            shown = {k: v for k, v in m.items() if isinstance(v, int | float)}
            print(f"{study}/{case}: " + ", ".join(f"{k}={v:.6g}" if isinstance(v, float)
                                                  else f"{k}={v}" for k, v in shown.items()))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
