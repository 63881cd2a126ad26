"""Two-wheel spacecraft (Endo, Sekiguchi, Nonaka 2017): input-output linearization with MEC.

``scenario`` holds the published parameter sets and cases, ``diagrams`` the paper's
Fig. 2-4 wired with ``control.interconnect``, ``outputs`` the CSV columns, metrics and
Fig. 5-10, ``robustness`` the sweep over model errors, ``frequency`` the loops linearized
at the target with and without MEC (``frequency_outputs`` their files); :data:`STUDY` is
the study's registry entry.
"""

from __future__ import annotations

from ..registry import Study, scenario_runner
from . import frequency_outputs, outputs, robustness, scenario


def _streaming_metrics(case, horizon):
    return outputs.StreamingMetrics(scenario.build_loop(case).output_labels, horizon)


#: ``controlkit reproduce spacecraft``: the paper's cases, CSV, metrics and Fig. 5-10.
STUDY = Study(
    "spacecraft", tuple(scenario.CASES), scenario.DEFAULT_CASES, scenario_runner(scenario),
    outputs.table, outputs.metrics_from_table, outputs.figures, default_stride=10,
    figure_stems=tuple(spec[0] for spec in outputs.FIGURES),
    draw_first=("fig07_pointing_error",),  # a log axis: 1.5-2x the others
    figure_columns=outputs.figure_columns, stems_for=outputs.figure_stems,
    Ts=scenario.sc.TS_PAPER, horizon=scenario.HORIZON, signals=60,
    streaming=_streaming_metrics, robustness=robustness.ROBUSTNESS,
    horizon_note=scenario.horizon_note, extra=frequency_outputs.write,
)
