"""How robust is the CMG controller? Tracking over drawn friction and inertia.

Each run draws a factor on every friction coefficient of the case and a factor on
the true gyroscope's inertias (the controller keeps its model), and checks that both
gimbals track their commands within :data:`TRACKING_BOUND_RAD` after the first
second. :data:`ROBUSTNESS` is the study's entry;
:func:`controlkit.studies.robustness.study` runs it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...outputs.style import legend_outside, log_scale, new_figure, save, slide_style
from .._sweep_results import (
    requirement_met,
    success_by_bin,
    warming,
    write_table_and_summary,
)
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


#: Compiles each case's loop before the workers start (``warm(cases)``).
warm = warming(scenario.run, scenario.cmg.TS_CMG)


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
    met = requirement_met(rows, "tracking_met")
    return "success_by_friction", success_by_bin(rows["friction_scale"], met, edges,
                                                 "friction_scale", closed=True)


def write(table, summary, out, **settings) -> list[Path]:
    """The study's files in ``out``: those of every sweep (``sweep.csv``, ``summary.json``)
    and the tracking errors over the friction factor, against the bound.

    Examples
    --------
    >>> import tempfile
    >>> from controlkit.studies import robustness
    >>> t, s = robustness.study("cmg", samples=2, horizon=1.5, executor="serial",
    ...                         progress=False)
    >>> [p.name for p in write(t, s, tempfile.mkdtemp())]
    ['sweep.csv', 'summary.json', 'cmg_tracking_vs_friction.png', 'cmg_tracking_vs_friction.svg']
    """
    paths = write_table_and_summary(table, {"settings": settings, "tracking_bound_rad":
                                            TRACKING_BOUND_RAD, "cases": summary}, out)
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
        paths += save(fig, Path(out) / "cmg_tracking_vs_friction.png")
    return paths


#: The study's registry entry (``controlkit sweep cmg``).
ROBUSTNESS = Robustness(
    run=run, ranges=RANGES, default_cases=lambda: tuple(scenario.DEFAULT_CASES),
    cases=lambda: tuple(scenario.CASES), success="tracking_met",
    error="max_abs_q2_error_after_1s_rad", binned=binned, warmup=warm, write=write)
