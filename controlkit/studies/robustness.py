"""A study's robustness sweep: seeded draws of its model errors, summarised per case.

Each study that has one declares a :class:`~controlkit.studies.registry.Robustness`
(what is drawn, what one run returns, what success is); :func:`study` runs it over
:func:`controlkit.sweep.sweep` and :func:`summarize` reports, per case, how often the
claim holds, with a Wilson 95 % interval, the median error, and the success rate in
bins of the main drawn parameter.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

from .._jit import available as compiles
from ..outputs.export import remove_stale_partials
from ..sweep import sweep, wilson_interval
from . import STUDIES
from ._sweep_results import RESULT_FILES, requirement_met, write_table_and_summary


def _robustness(name):
    entry = STUDIES.get(name)
    if entry is None or entry.robustness is None:
        known = [s.name for s in STUDIES.values() if s.robustness is not None]
        raise ValueError(f"study must be one of {known}, got {name!r}")
    return entry.robustness


def default_executor() -> str:
    """Where a study's runs go when ``executor`` is not given.

    ``"threads"`` where numba compiles the runs' loops: a compiled loop releases Python's
    lock, so threads of this process share the cores, with no process to start nor
    imports and compiled code to load in each (``benchmarks/bench_sweep.py``, 48
    spacecraft runs on 2 cores: of the paper's 20 000 s, two threads 1.6x faster than
    one and 1.9x faster than two processes; of 2 000 s, 1.2x and 3.0x, numba's start and
    the runs' Python part, which holds the lock, weighing more). ``"processes"``
    otherwise: runs made in Python hold the lock.

    Examples
    --------
    >>> default_executor() in ("threads", "processes")
    True
    """
    return "threads" if compiles() else "processes"


#: How many of the most common run errors a summary lists per case.
SHOWN_ERRORS = 3


def _check_horizon(name, horizon):
    """``horizon`` on the study's time grid, and one run within memory (ValueError)."""
    from ..blocks.sampling import time_grid
    from .reproduce import MEMORY_LIMIT

    entry = STUDIES[name]
    if isinstance(horizon, bool):
        raise ValueError(f"horizon must be a number of seconds, got {horizon!r}")
    try:
        grid = time_grid(horizon, entry.Ts, lazy=True)  # checked without making its samples
    except ValueError as error:
        raise ValueError(f"horizon for {name}: {error}") from None
    need = len(grid) * entry.signals * 8 * 3  # a run's response, its table and metrics
    if need > MEMORY_LIMIT:
        raise ValueError(f"horizon {float(horizon):g} s: a {name} run of {len(grid)} steps "
                         f"would hold about {need / 1e9:.3g} GB in memory (limit "
                         f"{MEMORY_LIMIT / 1e9:.0f} GB per run); shorten it to at most "
                         f"{MEMORY_LIMIT // (entry.signals * 24) * entry.Ts:g} s")
    return float(horizon)


def _check_values(name, spec, case, varied):
    """One run of two samples at the low and at the high ends of the varied parameters:
    a value the study's run refuses (a negative factor, say) is refused now, before the
    store or any worker exists, rather than failing every run."""
    from ..blocks.spacecraft import SingularDecouplingError

    if not varied:
        return
    Ts = STUDIES[name].Ts
    for end in (0, -1):
        values = {k: v[end] for k, v in varied.items()}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # (overflow of an extreme value, say)
                spec.run(case=case, horizon=2 * Ts, **values)
        except (ArithmeticError, SingularDecouplingError):
            return  # the loop diverges there: an outcome the sweep records, not a bad value
        except ValueError as error:
            shown = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v!r}"
                              for k, v in values.items())
            raise ValueError(f"a {name} run refuses the {'low' if end == 0 else 'high'} end "
                             f"of the varied values ({shown}): {error}") from None


