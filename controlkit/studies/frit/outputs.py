"""The FRIT sensitivity study's table, metrics and figures (``controlkit reproduce frit``)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from ...blocks.spacecraft import POINTING_REQUIREMENT_DEG
from ...outputs.export import atomic, write_json
from . import scenario

#: Columns of ``sensitivity.csv``, in order: the required ones, then when a run diverged.
COLUMNS = ("tuner", "filter", "start", "freeze", "units", "horizon_s",
           "max_pointing_error_last_half_deg", "final_pointing_error_deg", "max_abs_K",
           "peak_abs_u_after_1000s_rad_s", "diverged", "requirement_met_last_half",
           "diverged_at_s")
#: Colour of each tuner in the figures.
TUNER_COLORS = {"paper": "tab:red", "safeguarded": "tab:blue"}
#: Figure file stems.
FIGURES = ("sensitivity_last_half_error", "sensitivity_K_failing")


def reading_label(reading: dict) -> str:
    """A short label of a reading, e.g. ``"zoh rest row deg"``.

    Examples
    --------
    >>> reading_label(scenario.READINGS[0])
    'zoh rest row deg'
    """
    return " ".join(str(reading[name]) for name in ("filter", "start", "freeze", "units"))


def rows(results: dict[str, list]) -> list[dict]:
    """One ``sensitivity.csv`` row per tuner and reading.

    Parameters
    ----------
    results : dict
        Tuner name to its list of :class:`~controlkit.studies.frit.scenario.ReadingResult`.

    Returns
    -------
    list of dict
        Keys :data:`COLUMNS`.

    Examples
    --------
    >>> r = rows({"paper": [scenario.run_reading("paper", horizon=1.0)]})
    >>> list(r[0]) == list(COLUMNS), r[0]["tuner"]
    (True, 'paper')
    """
    out = []
    for tuner, per_reading in results.items():
        for result in per_reading:
            out.append({"tuner": tuner, **result.reading, **result.metrics})
    return [{name: row[name] for name in COLUMNS} for row in out]


def _atomic_csv(path: Path, table: list[dict]) -> Path:
    with atomic(path) as partial, partial.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=COLUMNS)
        writer.writeheader()
        for row in table:
            writer.writerow({k: (f"{v:.10g}" if isinstance(v, float) else v)
                             for k, v in row.items()})
    return path


def figure(results: dict[str, list], stem: str):
    """One of the study's figures as a slide-sized :class:`matplotlib.figure.Figure`.

    ``"sensitivity_last_half_error"``: the worst pointing error over the last half of
    every reading, one marker per tuner, on a log axis with the 0.05 deg requirement
    (a diverged run is drawn at the top, marked x). ``"sensitivity_K_failing"``: the
    gain ``K`` of the readings where the paper's tuner misses the requirement (a run that
    diverged is drawn up to the last chunk that stayed finite, ending in an x).

    Examples
    --------
    >>> fig = figure({"paper": scenario.run("paper", horizon=1.0)},
    ...              "sensitivity_last_half_error")
    >>> fig.axes[0].get_yscale()
    'log'
    """
    from ...outputs.style import legend_outside, log_scale, new_figure, slide_style

    if stem not in FIGURES:
        raise ValueError(f"stem must be one of {list(FIGURES)}, got {stem!r}")
    labels = [reading_label(r) for r in scenario.READINGS]
    with slide_style():
        if stem == "sensitivity_last_half_error":
            fig, (ax,) = new_figure(size=(10.0, 5.625))
            finite = [r.metrics["max_pointing_error_last_half_deg"] for rs in results.values()
                      for r in rs if not r.metrics["diverged"]]
            top = 10 ** math.ceil(math.log10(max(finite + [1.0]))) * 3
            offsets = np.linspace(-0.15, 0.15, max(1, len(results)))
            for offset, (tuner, per_reading) in zip(offsets, results.items(), strict=True):
                x = np.arange(len(per_reading)) + offset
                y = np.array([r.metrics["max_pointing_error_last_half_deg"]
                              for r in per_reading])
                gone = np.array([r.metrics["diverged"] for r in per_reading])
                color = TUNER_COLORS.get(tuner, "k")
                ax.plot(x[~gone], y[~gone], "o", color=color, markersize=8,
                        label=f"{tuner} tuner")
                if gone.any():
                    ax.plot(x[gone], np.full(gone.sum(), top), "x", color=color,
                            markersize=10, markeredgewidth=2.5,
                            label=f"{tuner} tuner: diverged")
            ax.axhline(POINTING_REQUIREMENT_DEG, color="k", linestyle=":", linewidth=1.6,
                       label=f"requirement {POINTING_REQUIREMENT_DEG} deg")
            log_scale(ax)
            ax.set_ylim(1e-4, top * 2)
            ax.set_xticks(np.arange(len(labels)), labels, rotation=60, ha="right",
                          fontsize=10.5)
            ax.set_xlabel("reading: filter, start, freeze, units")
            ax.set_ylabel("worst error, last half [deg]")
            ax.set_title("Pointing error under each reading of the FRIT tuner")
            legend_outside(fig, ncols=4)
            return fig
        failing = [r for r in results.get("paper", [])
                   if not r.metrics["requirement_met_last_half"]]
        fig, (ax,) = new_figure(size=(10.0, 5.625))  # room for labels that say "diverged"
        styles = ("-", "--", "-.", ":")
        colors = ("tab:red", "tab:orange", "tab:purple", "tab:brown", "tab:olive", "tab:cyan",
                  "tab:pink", "tab:gray")
        for color, r in zip(colors, failing, strict=False):
            label = reading_label(r.reading)
            if r.metrics["diverged"]:
                label += f": diverged, {r.metrics['diverged_at_s']:.0f} s"
            if r.K.size == 0:  # diverged before any sample was kept: the legend says when
                ax.plot([], [], "x", color=color, markeredgewidth=2.5, label=label)
                continue
            norm = np.abs(r.K).max(axis=0)
            ax.plot(r.time, norm, color=color, linestyle=styles[0], label=label)
            if r.metrics["diverged"]:  # the trace ends where the run was last finite
                ax.plot(r.time[-1], norm[-1], "x", color=color, markersize=11,
                        markeredgewidth=2.5)
        if not failing:
            ax.text(0.5, 0.5, "the paper's tuner meets the requirement in every reading",
                    transform=ax.transAxes, ha="center", va="center")
        log_scale(ax)
        ax.set_ylim(bottom=1e-3)  # K starts at 0: the first samples would stretch the axis
        ax.set_xlabel("time [s]")
        ax.set_ylabel("max |K_ij| [1/s]")
        ax.set_title("Gain of the paper's tuner where it misses the requirement")
        if ax.get_legend_handles_labels()[0]:
            legend_outside(fig, ncols=2)
        return fig


def write(results: dict[str, list], outdir) -> tuple[dict, list[Path]]:
    """Write ``sensitivity.csv``, ``metrics.json`` and the figures of the study.

    Parameters
    ----------
    results : dict
        Tuner name to its list of :class:`~controlkit.studies.frit.scenario.ReadingResult`.
    outdir : str or pathlib.Path
        The study's folder (``out/frit``).

    Returns
    -------
    metrics : dict
        Per tuner: how many readings meet the requirement, diverge, and each row.
    paths : list of pathlib.Path
        Files written.

    Examples
    --------
    >>> import tempfile
    >>> m, paths = write({"paper": scenario.run("paper", horizon=1.0)}, tempfile.mkdtemp())
    >>> m["paper"]["readings"], sorted(p.name for p in paths)[:2]
    (16, ['metrics.json', 'sensitivity.csv'])
    """
    from ...outputs.style import save

    outdir = Path(outdir)
    table = rows(results)
    paths = [_atomic_csv(outdir / "sensitivity.csv", table)]
    metrics = {}
    for tuner in results:
        mine = [row for row in table if row["tuner"] == tuner]
        metrics[tuner] = {
            "readings": len(mine),
            "requirement_met": sum(row["requirement_met_last_half"] for row in mine),
            "diverged": sum(row["diverged"] for row in mine),
            "rows": mine,
        }
    paths.append(write_json(outdir / "metrics.json", metrics))
    for stem in FIGURES:
        paths += save(figure(results, stem), outdir / f"{stem}.png")
    return metrics, paths
