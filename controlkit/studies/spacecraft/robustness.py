"""How robust is MEC? The spacecraft paper's claim over many model errors.

The paper shows one model error (Table 2). This study draws many: each
diagonal entry of ``Delta J`` scaled by a factor from 0 to 3, the amplitude of
``H0(t)`` from 0.5 to 5 times the paper's, and the initial attitude (a random
axis, 10 to 60 deg); every draw runs each case (the same draw for every case,
so the cases are compared on equal terms), and the study reports how often
the 0.05 deg requirement holds over the last half of the run, with a Wilson
95 % interval, the distribution of the error per case, and the success rate
against the size of the inertia error. :data:`ROBUSTNESS` is the study's entry;
:func:`controlkit.studies.robustness.study` runs it.
"""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np

from ...blocks.sampling import time_grid
from ...blocks.spacecraft import (
    POINTING_REQUIREMENT_DEG,
    TS_PAPER,
    pointing_error_deg,
    quaternion_from_axis_angle,
)
from .._sweep_results import (
    requirement_met,
    success_by_bin,
    warming,
    write_table_and_summary,
)
from ..registry import Robustness
from . import scenario

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
    return BASE_CASES + (("safeguarded",) if "safeguarded" in scenario.CASES else ())


def _normal(rng):
    return float(rng.normal())


def run(case, *, inertia_error_x=1.0, inertia_error_y=1.0, inertia_error_z=1.0,
                   momentum_scale=1.0, axis_x=1.0, axis_y=2.0, axis_z=3.0, angle_deg=30.0,
                   horizon=None, keep_every=0) -> dict:
    """One run of the study: the metrics of a case under one model error and attitude.

    Parameters
    ----------
    case : str
        A case of :data:`controlkit.studies.spacecraft.scenario.CASES`.
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
    >>> m = run("without_mec", horizon=100.0)
    >>> m["requirement_met_last_half"]
    False
    """

    horizon = scenario.HORIZON if horizon is None else horizon
    grid = time_grid(horizon, TS_PAPER, lazy=True)
    metrics = _Metrics(case, last_half_from=grid[-1] / 2)
    q0 = quaternion_from_axis_angle([axis_x, axis_y, axis_z], angle_deg)
    # streamed: the metrics see every step, chunk by chunk, and the response keeps only the
    # trajectory's samples (a 20 000 s run would otherwise hold and copy about 80 MB)
    resp = scenario.run(case, q_initial=q0, plant_options={
        "inertia_error_scale": [inertia_error_x, inertia_error_y, inertia_error_z],
        "momentum_scale": momentum_scale}, horizon=horizon,
        record_every=keep_every or len(grid), on_chunk=metrics.add)
    result = metrics.result()
    if keep_every:
        kept = len(range(0, len(grid), keep_every))  # the forced last sample is left out
        result["trajectory"] = {"time": resp.time[:kept],
                                "error_deg": pointing_error_deg(resp.outputs[metrics.q, :kept])}
    return result


@functools.cache
def _rows(case) -> tuple[list[int], list[int], list[int]]:
    """Rows of ``q``, ``u`` and ``K`` among the outputs of ``case``'s loop (no ``K`` where it
    has no compensator); the loop's labels do not depend on its parameters."""
    labels = list(scenario.build_loop(case).output_labels)
    return tuple([labels.index(f"{name}[{i}]") for i in range(n) if f"{name}[{i}]" in labels]
                 for name, n in (("q", 4), ("u", 2), ("K", 4)))


class _Metrics:
    """A run's metrics from its outputs, given chunk by chunk (``on_chunk``): the worst
    pointing error from ``last_half_from`` on, the final one, and the peaks of ``|u|`` and
    ``|K|``, each a maximum over every step."""

    def __init__(self, case, last_half_from):
        self.q, self.u, self.K = _rows(case)
        self.last_half_from = last_half_from
        self.worst = self.final = None
        self.peak_u = self.peak_K = 0.0

    def add(self, time, outputs, states):
        error = pointing_error_deg(outputs[self.q])
        late = error[time >= self.last_half_from]
        if late.size:  # np.maximum, as one max over the run, keeps a NaN
            self.worst = late.max() if self.worst is None else np.maximum(self.worst,
                                                                          late.max())
        self.final = error[-1]
        self.peak_u = np.maximum(self.peak_u, np.abs(outputs[self.u]).max())
        if self.K:
            self.peak_K = np.maximum(self.peak_K, np.abs(outputs[self.K]).max())

    def result(self) -> dict:
        worst = float(self.worst)
        return {"max_pointing_error_last_half_deg": worst,
                "final_pointing_error_deg": float(self.final),
                "requirement_met_last_half": bool(worst <= POINTING_REQUIREMENT_DEG),
                "peak_abs_u_rad_s": float(self.peak_u), "max_abs_K": float(self.peak_K)}


#: Compiles each case's loop before the workers start (``warm(cases)``).
warm = warming(scenario.run, TS_PAPER)