def study(name, *, samples=None, seed=None, cases=None, horizon=None, ranges=None,
          grid=None, executor=None, workers=None, scheduler=None, out=None, resume=False,
          timeout=None, progress=True):
    """Run study ``name``'s robustness sweep and (with ``out``) write its files.

    Every argument is checked before the store or any worker is created: the horizon on
    the study's time grid and within memory, the cases, the varied names (each once), and
    the ends of the varied ranges by one two-sample run at each end.

    Parameters
    ----------
    name : str
        A study with a robustness entry: ``"spacecraft"`` (model error of the MEC
        paper) or ``"cmg"`` (friction and inertia of the gyroscope).
    samples : int, optional
        Number of draws, each running every case (default 200). When every drawn
        parameter is on the ``grid`` nothing is drawn: each grid point runs once, and
        ``samples`` is refused.
    seed : int, optional
        Seed of the draws (default 0).
    cases : list of str, optional
        Default: the study's ``default_cases()``; one text is one case.
    horizon : float, optional
        Simulated time per run, s (default: the study's published horizon); a multiple
        of the study's sampling period.
    ranges : dict, optional
        Overrides of the study's ``ranges``, e.g. ``{"momentum_scale": (1.0, 2.0)}``.
    grid : dict, optional
        Drawn parameters taken on a grid instead (name to values); each grid point is
        crossed with the same draws of the others.
    executor : str or concurrent.futures.Executor, optional
        As in :func:`controlkit.sweep.sweep`; default :func:`default_executor` (threads
        where numba compiles the loops, else processes).
    workers, scheduler, resume, timeout, progress
        As in :func:`controlkit.sweep.sweep`.
    out : str or pathlib.Path, optional
        Folder for ``sweep.csv``, ``summary.json``, the figures and the run store. When
        no run finished, the figures (which plot the runs' metrics) are not drawn:
        ``summary.json`` lists the runs' errors.

    Returns
    -------
    table : pandas.DataFrame
        One row per run (see :func:`controlkit.sweep.sweep`).
    summary : dict
        Per case, see :func:`summarize`.

    Examples
    --------
    >>> table, summary = study("spacecraft", samples=2, cases=["without_mec"],
    ...                        horizon=50.0, executor="serial", progress=False)
    >>> len(table), summary["without_mec"]["runs"]
    (2, 2)
    """
    spec = _robustness(name)
    if executor is None and scheduler is None:
        executor = default_executor()
    if cases is None:
        cases = list(spec.default_cases())
    elif isinstance(cases, str):  # one case, not its letters
        cases = [cases]
    else:
        cases = list(cases)
    unknown = [c for c in cases if c not in spec.cases()]
    if unknown:
        raise ValueError(f"unknown case {unknown}; known: {list(spec.cases())}")
    if horizon is not None:
        horizon = _check_horizon(name, horizon)
    for what, given in (("ranges", ranges), ("grid", grid)):
        if given is not None and not isinstance(given, dict):
            raise ValueError(f"{what} must be a dict of parameter -> values, got {given!r}")
    ranges, grid = dict(ranges or {}), dict(grid or {})
    for k, v in ranges.items():
        try:
            low, high = (float(x) for x in v)
        except (TypeError, ValueError):
            low = high = float("nan")
        if not (math.isfinite(low) and math.isfinite(high) and low <= high):
            raise ValueError(f"ranges[{k!r}] must be a (low, high) pair of finite numbers with "
                             f"low <= high, got {v!r}")
    unknown = sorted((set(ranges) | set(grid)) - set(spec.ranges))
    if unknown:
        raise ValueError(f"unknown varied parameters {unknown}; known: {list(spec.ranges)}")
    both = sorted(set(ranges) & set(grid))
    if both:
        raise ValueError(f"{both} are given both a range and a grid; give each one once")
    span = {**spec.ranges, **ranges}
    drawn = {**{k: tuple(map(float, v)) for k, v in span.items()}, **spec.extra_draws}
    draws = {k: v for k, v in drawn.items() if k not in grid}
    if not draws:
        if samples is not None:
            raise ValueError(f"samples={samples!r} would draw nothing: every parameter of the "
                             f"{name} study is on the grid ({', '.join(grid)}), so each grid "
                             "point runs once; omit samples (--samples), or draw a parameter")
    elif samples is None:
        samples = 200
    if draws and seed is None:
        seed = 0
    if ranges or grid:
        checked = {k: sorted(map(float, v)) for k, v in ranges.items()}
        for k, values in grid.items():
            try:
                checked[k] = sorted(float(v) for v in values)
            except (TypeError, ValueError):
                raise ValueError(f"grid[{k!r}] must be a list of numbers, got {values!r}"
                                 ) from None
            if not checked[k]:
                raise ValueError(f"grid[{k!r}] has no values")
        _check_values(name, spec, cases[0], checked)
    fixed = {} if horizon is None else {"horizon": horizon}
    if out is not None:  # found after the runs, a folder in the way would cost them all
        for name in RESULT_FILES:
            if (Path(out) / name).is_dir():
                raise ValueError(f"out: {Path(out) / name} is a folder, where the sweep "
                                 f"writes its {name}; move it away or choose another out")
    table = sweep(spec.run, grid=grid or None, draws=draws or None, samples=samples,
                  seed=seed, cases=cases, fixed=fixed, executor=executor, workers=workers,
                  scheduler=scheduler, store=None if out is None else Path(out) / "store",
                  resume=resume, timeout=timeout, warmup=lambda: spec.warmup(cases),
                  progress=progress)
    summary = summarize(table, cases, spec, span)
    if out is not None:
        remove_stale_partials(out)  # what a killed run of this sweep was writing
        settings = dict(seed=seed, samples=samples, horizon=horizon, ranges=ranges,
                        grid=grid)
        if (table["error"] == "").any():
            spec.write(table, summary, out, **settings)
        else:
            _write_without_figures(table, summary, out, settings)
    return table, summary


