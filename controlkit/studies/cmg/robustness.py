"""How robust is the CMG controller? Tracking over drawn friction and inertia.

Each run draws a factor on every friction coefficient of the case and a factor on
the true gyroscope's inertias (the controller keeps its model), and checks that both
gimbals track their commands within :data:`TRACKING_BOUND_RAD` after the first
second. :data:`ROBUSTNESS` is the study's entry;
:func:`controlkit.studies.robustness.study` runs it.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ...outputs.export import atomic
from ...outputs.style import legend_outside, log_scale, new_figure, save, slide_style
from ..registry import Robustness
from . import scenario
from .outputs import metrics

#: Drawn parameters of the CMG study (uniform): a factor on every friction coefficient of
#: the case, and a factor on the true gyroscope's inertias (the controller keeps the model).
RANGES = {"friction_scale": (0.0, 5.0), "inertia_scale": (0.8, 1.2)}
#: Tracking bound of the CMG study: both gimbal errors after the first second, rad.
TRACKING_BOUND_RAD = 0.01


def run(case="thesis", *, friction_scale=1.0, inertia_scale=1.0, horizon=None) -> dict:
    """One run of the CMG study: tracking after 1 s under drawn friction and inertia.

    Returns the metrics of :func:`controlkit.studies.cmg.outputs.metrics` that are numbers, and
    ``tracking_met``: both gimbal errors after 1 s within :data:`TRACKING_BOUND_RAD`.

    Examples
    --------
    >>> run(horizon=2.0)["tracking_met"]
    True
    """
    kwargs = {} if horizon is None else {"horizon": horizon}
    m = metrics(scenario.run(case, plant_options={"friction_scale": friction_scale,
                                             "inertia_scale": inertia_scale}, **kwargs))
    out = {k: v for k, v in m.items() if isinstance(v, int | float)}
    out["tracking_met"] = bool(
        max(m["max_abs_q2_error_after_1s_rad"], m["max_abs_q4_error_after_1s_rad"])
        <= TRACKING_BOUND_RAD)
    return out


def warm(cases) -> None:
    """Compile each case's simulation loop once (numba's disk cache), before workers start.

    Examples
    --------
    >>> warm(["thesis"])
    """
    for case in cases:
        scenario.run(case, horizon=2 * scenario.cmg.TS_CMG)


def binned(rows, span) -> tuple[str, list[dict]]:
    """Success rate in five bins of ``friction_scale`` over ``span``'s range.

    Examples
    --------
    >>> import pandas as pd
    >>> rows = pd.DataFrame({"friction_scale": [0.5, 4.5], "error": ["", ""],
    ...                      "tracking_met": [True, False]})
    >>> key, bins = binned(rows, RANGES)
    >>> key, [b["success_rate"] for b in bins][::4]
    ('success_by_friction', [1.0, 0.0])
    """
    edges = np.linspace(span["friction_scale"][0], span["friction_scale"][1], 6)
    met = rows["tracking_met"].fillna(False).astype(bool) & (rows["error"] == "")
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        inside = (rows["friction_scale"] >= a) & (rows["friction_scale"] <= b)
        n = int(inside.sum())
        rate = float(met[inside].mean())
        out.append({"friction_scale_low": float(a), "friction_scale_high": float(b),
                    "runs": n, "success_rate": rate if n else float("nan")})
    return "success_by_friction", out


def write(table, summary, out, **settings) -> list[Path]:
    """Write ``sweep.csv``, ``summary.json`` and the tracking figure into ``out``.

    Each file is written under a temporary name and renamed when complete.

    Examples
    --------
    >>> import tempfile
    >>> from controlkit.studies import robustness
    >>> t, s = robustness.study("cmg", samples=2, horizon=1.5, executor="serial",
    ...                         progress=False)
    >>> [p.name for p in write(t, s, tempfile.mkdtemp())]
    ['sweep.csv', 'summary.json', 'cmg_tracking_vs_friction.png', 'cmg_tracking_vs_friction.svg']
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with atomic(out / "sweep.csv") as partial:
        table.to_csv(partial, index=False)
    with atomic(out / "summary.json") as partial:
        partial.write_text(json.dumps({"settings": settings, "tracking_bound_rad":
                                       TRACKING_BOUND_RAD, "cases": summary}, indent=2) + "\n")
    paths = [out / "sweep.csv", out / "summary.json"]
    with slide_style():
        fig, (ax,) = new_figure()
        for case in summary:
            mine = table[(table["case"] == case) & (table["error"] == "")]
            for column, marker in (("max_abs_q2_error_after_1s_rad", "o"),
                                   ("max_abs_q4_error_after_1s_rad", "s")):
                ax.plot(mine["friction_scale"], mine[column], marker, alpha=0.6,
                        markersize=4, label=f"{case}: {column.split('_')[2]} error")
        ax.axhline(TRACKING_BOUND_RAD, color="k", linestyle=":", linewidth=1.6,
                   label=f"bound {TRACKING_BOUND_RAD} rad")
        log_scale(ax)
        ax.set_xlabel("factor on the friction of the case")
        ax.set_ylabel("max |error| after 1 s [rad]")
        ax.set_title("CMG tracking over drawn friction and inertia")
        legend_outside(fig)
        paths += save(fig, out / "cmg_tracking_vs_friction.png")
    return paths


#: The study's registry entry (``controlkit sweep cmg``).
ROBUSTNESS = Robustness(
    run=run, ranges=RANGES, default_cases=lambda: tuple(scenario.DEFAULT_CASES),
    cases=lambda: tuple(scenario.CASES), success="tracking_met",
    error="max_abs_q2_error_after_1s_rad", binned=binned, warmup=warm, write=write)
