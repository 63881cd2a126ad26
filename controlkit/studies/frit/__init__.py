"""How much the spacecraft paper's FRIT claim depends on what the paper leaves unstated.

``scenario`` runs the proposed loop under the 16 readings of the tuner's filter,
start, freeze and units, for the paper's tuner and the safeguarded one; ``outputs``
writes the table and the two sensitivity figures; :data:`STUDY` is the study's registry
entry (asked for by name: ``controlkit reproduce frit``).
"""

from __future__ import annotations

from ..registry import Study, scenario_runner
from . import outputs, scenario

#: ``controlkit reproduce frit``: the sensitivity table and figures.
STUDY = Study(
    "frit", scenario.CASES, scenario.DEFAULT_CASES, scenario_runner(scenario),
    None, None, None, write=outputs.write, in_all=False, signals=0,
    simulation_cost=16.0,  # 16 readings of the proposed loop per tuner
)
