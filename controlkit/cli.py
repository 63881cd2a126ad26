"""The ``controlkit`` command line: argument parsing for ``reproduce`` and ``sweep``.

``controlkit reproduce`` runs :func:`controlkit.studies.reproduce.reproduce`;
``controlkit sweep`` runs :func:`controlkit.studies.robustness.study`. The studies
and their options come from :data:`controlkit.studies.STUDIES`.
"""

from __future__ import annotations

import argparse
import gc
import signal
import sys

# Importing python-control (with scipy, matplotlib and numba) creates ~200 000 objects that
# live as long as the process; the garbage collector's passes over them while they are
# created find nothing to free and took a tenth of the import (0.1 s of the command's
# 1.2 s floor). It is switched back on, if it was on, at the end of this module.
_COLLECTING = gc.isenabled()
gc.disable()
try:
    import numpy as np

    from .studies import STUDIES
    from .studies.registry import UsageError
    from .studies.reproduce import _horizons, reproduce
except BaseException:
    if _COLLECTING:
        gc.enable()
    raise


HELP = """Reproduce the papers' results and study their robustness.

  controlkit reproduce [spacecraft|cmg|frit|all] [--case NAME]... [--horizon SECONDS]
  controlkit sweep spacecraft --samples N --out DIR
  controlkit warmup          (compile ahead of a lecture: a few minutes after an install)

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


def _vary(text, known):
    """``NAME=LOW:HIGH`` (drawn uniformly) or ``NAME=LOW:HIGH:N`` (an N-point grid)."""
    name, _, span = text.partition("=")
    parts = span.split(":")
    if not name or len(parts) not in (2, 3):
        raise ValueError(f"--vary {text!r}: expected NAME=LOW:HIGH or NAME=LOW:HIGH:N")
    if name not in known:
        raise ValueError(f"--vary {text!r}: unknown parameter {name!r}; known: "
                         f"{list(known)}")
    try:
        low, high = float(parts[0]), float(parts[1])
        n = int(parts[2]) if len(parts) == 3 else None
    except ValueError:
        raise ValueError(f"--vary {text!r}: LOW and HIGH must be numbers and N an "
                         "integer") from None
    if not (np.isfinite(low) and np.isfinite(high) and low <= high) or (n is not None
                                                                         and n < 1):
        raise ValueError(f"--vary {text!r}: needs finite LOW <= HIGH and N >= 1")
    from .sweep import MAX_RUNS

    if n is not None and n > MAX_RUNS:  # refused before its points are made
        raise ValueError(f"--vary {text!r}: {n:,} grid points is more than one sweep holds "
                         f"(MAX_RUNS = {MAX_RUNS:,})")
    return name, (low, high), n


def _add_sweep(subparsers) -> None:
    """Add ``controlkit sweep`` to the command line's subcommands: one study's robustness
    sweep (:func:`controlkit.studies.robustness.study`), for every study that has one."""
    swept = {name: s.robustness for name, s in STUDIES.items() if s.robustness is not None}
    p = subparsers.add_parser(
        "sweep", help="robustness study: many model errors, on all cores or a Dask cluster",
        description="Run the robustness study of the spacecraft paper: seeded draws of the "
                    "inertia error, the amplitude of H0 and the initial attitude, each run "
                    "for every case; writes sweep.csv, summary.json and figures.")
    p.add_argument("study", choices=list(swept),
                   help="spacecraft (model error of the MEC paper) or cmg (friction and "
                        "inertia of the gyroscope)")
    p.add_argument("--case", action="append", dest="cases", metavar="NAME",
                   help="case to run (repeatable; spacecraft default: without_mec, "
                        "mec_fixed, proposed, safeguarded; cmg default: thesis)")
    p.add_argument("--samples", type=int, metavar="N",
                   help="number of draws (default 200; none when every parameter is on a "
                        "grid: each grid point then runs once)")
    p.add_argument("--seed", type=int, metavar="S", help="seed of the draws (default 0)")
    p.add_argument("--horizon", type=float, metavar="SECONDS",
                   help="simulated time per run, a multiple of the study's sampling period "
                        "(default: the published horizon)")
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LOW:HIGH[:N]",
                   help="range of a drawn parameter ("
                        + "; ".join(f"{name}: {', '.join(r.ranges)}" for name, r in swept.items())
                        + "); with :N it is an N-point grid crossed with the draws")
    p.add_argument("--workers", type=int, metavar="N", help="workers (default: all cores)")
    p.add_argument("--executor", choices=["processes", "threads", "serial", "dask"],
                   help="where runs go (default: threads where numba compiles the runs' "
                        "loops, which release Python's lock; else local processes)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://host:8786 (with --executor dask)")
    p.add_argument("--timeout", type=float, metavar="SECONDS",
                   help="longest run: a run still going after it is a failed row "
                        "(TimeoutError) and the sweep goes on")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--resume", action="store_true",
                   help="complete the interrupted sweep in DIR without repeating its runs")


def _sweep(args) -> int:
    """Run ``controlkit sweep`` from parsed arguments, print the summary; the exit status.

    Every argument is checked, and ``--out`` proven writable, before the store or any
    worker is created. A run that fails is a row; when every run failed the command says
    so with the runs' most common errors and exits with 1.

    Examples
    --------
    >>> import tempfile
    >>> main(["sweep", "spacecraft", "--samples", "2", "--horizon", "20", "--case", "ideal",
    ...       "--executor", "serial", "--out", tempfile.mkdtemp()])  # doctest: +ELLIPSIS
    sweep/ideal: runs=2, requirement_met=...
    0
    """
    if args.samples is not None and args.samples < 1:
        raise ValueError(f"--samples must be >= 1, got {args.samples}")
    if args.scheduler is not None and args.executor != "dask":
        raise ValueError("--scheduler goes with --executor dask")
    import warnings
    from pathlib import Path

    from .studies import robustness
    from .studies.reproduce import _writable
    from .sweep import StoreWarning

    spec = STUDIES[args.study].robustness
    unknown = [c for c in args.cases or [] if c not in spec.cases()]
    if unknown:
        raise ValueError(f"unknown --case {unknown}; known: {list(spec.cases())}")
    ranges, grid, given = {}, {}, {}
    for text in args.vary:
        name, span, n = _vary(text, spec.ranges)
        if name in given:
            raise ValueError(f"--vary {name} is given twice ({given[name]!r} and {text!r}); "
                             "give each parameter once")
        given[name] = text
        if n is None:
            ranges[name] = span
        else:
            grid[name] = np.linspace(span[0], span[1], n).tolist()
    existed = Path(args.out).expanduser().exists() if args.out.strip() else True
    out = _writable(args.out)  # "cannot write to out ...", as reproduce says
    shown = warnings.showwarning

    def show(message, category, *rest, **kwargs):  # a store's warning: one line, no source
        if issubclass(category, StoreWarning):
            print(f"controlkit: warning: {message}", file=sys.stderr)
        else:
            shown(message, category, *rest, **kwargs)

    warnings.showwarning = show
    try:
        _, summary = robustness.study(
            args.study, samples=args.samples, seed=args.seed, cases=args.cases,
            horizon=args.horizon, ranges=ranges, grid=grid, executor=args.executor,
            workers=args.workers, scheduler=args.scheduler, out=out, resume=args.resume,
            timeout=args.timeout)
    except ValueError:
        if not existed:  # refused: leave no empty folder behind
            try:
                out.rmdir()
            except OSError:
                pass
        raise
    finally:
        warnings.showwarning = shown
    for case, s in summary.items():
        low_ci, high_ci = s["success_rate_95ci"]
        print(f"sweep/{case}: runs={s['runs']}, requirement_met={s['requirement_met']}, "
              f"success_rate={s['success_rate']:.3f} (95% CI {low_ci:.3f}-{high_ci:.3f}), "
              f"failed_runs={s['failed_runs']}, median_error={s['median_error']:.4g}")
        for text, n in s["errors"].items():
            print(f"  {n} run(s) failed: {text}")
    runs = sum(s["runs"] for s in summary.values())
    if runs and all(s["failed_runs"] == s["runs"] for s in summary.values()):
        first = next(iter(next(iter(summary.values()))["errors"]), "")
        print(f"controlkit: every run failed ({runs} runs; e.g. {first}); sweep.csv lists "
              "each run's error", file=sys.stderr)
        return 1
    return 0


def main(argv=None) -> int:
    """Entry point of the ``controlkit`` command.

    Exit status: 0 on success, 1 when a run failed (one line naming the cause; a case
    that failed while the others completed also gives 1; a sweep whose every run failed
    too), 2 for a usage error (nothing was run), 130 when interrupted (Ctrl-C), 143 when
    terminated (``kill PID``, handled as Ctrl-C). ``--debug`` shows the traceback instead
    of the one line, and stops ``reproduce`` at the first case that fails.

    Examples
    --------
    >>> main(["reproduce", "--horizon", "-3"])  # says why on stderr, in one line
    2
    """
    if argv is None:  # the command line: this process ends when main returns
        _freeze_objects()  # those of the imports
        # `kill PID` stops the run as Ctrl-C does: run.json says what is missing, temporary
        # files are removed, figure workers end
        signal.signal(signal.SIGTERM, _terminate)
    try:
        return _main(argv)
    finally:
        if argv is None:
            _freeze_objects()  # and those of the run, before the interpreter exits


class _Terminated(KeyboardInterrupt):
    """Raised in the command's process by SIGTERM (``kill PID``): handled as Ctrl-C is,
    with exit status 143 (128 + SIGTERM)."""


def _terminate(signum, frame):
    raise _Terminated("terminated (SIGTERM)")


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
                          "(repeatable, e.g. --horizon spacecraft=14000, the shortest "
                          "that shows the paper's claim); default: the published horizons")
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
    _add_sweep(sub)
    sub.add_parser(
        "warmup", help="compile ahead of a lecture: the integrator and the papers' diagrams",
        description="Compile, once, what the course's runs need compiled and keep it in the "
                    "store (CONTROLKIT_CACHE_DIR): the integrator (its step machine and loop) and "
                    "every case of the papers' studies. After an install or an upgrade this takes "
                    "a few minutes; run it before class so that no run waits for a compile.")
    args = parser.parse_args(argv)
    try:
        if args.command == "warmup":
            return _warmup()
        if args.command == "sweep":
            try:
                return _sweep(args)
            except ValueError as error:  # failed runs are rows: what escapes is an argument
                raise UsageError(str(error)) from error
        horizon = None
        named = [study or "every study" for study, _ in args.horizon or []]
        repeated = sorted({n for n in named if named.count(n) > 1})
        if repeated:
            raise UsageError(f"--horizon for {', '.join(repeated)} is given more than once; "
                             "give it once (STUDY=SECONDS sets one study)")
        for study, seconds in args.horizon or []:
            if study is None:
                horizon = seconds if not isinstance(horizon, dict) else {
                    **{s: seconds for s in STUDIES}, **horizon}
            else:
                horizon = {**({s: horizon for s in STUDIES} if isinstance(horizon, float)
                              else horizon or {}), study: seconds}
        repeated = sorted({name for name, _ in args.options
                           if [n for n, _ in args.options].count(name) > 1})
        if repeated:
            raise UsageError(f"--set {', '.join(repeated)} is given more than once; give each "
                             "option once")
        summary = reproduce(args.study, out=args.out, cases=args.cases, horizon=horizon,
                            stride=args.stride, engine=args.engine,
                            options=dict(args.options), raise_errors=args.debug)
    except KeyboardInterrupt as stop:
        if args.command == "sweep":
            print("controlkit: interrupted; the finished runs are kept in the store: the same "
                  "command with --resume makes only the others", file=sys.stderr)
        else:
            print("controlkit: interrupted; finished files are kept and run.json lists what "
                  "is missing", file=sys.stderr)
        return 143 if isinstance(stop, _Terminated) else 130
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
    for study in summary:  # what a short horizon cannot show
        seconds = _horizons([STUDIES[study]], horizon)[study]
        note = STUDIES[study].horizon_note
        if seconds is not None and note is not None and note(seconds):
            print(f"{study}: note: {note(seconds)}")
    if failed:
        print(f"controlkit: {len(failed)} case(s) failed; " + "; ".join(failed),
              file=sys.stderr)
        return 1
    return 0


def _warmup() -> int:
    """``controlkit warmup``: the integrator, then each study's cases, compiled."""
    import time

    from .engines.fast import store
    from .engines.fast.continuous import compile_integrator

    started = time.perf_counter()
    print("controlkit warmup: the integrator (its step machine and loop)", flush=True)
    compile_integrator()
    for name, study in STUDIES.items():
        spec = study.robustness
        if spec is None:
            continue
        cases = tuple(spec.cases())
        for i, case in enumerate(cases, start=1):
            print(f"controlkit warmup: {name} {case} ({i}/{len(cases)}, "
                  f"{time.perf_counter() - started:.0f} s so far)", flush=True)
            spec.warmup([case])
    print(f"controlkit warmup: done in {time.perf_counter() - started:.0f} s; later runs "
          f"load what was compiled from {store.folder()}", flush=True)
    return 0


# Not before: with the imported objects all in the youngest generation, the definitions
# of this module allocated enough to start collections that walked every one of them
# (0.09 s of the command's floor). The command freezes them first thing (main); a
# program importing this module gets its collector back as it was.
if _COLLECTING:
    gc.enable()

if __name__ == "__main__":
    raise SystemExit(main())
