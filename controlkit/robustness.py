"""How robust is MEC? The spacecraft paper's claim over many model errors.

The paper shows one model error (Table 2). This study draws many: each
diagonal entry of ``Delta J`` scaled by a factor from 0 to 3, the amplitude of
``H0(t)`` from 0.5 to 5 times the paper's, and the initial attitude (a random
axis, 10 to 60 deg); every draw runs each case (the same draw for every case,
so the cases are compared on equal terms), and the study reports how often
the 0.05 deg requirement holds over the last half of the run, with a Wilson
95 % interval, the distribution of the error per case, and the success rate
against the size of the inertia error.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .blocks.spacecraft import POINTING_REQUIREMENT_DEG, pointing_error_deg
from .sweep import check_folder, sweep, wilson_interval

#: Cases compared by default (``safeguarded`` joins when the scenario has it).
BASE_CASES = ("without_mec", "mec_fixed", "proposed")
#: The drawn parameters and their ranges (uniform): factors on Table 2's model error
#: and the initial rotation angle in degrees. The axis is drawn by ``_axis``.
RANGES = {
    "inertia_error_x": (0.0, 3.0),
    "inertia_error_y": (0.0, 3.0),
    "inertia_error_z": (0.0, 3.0),
    "momentum_scale": (0.5, 5.0),
    "angle_deg": (10.0, 60.0),
}


def default_cases() -> tuple[str, ...]:
    """The study's cases: :data:`BASE_CASES`, plus ``safeguarded`` where it exists.

    Examples
    --------
    >>> default_cases()[:3]
    ('without_mec', 'mec_fixed', 'proposed')
    """
    from .scenarios import spacecraft

    return BASE_CASES + (("safeguarded",) if "safeguarded" in spacecraft.CASES else ())


def _normal(rng):
    return float(rng.normal())


def draws(ranges: dict | None = None) -> dict:
    """The distributions of the spacecraft study (:data:`RANGES`, overridable by name).

    The rotation axis is ``(axis_x, axis_y, axis_z)``, three standard normal draws
    (their direction is uniform on the sphere).

    Examples
    --------
    >>> sorted(draws({"angle_deg": (20.0, 30.0)}))[:2]
    ['angle_deg', 'axis_x']
    """
    ranges = {**RANGES, **(ranges or {})}
    unknown = sorted(set(ranges) - set(RANGES))
    if unknown:
        raise ValueError(f"unknown varied parameters {unknown}; known: {list(RANGES)}")
    return {**{name: tuple(map(float, span)) for name, span in ranges.items()},
            "axis_x": _normal, "axis_y": _normal, "axis_z": _normal}


def spacecraft_run(case, *, inertia_error_x=1.0, inertia_error_y=1.0, inertia_error_z=1.0,
                   momentum_scale=1.0, axis_x=1.0, axis_y=2.0, axis_z=3.0, angle_deg=30.0,
                   horizon=None, keep_every=0) -> dict:
    """One run of the study: the metrics of a case under one model error and attitude.

    Parameters
    ----------
    case : str
        A case of :data:`controlkit.scenarios.spacecraft.CASES`.
    inertia_error_x, inertia_error_y, inertia_error_z : float
        Factors on the diagonal of Table 2's ``Delta J`` (1: the paper's).
    momentum_scale : float
        Factor on the amplitude of ``H0(t)``.
    axis_x, axis_y, axis_z, angle_deg : float
        Initial attitude: a rotation of ``angle_deg`` about this axis (the paper's:
        30 deg about ``[1, 2, 3]``).
    horizon : float, optional
        Simulated time, s (default the paper's 20 000 s).
    keep_every : int
        When > 0, also return the pointing error every ``keep_every`` samples as
        ``"trajectory"`` (kept by :func:`~controlkit.sweep.sweep` per run).

    Returns
    -------
    dict
        ``max_pointing_error_last_half_deg``, ``final_pointing_error_deg``,
        ``requirement_met_last_half``, ``peak_abs_u_rad_s``, ``max_abs_K``.

    Examples
    --------
    >>> m = spacecraft_run("without_mec", horizon=100.0)
    >>> m["requirement_met_last_half"]
    False
    """
    from .blocks import spacecraft as sc
    from .scenarios import spacecraft

    kwargs = {} if horizon is None else {"horizon": horizon}
    q0 = sc.quaternion_from_axis_angle([axis_x, axis_y, axis_z], angle_deg)
    resp = spacecraft.run(case, q_initial=q0, plant_options={
        "inertia_error_scale": [inertia_error_x, inertia_error_y, inertia_error_z],
        "momentum_scale": momentum_scale}, **kwargs)
    labels = list(resp.output_labels)

    def rows(name, n):
        present = [f"{name}[{i}]" for i in range(n) if f"{name}[{i}]" in labels]
        return resp.outputs[[labels.index(label) for label in present]]

    t = resp.time
    error = pointing_error_deg(rows("q", 4))
    worst = float(error[t >= t[-1] / 2].max())
    K = rows("K", 4)
    result = {
        "max_pointing_error_last_half_deg": worst,
        "final_pointing_error_deg": float(error[-1]),
        "requirement_met_last_half": bool(worst <= POINTING_REQUIREMENT_DEG),
        "peak_abs_u_rad_s": float(np.abs(rows("u", 2)).max()),
        "max_abs_K": float(np.abs(K).max()) if K.size else 0.0,
    }
    if keep_every:
        result["trajectory"] = {"time": t[::keep_every], "error_deg": error[::keep_every]}
    return result


def warm_cases(cases) -> None:
    """Compile each case's simulation loop once (numba's disk cache), before workers start.

    Examples
    --------
    >>> warm_cases(["ideal"])
    """
    from .blocks.spacecraft import TS_PAPER
    from .scenarios import spacecraft

    for case in cases:
        spacecraft.run(case, horizon=2 * TS_PAPER)


def _success(table, cases, factor_bins):
    summary = {}
    ok = table["error"] == ""
    for case in cases:
        mine = table[table["case"] == case]
        met = int((mine["requirement_met_last_half"].fillna(False).astype(bool)
                   & ok[mine.index]).sum())
        low, high = wilson_interval(met, len(mine))
        errors = mine.loc[ok[mine.index], "max_pointing_error_last_half_deg"]
        summary[case] = {
            "runs": len(mine), "requirement_met": met,
            "success_rate": met / len(mine) if len(mine) else float("nan"),
            "success_rate_95ci": [low, high],
            "failed_runs": int((~ok[mine.index]).sum()),
            "median_error": float(errors.median()) if len(errors) else float("nan"),
            "success_by_inertia_error": _binned(mine, factor_bins),
        }
    return summary


def _binned(mine, bins):
    factor = mine[["inertia_error_x", "inertia_error_y", "inertia_error_z"]].mean(axis=1)
    met = mine["requirement_met_last_half"].fillna(False).astype(bool) & (mine["error"] == "")
    out = []
    for low, high in zip(bins[:-1], bins[1:], strict=True):
        inside = (factor >= low) & (factor < high if high < bins[-1] else factor <= high)
        n = int(inside.sum())
        out.append({"mean_factor_low": float(low), "mean_factor_high": float(high), "runs": n,
                    "success_rate": float(met[inside].mean()) if n else float("nan")})
    return out


def spacecraft_study(*, samples=200, seed=0, cases=None, horizon=None, ranges=None,
                     grid=None, executor=None, workers=None, scheduler=None, out=None,
                     resume=False, progress=True):
    """Run the robustness study and (with ``out``) write its table, summary and figures.

    Parameters
    ----------
    samples : int
        Number of drawn model errors and attitudes (each runs every case).
    seed : int
        Seed of the draws.
    cases : list of str, optional
        Default :func:`default_cases`.
    horizon : float, optional
        Simulated time per run, s (default 20 000 s).
    ranges : dict, optional
        Overrides of :data:`RANGES`, e.g. ``{"momentum_scale": (1.0, 2.0)}``.
    grid : dict, optional
        Parameters of :data:`RANGES` taken on a grid instead of drawn (name to values);
        each grid point is crossed with the same draws of the others.
    executor, workers, scheduler, resume, progress
        As in :func:`controlkit.sweep.sweep`.
    out : str or pathlib.Path, optional
        Folder for ``sweep.csv``, ``summary.json``, the figures and the run store.

    Returns
    -------
    table : pandas.DataFrame
        One row per run (see :func:`controlkit.sweep.sweep`).
    summary : dict
        Per case: runs, successes, rate with its Wilson 95 % interval, median error,
        success rate per bin of the mean inertia-error factor.

    Examples
    --------
    >>> table, summary = spacecraft_study(samples=2, cases=["without_mec"], horizon=50.0,
    ...                                   executor="serial", progress=False)
    >>> len(table), summary["without_mec"]["runs"]
    (2, 2)
    """
    cases = list(cases or default_cases())
    fixed = {} if horizon is None else {"horizon": float(horizon)}
    grid = dict(grid or {})
    distributions = {k: v for k, v in draws(ranges).items() if k not in grid}
    table = sweep(spacecraft_run, grid=grid or None, draws=distributions, samples=samples,
                  seed=seed, cases=cases, fixed=fixed, executor=executor, workers=workers,
                  scheduler=scheduler, store=None if out is None else Path(out) / "store",
                  resume=resume, warmup=lambda: warm_cases(cases), progress=progress)
    span = {**RANGES, **(ranges or {})}
    low = np.mean([span[f"inertia_error_{a}"][0] for a in "xyz"])
    high = np.mean([span[f"inertia_error_{a}"][1] for a in "xyz"])
    summary = _success(table, cases, np.linspace(low, high, 7))
    if out is not None:
        write(table, summary, out, seed=seed, samples=samples, horizon=horizon,
              ranges=ranges, grid=grid)
    return table, summary


def write(table, summary, out, **settings) -> list[Path]:
    """Write ``sweep.csv``, ``summary.json`` and the study's figures into ``out``.

    Each file is written under a temporary name and renamed when complete.

    Examples
    --------
    >>> import tempfile
    >>> t, s = spacecraft_study(samples=2, cases=["without_mec"], horizon=20.0,
    ...                         executor="serial", progress=False)
    >>> sorted(p.name for p in write(t, s, tempfile.mkdtemp()))[-2:]
    ['summary.json', 'sweep.csv']
    """
    from .outputs.export import atomic
    from .outputs.style import save

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    with atomic(out / "sweep.csv") as partial:
        table.to_csv(partial, index=False)
    with atomic(out / "summary.json") as partial:
        partial.write_text(json.dumps({"settings": settings, "requirement_deg":
                                       POINTING_REQUIREMENT_DEG, "cases": summary},
                                      indent=2) + "\n")
    paths += [out / "sweep.csv", out / "summary.json"]
    for stem, fig in figures(table, summary).items():
        paths += save(fig, out / f"{stem}.png")
    return paths


#: Colour of each case in the study's figures (the paper's where it has one).
CASE_COLORS = {"without_mec": "tab:green", "mec_fixed": "tab:purple", "proposed": "tab:red",
               "safeguarded": "tab:blue"}


def figures(table, summary) -> dict:
    """The study's two figures, as slide-sized :class:`matplotlib.figure.Figure` objects.

    ``robustness_errors``: the worst last-half error of every run, per case (box plot
    and the runs as dots) on a log axis with the 0.05 deg requirement.
    ``robustness_success_vs_inertia``: success rate against the mean inertia-error
    factor (1 = Table 2), per case.

    Examples
    --------
    >>> t, s = spacecraft_study(samples=3, cases=["without_mec"], horizon=20.0,
    ...                         executor="serial", progress=False)
    >>> sorted(figures(t, s))
    ['robustness_errors', 'robustness_success_vs_inertia']
    """
    from .outputs.style import legend_outside, log_scale, new_figure, slide_style

    cases = list(summary)
    out = {}
    with slide_style():
        fig, (ax,) = new_figure()
        ok = table["error"] == ""
        data = [table.loc[(table["case"] == c) & ok, "max_pointing_error_last_half_deg"]
                .to_numpy() for c in cases]
        data = [np.clip(d, 1e-6, None) for d in data]
        positions = np.arange(1, len(cases) + 1)
        ax.boxplot([d if d.size else [np.nan] for d in data], positions=positions,
                   widths=0.5, showfliers=False)
        rng = np.random.default_rng(0)  # jitter only, so the dots do not hide each other
        for x, case, d in zip(positions, cases, data, strict=True):
            ax.plot(x + rng.uniform(-0.18, 0.18, d.size), d, "o", markersize=3.5, alpha=0.5,
                    color=CASE_COLORS.get(case, "k"))
        ax.axhline(POINTING_REQUIREMENT_DEG, color="k", linestyle=":", linewidth=1.6,
                   label=f"requirement {POINTING_REQUIREMENT_DEG} deg")
        log_scale(ax)
        labels = [f"{c}\n{100 * summary[c]['success_rate']:.1f} % met" for c in cases]
        ax.set_xticks(positions, labels)
        ax.set_ylabel("worst error, last half [deg]")
        runs = summary[cases[0]]["runs"] if cases else 0
        ax.set_title(f"Pointing error over {runs} drawn model errors")
        legend_outside(fig)
        out["robustness_errors"] = fig

        fig, (ax,) = new_figure()
        # distinct markers and dashes: cases at the same rate (often 100 %) stay visible
        styles = ["o-", "s--", "^-.", "D:", "v-"]
        for i, case in enumerate(cases):
            bins = summary[case]["success_by_inertia_error"]
            centres = [(b["mean_factor_low"] + b["mean_factor_high"]) / 2 for b in bins]
            rates = [100 * b["success_rate"] for b in bins]
            ax.plot(centres, rates, styles[i % len(styles)], color=CASE_COLORS.get(case, "k"),
                    label=case, markersize=8 - i, linewidth=2.0)
        ax.axvline(1.0, color="0.4", linestyle="--", linewidth=1.2, label="Table 2's error")
        ax.set_ylim(-5, 105)
        ax.set_xlabel("mean factor on Table 2's inertia error")
        ax.set_ylabel("requirement met [% of runs]")
        ax.set_title("Success rate against the size of the inertia error")
        legend_outside(fig)
        out["robustness_success_vs_inertia"] = fig
    return out


def _vary(text, known=None):
    """``NAME=LOW:HIGH`` (drawn uniformly) or ``NAME=LOW:HIGH:N`` (an N-point grid)."""
    known = RANGES if known is None else known
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
    return name, (low, high), n


def add_cli(subparsers) -> None:
    """Add ``controlkit sweep`` to the command line's subcommands.

    Examples
    --------
    >>> import argparse
    >>> parser = argparse.ArgumentParser(prog="controlkit")
    >>> add_cli(parser.add_subparsers(dest="command"))
    >>> parser.parse_args(["sweep", "spacecraft", "--samples", "3", "--out", "d"]).samples
    3
    """
    p = subparsers.add_parser(
        "sweep", help="robustness study: many model errors, on all cores or a Dask cluster",
        description="Run the robustness study of the spacecraft paper: seeded draws of the "
                    "inertia error, the amplitude of H0 and the initial attitude, each run "
                    "for every case; writes sweep.csv, summary.json and figures.")
    p.add_argument("study", choices=["spacecraft", "cmg"],
                   help="spacecraft (model error of the MEC paper) or cmg (friction and "
                        "inertia of the gyroscope)")
    p.add_argument("--case", action="append", dest="cases", metavar="NAME",
                   help="case to run (repeatable; spacecraft default: without_mec, "
                        "mec_fixed, proposed, safeguarded; cmg default: thesis)")
    p.add_argument("--samples", type=int, default=200, metavar="N",
                   help="number of draws (default 200)")
    p.add_argument("--seed", type=int, default=0, metavar="S", help="seed (default 0)")
    p.add_argument("--horizon", type=float, metavar="SECONDS",
                   help="simulated time per run (default 20000)")
    p.add_argument("--vary", action="append", default=[], metavar="NAME=LOW:HIGH[:N]",
                   help=f"range of a drawn parameter (spacecraft: {', '.join(RANGES)}; cmg: "
                        f"{', '.join(CMG_RANGES)}); with :N it is an N-point grid crossed "
                        "with the draws")
    p.add_argument("--workers", type=int, metavar="N", help="workers (default: all cores)")
    p.add_argument("--executor", choices=["processes", "threads", "serial", "dask"],
                   default="processes", help="where runs go (default: local processes)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="a running Dask scheduler, e.g. tcp://host:8786 (with --executor dask)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder")
    p.add_argument("--resume", action="store_true",
                   help="complete the interrupted sweep in DIR without repeating its runs")


def run_cli(args) -> dict:
    """Run ``controlkit sweep`` from parsed arguments; returns the summary.

    Examples
    --------
    >>> import argparse, tempfile
    >>> parser = argparse.ArgumentParser(prog="controlkit")
    >>> add_cli(parser.add_subparsers(dest="command"))
    >>> args = parser.parse_args(["sweep", "spacecraft", "--samples", "2", "--horizon", "20",
    ...                           "--case", "ideal", "--executor", "serial",
    ...                           "--out", tempfile.mkdtemp()])
    >>> summary = run_cli(args)  # doctest: +ELLIPSIS
    sweep/ideal: runs=2, requirement_met=...
    >>> summary["ideal"]["runs"]
    2
    """
    if args.samples < 1:
        raise ValueError(f"--samples must be >= 1, got {args.samples}")
    if args.horizon is not None and not (np.isfinite(args.horizon) and args.horizon > 0):
        raise ValueError(f"--horizon must be finite and > 0, got {args.horizon}")
    if args.scheduler and args.executor != "dask":
        raise ValueError("--scheduler goes with --executor dask")
    from .scenarios import cmg, spacecraft

    scenario, known = (spacecraft, RANGES) if args.study == "spacecraft" else (cmg, CMG_RANGES)
    unknown = [c for c in args.cases or [] if c not in scenario.CASES]
    if unknown:
        raise ValueError(f"unknown --case {unknown}; known: {list(scenario.CASES)}")
    ranges, grid = {}, {}
    for text in args.vary:
        name, span, n = _vary(text, known)
        if n is None:
            ranges[name] = span
        else:
            grid[name] = np.linspace(span[0], span[1], n).tolist()
    out = check_folder(args.out, "--out")
    study = spacecraft_study if args.study == "spacecraft" else cmg_study
    _, summary = study(samples=args.samples, seed=args.seed, cases=args.cases,
                       horizon=args.horizon, ranges=ranges, grid=grid,
                       executor=args.executor, workers=args.workers,
                       scheduler=args.scheduler, out=out, resume=args.resume)
    for case, s in summary.items():
        low_ci, high_ci = s["success_rate_95ci"]
        print(f"sweep/{case}: runs={s['runs']}, requirement_met={s['requirement_met']}, "
              f"success_rate={s['success_rate']:.3f} (95% CI {low_ci:.3f}-{high_ci:.3f}), "
              f"failed_runs={s['failed_runs']}, median_error={s['median_error']:.4g}")
    return summary


# --- the CMG: friction and inertia of the gyroscope ---------------------------------------

#: Drawn parameters of the CMG study (uniform): a factor on every friction coefficient of
#: the case, and a factor on the true gyroscope's inertias (the controller keeps the model).
CMG_RANGES = {"friction_scale": (0.0, 5.0), "inertia_scale": (0.8, 1.2)}
#: Tracking bound of the CMG study: both gimbal errors after the first second, rad.
CMG_TRACKING_BOUND_RAD = 0.01


def cmg_run(case="thesis", *, friction_scale=1.0, inertia_scale=1.0, horizon=None) -> dict:
    """One run of the CMG study: tracking after 1 s under drawn friction and inertia.

    Returns the metrics of :func:`controlkit.outputs.cmg.metrics` that are numbers, and
    ``tracking_met``: both gimbal errors after 1 s within :data:`CMG_TRACKING_BOUND_RAD`.

    Examples
    --------
    >>> cmg_run(horizon=2.0)["tracking_met"]
    True
    """
    from .outputs.cmg import metrics
    from .scenarios import cmg

    kwargs = {} if horizon is None else {"horizon": horizon}
    m = metrics(cmg.run(case, plant_options={"friction_scale": friction_scale,
                                             "inertia_scale": inertia_scale}, **kwargs))
    out = {k: v for k, v in m.items() if isinstance(v, int | float)}
    out["tracking_met"] = bool(
        max(m["max_abs_q2_error_after_1s_rad"], m["max_abs_q4_error_after_1s_rad"])
        <= CMG_TRACKING_BOUND_RAD)
    return out


def cmg_study(*, samples=200, seed=0, cases=None, horizon=None, ranges=None, grid=None,
              executor=None, workers=None, scheduler=None, out=None, resume=False,
              progress=True):
    """The CMG robustness study: friction and inertia draws; as :func:`spacecraft_study`.

    Success is ``tracking_met`` (both gimbals within :data:`CMG_TRACKING_BOUND_RAD` after
    1 s); the summary bins success by ``friction_scale``.

    Examples
    --------
    >>> table, summary = cmg_study(samples=2, horizon=1.5, executor="serial", progress=False)
    >>> len(table), summary["thesis"]["runs"]
    (2, 2)
    """
    from .scenarios import cmg

    cases = list(cases or cmg.DEFAULT_CASES)
    span = {**CMG_RANGES, **(ranges or {})}
    unknown = sorted(set(span) - set(CMG_RANGES))
    if unknown:
        raise ValueError(f"unknown varied parameters {unknown}; known: {list(CMG_RANGES)}")
    grid = dict(grid or {})
    fixed = {} if horizon is None else {"horizon": float(horizon)}
    table = sweep(cmg_run, grid=grid or None,
                  draws={k: tuple(map(float, v)) for k, v in span.items() if k not in grid},
                  samples=samples, seed=seed, cases=cases, fixed=fixed, executor=executor,
                  workers=workers, scheduler=scheduler,
                  store=None if out is None else Path(out) / "store", resume=resume,
                  warmup=lambda: [cmg.run(c, horizon=2 * cmg.cmg.TS_CMG) for c in cases],
                  progress=progress)
    bins = np.linspace(span["friction_scale"][0], span["friction_scale"][1], 6)
    summary = {}
    for case in cases:
        mine = table[table["case"] == case]
        ok = mine["error"] == ""
        met = int((mine["tracking_met"].fillna(False).astype(bool) & ok).sum())
        low, high = wilson_interval(met, len(mine))
        q2 = mine.loc[ok, "max_abs_q2_error_after_1s_rad"]
        by = []
        for a, b in zip(bins[:-1], bins[1:], strict=True):
            inside = (mine["friction_scale"] >= a) & (mine["friction_scale"] <= b)
            n = int(inside.sum())
            rate = float((mine["tracking_met"].fillna(False).astype(bool) & ok)[inside].mean())
            by.append({"friction_scale_low": float(a), "friction_scale_high": float(b),
                       "runs": n, "success_rate": rate if n else float("nan")})
        summary[case] = {"runs": len(mine), "requirement_met": met,
                         "success_rate": met / len(mine) if len(mine) else float("nan"),
                         "success_rate_95ci": [low, high],
                         "failed_runs": int((~ok).sum()),
                         "median_error": float(q2.median()) if len(q2) else float("nan"),
                         "success_by_friction": by}
    if out is not None:
        _write_cmg(table, summary, Path(out), seed=seed, samples=samples, horizon=horizon)
    return table, summary


def _write_cmg(table, summary, out, **settings):
    from .outputs.export import atomic
    from .outputs.style import legend_outside, log_scale, new_figure, save, slide_style

    out.mkdir(parents=True, exist_ok=True)
    with atomic(out / "sweep.csv") as partial:
        table.to_csv(partial, index=False)
    with atomic(out / "summary.json") as partial:
        partial.write_text(json.dumps({"settings": settings, "tracking_bound_rad":
                                       CMG_TRACKING_BOUND_RAD, "cases": summary}, indent=2))
    with slide_style():
        fig, (ax,) = new_figure()
        for case in summary:
            mine = table[(table["case"] == case) & (table["error"] == "")]
            for column, marker in (("max_abs_q2_error_after_1s_rad", "o"),
                                   ("max_abs_q4_error_after_1s_rad", "s")):
                ax.plot(mine["friction_scale"], mine[column], marker, alpha=0.6,
                        markersize=4, label=f"{case}: {column.split('_')[2]} error")
        ax.axhline(CMG_TRACKING_BOUND_RAD, color="k", linestyle=":", linewidth=1.6,
                   label=f"bound {CMG_TRACKING_BOUND_RAD} rad")
        log_scale(ax)
        ax.set_xlabel("factor on the friction of the case")
        ax.set_ylabel("max |error| after 1 s [rad]")
        ax.set_title("CMG tracking over drawn friction and inertia")
        legend_outside(fig)
        save(fig, out / "cmg_tracking_vs_friction.png")
