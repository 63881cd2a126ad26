"""Control moment gyroscope (ECP Model 750): adaptive backstepping sliding-mode control.

``scenario`` holds the thesis's experiment, ``diagrams`` its closed loop wired with
``control.interconnect``, ``outputs`` the CSV columns, metrics and figures,
``robustness`` the sweep over friction and inertia; :data:`STUDY` is the study's
registry entry.
"""

from __future__ import annotations

from ..registry import Study, scenario_runner
from . import outputs, robustness, scenario

#: ``controlkit reproduce cmg``: the thesis's experiment, CSV, metrics and figures.
STUDY = Study(
    "cmg", tuple(scenario.CASES), scenario.DEFAULT_CASES, scenario_runner(scenario),
    outputs.table, outputs.metrics_from_table, outputs.figures,
    csv_stem=lambda case: "run" if case == "thesis" else case,
    csv_columns=outputs.csv_columns,
    figure_stems=tuple(spec[0] for spec in outputs.FIGURES),
    figure_columns=outputs.figure_columns,
    simulation_cost=0.05,  # 12 000 steps of a 10-state loop vs 3 x 200 000 steps
    Ts=scenario.cmg.TS_CMG, horizon=scenario.HORIZON, signals=32,
    robustness=robustness.ROBUSTNESS,
)
