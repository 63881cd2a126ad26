"""A study's robustness sweep: seeded draws of its model errors, summarised per case.

Each study that has one declares a :class:`~controlkit.studies.registry.Robustness`
(what is drawn, what one run returns, what success is); :func:`study` runs it over
:func:`controlkit.sweep.sweep` and :func:`summarize` reports, per case, how often the
claim holds, with a Wilson 95 % interval, the median error, and the success rate in
bins of the main drawn parameter.
"""

from __future__ import annotations

from pathlib import Path

from ..sweep import sweep, wilson_interval
from . import STUDIES


def _robustness(name):
    entry = STUDIES.get(name)
    if entry is None or entry.robustness is None:
        known = [s.name for s in STUDIES.values() if s.robustness is not None]
        raise ValueError(f"study must be one of {known}, got {name!r}")
    return entry.robustness


def study(name, *, samples=200, seed=0, cases=None, horizon=None, ranges=None, grid=None,
          executor=None, workers=None, scheduler=None, out=None, resume=False,
          progress=True):
    """Run study ``name``'s robustness sweep and (with ``out``) write its files.

    Parameters
    ----------
    name : str
        A study with a robustness entry: ``"spacecraft"`` (model error of the MEC
        paper) or ``"cmg"`` (friction and inertia of the gyroscope).
    samples : int
        Number of draws (each runs every case).
    seed : int
        Seed of the draws.
    cases : list of str, optional
        Default: the study's ``default_cases()``.
    horizon : float, optional
        Simulated time per run, s (default: the study's published horizon).
    ranges : dict, optional
        Overrides of the study's ``ranges``, e.g. ``{"momentum_scale": (1.0, 2.0)}``.
    grid : dict, optional
        Drawn parameters taken on a grid instead (name to values); each grid point is
        crossed with the same draws of the others.
    executor, workers, scheduler, resume, progress
        As in :func:`controlkit.sweep.sweep`.
    out : str or pathlib.Path, optional
        Folder for ``sweep.csv``, ``summary.json``, the figures and the run store.

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
    cases = list(cases or spec.default_cases())
    span = {**spec.ranges, **(ranges or {})}
    unknown = sorted(set(span) - set(spec.ranges))
    if unknown:
        raise ValueError(f"unknown varied parameters {unknown}; known: {list(spec.ranges)}")
    grid = dict(grid or {})
    drawn = {**{k: tuple(map(float, v)) for k, v in span.items()}, **spec.extra_draws}
    fixed = {} if horizon is None else {"horizon": float(horizon)}
    table = sweep(spec.run, grid=grid or None,
                  draws={k: v for k, v in drawn.items() if k not in grid}, samples=samples,
                  seed=seed, cases=cases, fixed=fixed, executor=executor, workers=workers,
                  scheduler=scheduler, store=None if out is None else Path(out) / "store",
                  resume=resume, warmup=lambda: spec.warmup(cases), progress=progress)
    summary = summarize(table, cases, spec, span)
    if out is not None:
        spec.write(table, summary, out, seed=seed, samples=samples, horizon=horizon,
                   ranges=ranges, grid=grid)
    return table, summary


def summarize(table, cases, spec, span) -> dict:
    """Per case: runs, successes, the rate with its Wilson 95 % interval, failed runs, the
    median error of the runs that finished, and the success rate per bin (``spec.binned``).

    Examples
    --------
    >>> import pandas as pd
    >>> from controlkit.studies.cmg.robustness import ROBUSTNESS, RANGES
    >>> table = pd.DataFrame({"case": ["thesis"] * 2, "error": ["", "boom"],
    ...                       "tracking_met": [True, None], "friction_scale": [1.0, 2.0],
    ...                       "max_abs_q2_error_after_1s_rad": [1e-4, None]})
    >>> s = summarize(table, ["thesis"], ROBUSTNESS, RANGES)["thesis"]
    >>> s["requirement_met"], s["failed_runs"], s["median_error"]
    (1, 1, 0.0001)
    """
    summary = {}
    ok = table["error"] == ""
    for case in cases:
        mine = table[table["case"] == case]
        good = ok[mine.index]
        met = int((mine[spec.success].fillna(False).astype(bool) & good).sum())
        low, high = wilson_interval(met, len(mine))
        errors = mine.loc[good, spec.error]
        key, bins = spec.binned(mine, span)
        summary[case] = {
            "runs": len(mine), "requirement_met": met,
            "success_rate": met / len(mine) if len(mine) else float("nan"),
            "success_rate_95ci": [low, high],
            "failed_runs": int((~good).sum()),
            "median_error": float(errors.median()) if len(errors) else float("nan"),
            key: bins,
        }
    return summary