def binned(rows, span) -> tuple[str, list[dict]]:
    """Success rate in six bins of the mean inertia-error factor, over ``span``'s range.

    Examples
    --------
    >>> import pandas as pd
    >>> rows = pd.DataFrame({"inertia_error_x": [0.2, 2.8], "inertia_error_y": [0.2, 2.8],
    ...                      "inertia_error_z": [0.2, 2.8], "error": ["", ""],
    ...                      "requirement_met_last_half": [True, False]})
    >>> key, bins = binned(rows, RANGES)
    >>> key, [b["success_rate"] for b in bins][::5]
    ('success_by_inertia_error', [1.0, 0.0])
    """
    low = np.mean([span[f"inertia_error_{a}"][0] for a in "xyz"])
    high = np.mean([span[f"inertia_error_{a}"][1] for a in "xyz"])
    edges = np.linspace(low, high, 7)
    factor = rows[["inertia_error_x", "inertia_error_y", "inertia_error_z"]].mean(axis=1)
    met = requirement_met(rows, "requirement_met_last_half")
    return "success_by_inertia_error", success_by_bin(factor, met, edges, "mean_factor")


def write(table, summary, out, **settings) -> list[Path]:
    """The study's files in ``out``: those of every sweep (``sweep.csv``, ``summary.json``)
    and the two figures of :func:`figures`.

    Examples
    --------
    >>> import tempfile
    >>> from controlkit.studies import robustness
    >>> t, s = robustness.study("spacecraft", samples=2, cases=["without_mec"], horizon=20.0,
    ...                           executor="serial", progress=False)
    >>> sorted(p.name for p in write(t, s, tempfile.mkdtemp()))[-2:]
    ['summary.json', 'sweep.csv']
    """
    from ...outputs.style import save

    paths = write_table_and_summary(table, {"settings": settings, "requirement_deg":
                                            POINTING_REQUIREMENT_DEG, "cases": summary}, out)
    for stem, fig in figures(table, summary).items():
        paths += save(fig, Path(out) / f"{stem}.png")
    return paths


#: Colour of each case in the study's figures (the paper's where it has one).
CASE_COLORS = {"without_mec": "tab:green", "mec_fixed": "tab:purple", "proposed": "tab:red",
               "safeguarded": "tab:blue"}


def figures(table, summary) -> dict:
    """The study's two figures, as slide-sized :class:`matplotlib.figure.Figure` objects.

    ``robustness_errors``: the worst last-half error of every run, per case (box plot
    and the runs as dots) on a log axis with the 0.05 deg requirement.
    ``robustness_success_vs_inertia``: success rate against the mean inertia-error
    factor (1 = Table 2), per case, as bars side by side in each bin of the factor.

    Examples
    --------
    >>> from controlkit.studies import robustness
    >>> t, s = robustness.study("spacecraft", samples=3, cases=["without_mec"], horizon=20.0,
    ...                           executor="serial", progress=False)
    >>> sorted(figures(t, s))
    ['robustness_errors', 'robustness_success_vs_inertia']
    """
    from ...outputs.style import legend_outside, log_scale, new_figure, slide_style

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
        _success_bars(ax, summary, cases)
        ax.axvline(1.0, color="0.3", linestyle="--", linewidth=1.4, label="Table 2's error",
                   zorder=4)
        ax.set_ylim(-2.5, 109)  # a bar at 0 % stays a stroke above the axis
        ax.set_xlabel("mean factor on Table 2's inertia error (bins)")
        ax.set_ylabel("requirement met [% of runs]")
        ax.set_title("Success rate against the size of the inertia error")
        legend_outside(fig)
        out["robustness_success_vs_inertia"] = fig
    return out


#: Hatching of each case's bars, in the order of the cases: told apart in grey too.
HATCHES = ("", "//", "..", "xx", "\\\\")


def _success_bars(ax, summary, cases):
    """Each case's success rate per bin of the inertia error, as bars side by side.

    Several cases often meet the requirement in every run of a bin: as curves their
    100 % points lie on one another and only the last drawn shows. Side by side in their
    bin, each case has its own bar (its colour and hatching, named in the legend); a case
    at 0 % keeps a visible stroke at 0, and a bin without runs of a case has no bar.
    """
    width = 1.0 / (len(cases) + 1)  # of a bin, with a gap of one bar between bins
    for i, case in enumerate(cases):
        bins = summary[case]["success_by_inertia_error"]
        low = np.array([b["mean_factor_low"] for b in bins])
        span = np.array([b["mean_factor_high"] for b in bins]) - low
        rates = np.array([100 * b["success_rate"] for b in bins])
        drawn = np.isfinite(rates)
        colour = CASE_COLORS.get(case, "k")
        ax.bar((low + span * width * (i + 0.5))[drawn], rates[drawn], span[drawn] * width,
               align="edge", color=colour, alpha=0.85, edgecolor=colour, linewidth=1.5,
               hatch=HATCHES[i % len(HATCHES)], label=case, zorder=3)
    ax.grid(axis="x", visible=False)


#: The study's registry entry (``controlkit sweep spacecraft``).
ROBUSTNESS = Robustness(
    run=run, ranges=RANGES, default_cases=default_cases, cases=lambda: tuple(scenario.CASES),
    success="requirement_met_last_half", error="max_pointing_error_last_half_deg",
    binned=binned, warmup=warm, write=write,
    extra_draws={"axis_x": _normal, "axis_y": _normal, "axis_z": _normal})