def _write_without_figures(table, summary, out, settings) -> None:
    """``sweep.csv`` and ``summary.json`` of a sweep in which no run finished (the
    figures plot metrics that no run returned)."""
    write_table_and_summary(table, {"settings": settings, "cases": summary,
                                    "figures": "none: no run finished"}, out)


def summarize(table, cases, spec, span) -> dict:
    """Per case: runs, successes, the rate with its Wilson 95 % interval, failed runs and
    their most common errors (``errors``: text to count, at most :data:`SHOWN_ERRORS`), the
    median error of the runs that finished, and the success rate per bin (``spec.binned``).

    Examples
    --------
    >>> import pandas as pd
    >>> from controlkit.studies.cmg.robustness import ROBUSTNESS, RANGES
    >>> table = pd.DataFrame({"case": ["thesis"] * 2, "error": ["", "boom"],
    ...                       "tracking_met": [True, None], "friction_scale": [1.0, 2.0],
    ...                       "max_abs_q2_error_after_1s_rad": [1e-4, None]})
    >>> s = summarize(table, ["thesis"], ROBUSTNESS, RANGES)["thesis"]
    >>> s["requirement_met"], s["failed_runs"], s["median_error"], s["errors"]
    (1, 1, 0.0001, {'boom': 1})
    """
    summary = {}
    ok = table["error"] == ""
    # metrics no run returned (every run failed) are missing, not zero
    table = table.assign(**{c: None for c in (spec.success, spec.error) if c not in table})
    _check_metric_kinds(table[ok], spec)
    for case in cases:
        mine = table[table["case"] == case]
        good = ok[mine.index]
        met = int(requirement_met(mine, spec.success).sum())
        low, high = wilson_interval(met, len(mine))
        errors = mine.loc[good, spec.error]
        key, bins = spec.binned(mine, span)
        summary[case] = {
            "runs": len(mine), "requirement_met": met,
            "success_rate": met / len(mine) if len(mine) else float("nan"),
            "success_rate_95ci": [low, high],
            "failed_runs": int((~good).sum()),
            "median_error": float(errors.median()) if len(errors) else float("nan"),
            "errors": {text: int(n) for text, n in
                       mine.loc[~good, "error"].value_counts().head(SHOWN_ERRORS).items()},
            key: bins,
        }
    return summary


def _check_metric_kinds(finished, spec) -> None:
    """ValueError naming the runs whose stored metrics are not of their kind (a number for
    ``spec.error``, True/False for ``spec.success``): rows edited by hand or written by
    something else, which the summary cannot count."""
    kinds = ((spec.error, "a number", lambda v: isinstance(v, int | float) and
              not isinstance(v, bool)),
             (spec.success, "True or False", lambda v: isinstance(v, bool)))
    for column, kind, fits in kinds:
        runs = finished["run"] if "run" in finished else finished.index
        bad = [(int(run), v) for run, v in zip(runs, finished[column], strict=True)
               if v is not None and not (isinstance(v, float) and math.isnan(v))
               and not fits(v.item() if hasattr(v, "item") else v)]
        if bad:
            shown = [run for run, _ in bad[:5]]
            raise ValueError(f"the finished runs {shown}{' ...' if len(bad) > 5 else ''} "
                             f"have a {column!r} that is not {kind} (e.g. "
                             f"{bad[0][1]!r}): rows of the "
                             "store (store/runs.jsonl) edited or written by something else; "
                             "remove those lines and resume to make these runs again")
