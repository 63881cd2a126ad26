"""The spacecraft study's frequency-domain files: the bounds (``mec_frequency.json``) and
the figures of the loops with and without MEC, written by ``controlkit reproduce``."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...analysis.plots import compare_frequency_responses
from ...outputs.common import select_stems
from . import frequency

#: File of the bounds and margins.
REPORT = "mec_frequency.json"
# (file stem, title)
FIGURES = (
    ("freq01_loop_gain", "Loop gain at the plant input (wheel 1), at the target"),
    ("freq02_sensitivity", "Input sensitivity S at the target, both wheels"),
    ("freq03_tolerance", "Inertia errors the loop tolerates (eigenvalues at the target)"),
)
#: Further figures :func:`figure` draws on request (not written by ``reproduce``).
MORE_FIGURES = (
    ("freq_complementary", "Complementary sensitivity T at the target, both wheels"),
)
#: The directions of ``freq03_tolerance``, bottom to top within a loop, and their colours.
BAR_DIRECTIONS = {"x": ("x axis only", "#0072B2"), "y": ("y axis only", "#E69F00"),
                  "delta_J": ("all axes, along ΔJ", "#009E73")}


def frit_gain(metrics) -> np.ndarray | None:
    """The gain the ``proposed`` case ended with (its ``final_K``), or None without it.

    Examples
    --------
    >>> frit_gain({"proposed": {"final_K": [1.0, 0.0, 0.0, 2.0]}}).tolist()
    [1.0, 0.0, 0.0, 2.0]
    >>> frit_gain({"ideal": {}}) is None
    True
    """
    entry = metrics.get("proposed") or {}
    K = entry.get("final_K")
    return None if K is None or "error" in entry else np.asarray(K, dtype=float)


def setting(options) -> frequency.Setting:
    """The loops' ``F``, ``Ts`` and fixed gain ``K`` from a run's options (the paper's when
    not set).

    Examples
    --------
    >>> setting({"F": 0.002}).F, setting({}).Ts
    (0.002, 0.1)
    """
    paper = frequency.PAPER
    return frequency.Setting(F=options.get("F", paper.F), Ts=options.get("Ts", paper.Ts),
                             K_fixed=options.get("K", paper.K_fixed))


def analyse(metrics, engine="fast", options=None):
    """The report and the figures' tables for a run's metrics, or ``(None, None)``.

    Written when the run has the ``proposed`` case: its final ``K`` is the gain FRIT
    converged to, compared with the loops without MEC and with the fixed gain. The loops
    take the run's ``F``, ``Ts`` and ``K`` options.

    Returns
    -------
    tuple
        ``(report, tables)``: :func:`controlkit.studies.spacecraft.frequency.report`'s
        dict (with the gain's source) and :func:`figures`'s tables.

    Examples
    --------
    >>> analyse({"ideal": {}})  # no proposed case: nothing to compare
    (None, None)
    """
    K_frit = frit_gain(metrics)
    if K_frit is None:
        return None, None
    design = setting(options or {})
    result = frequency.report(K_frit, setting=design, engine=engine)
    result["K_frit_source"] = (f"final K of the proposed case of this run "
                               f"({metrics['proposed'].get('horizon_s', 0):g} s)")
    columns = {"K_frit": K_frit.ravel(), "F": np.asarray(design.F, dtype=float).ravel(),
               "Ts": np.array([design.Ts]), "K_fixed": np.array([design.K_fixed])}
    for direction in BAR_DIRECTIONS:
        for side in ("low", "high"):
            ratios = [entry["tolerated"][direction][f"{side}_ratio"]
                      for entry in result["loops"].values()]
            columns[f"{direction}_{side}"] = np.array([np.nan if r is None else r
                                                       for r in ratios])
    for key in ("gain_margin", "phase_margin_deg"):
        values = [entry["margins_at_u"]["u[0]"][key] for entry in result["loops"].values()]
        columns[f"{key.removesuffix('_deg')}_u0"] = np.array(
            [np.nan if v is None else v for v in values])
    return result, {"frequency": columns}


def write(metrics, folder, engine="fast", options=None):
    """Write :data:`REPORT` into ``folder`` (see :func:`analyse`); return its path and the
    figures to draw.

    Returns
    -------
    tuple
        ``([path of the report], (figures, tables, stems))``: :func:`figures` and its
        arguments, for the figure workers; ``([], None)`` without the proposed case.

    Examples
    --------
    >>> import tempfile
    >>> write({"ideal": {}}, tempfile.mkdtemp())
    ([], None)
    """
    from ...outputs.export import write_json

    result, tables = analyse(metrics, engine, options)
    if result is None:
        return [], None
    path = Path(folder) / REPORT
    write_json(path, result)
    return [path], (figures, tables, tuple(spec[0] for spec in FIGURES))


def figures(tables, outdir, *, stems=None) -> list[Path]:
    """Draw the figures of :data:`FIGURES` (PNG and SVG) from :func:`analyse`'s tables.

    Examples
    --------
    >>> import tempfile
    >>> tables = {"frequency": {"K_frit": np.zeros(0)}}
    >>> [p.name for p in figures(tables, tempfile.mkdtemp(), stems=["freq02_sensitivity"])]
    ['freq02_sensitivity.png', 'freq02_sensitivity.svg']
    """
    from ...outputs.style import save

    written = []
    for stem in select_stems(FIGURES, stems):
        written += save(figure(tables, stem), Path(outdir) / f"{stem}.png")
    return written


def figure(tables, stem):
    """One figure of :data:`FIGURES` as a :class:`matplotlib.figure.Figure`.

    Examples
    --------
    >>> fig = figure({"frequency": {"K_frit": np.zeros(0)}}, "freq02_sensitivity")
    >>> fig.axes[0].get_ylabel()
    'largest singular value of S [dB]'
    """
    columns = tables["frequency"]
    K_frit = np.asarray(columns["K_frit"])
    paper = frequency.PAPER
    F = np.asarray(columns.get("F", paper.F), dtype=float).ravel()
    design = frequency.Setting(F=float(F[0]) if F.size == 1 else tuple(F),
                               Ts=float(np.asarray(columns.get("Ts", paper.Ts)).ravel()[0]),
                               K_fixed=float(np.asarray(columns.get("K_fixed",
                                                                    paper.K_fixed)).ravel()[0]))
    gains = frequency.loops(K_frit.reshape(2, 2) if K_frit.size else None, setting=design)
    known = dict(FIGURES + MORE_FIGURES)
    if stem not in known:
        raise ValueError(f"stem must be one of {list(known)}, got {stem!r}")
    title = known[stem]
    if stem == "freq03_tolerance":
        return _tolerance(gains, columns, title)
    omega = design.omega
    if stem == "freq01_loop_gain":
        systems = {}
        for i, (label, K) in enumerate(gains.items()):
            L = frequency.transfers(K, at="u[0]", setting=design).L
            m = {"gain_margin": columns["gain_margin_u0"][i],
                 "phase_margin_deg": columns["phase_margin_u0"][i]} \
                if "gain_margin_u0" in columns else frequency.margins(L)
            systems[f"{label}: GM {m['gain_margin']:.3g}, PM "
                     f"{m['phase_margin_deg']:.0f} deg"] = L
        return compare_frequency_responses(systems, omega, title=title,
                                           lines=[(1.0, "|L| = 1 (0 dB)")])
    which = "S" if stem == "freq02_sensitivity" else "T"
    systems = {label: getattr(frequency.transfers(K, setting=design), which)
               for label, K in gains.items()}
    bands = []
    if which == "S":
        for label, K in gains.items():
            if K is not None and np.ndim(K) == 0:
                bands = [(low, high, f"{label}: S below the loop without MEC")
                         for low, high in frequency.sensitivity_band(K, setting=design)]
    return compare_frequency_responses(systems, omega, title=title, phase=False,
                                       bands=bands[:1],
                                       ylabel=f"largest singular value of {which} [dB]")


def _tolerance(gains, columns, title):
    """Horizontal bars: the range of ``J_t / J_m`` each loop tolerates, per direction."""
    from ...outputs.style import legend_outside, log_scale, new_figure, slide_style

    floor = frequency._ratio(frequency.physical_limit("delta_J"), "delta_J")
    cap = frequency._ratio(frequency.SCALE_CAP, "delta_J")
    table2 = frequency._ratio(1.0, "delta_J")
    with slide_style():
        fig, (ax,) = new_figure()
        ticks = []
        for i, label in enumerate(gains):
            ticks.append((i, label))
            for j, (direction, (name, color)) in enumerate(BAR_DIRECTIONS.items()):
                y = i + (j - 1) * 0.25
                low = columns[f"{direction}_low"][i] if f"{direction}_low" in columns else np.nan
                high = columns[f"{direction}_high"][i] if f"{direction}_high" in columns \
                    else np.nan
                left = low if np.isfinite(low) else floor
                right = high if np.isfinite(high) else cap
                ax.barh(y, right - left, left=left, height=0.22, color=color,
                        label=name if i == 0 else None)
                for end, bound in ((left, low), (right, high)):
                    if np.isfinite(bound):  # a stability bound: its value, at the bar's end
                        ax.annotate(f"{bound:.3g}", (end, y), xytext=(3 if end == right
                                                                      else -3, 0),
                                    textcoords="offset points", va="center", fontsize=10,
                                    ha="left" if end == right else "right")
        ax.axvspan(floor / 3, floor, color="0.85", zorder=0,
                   label="J_b ≤ 0: no such body")
        ax.axvline(table2, color="k", linestyle="--", linewidth=1.2, label="Table 2's error")
        log_scale(ax, "x")
        ax.set_xlim(floor / 3, cap * 3)
        ax.set_yticks([t for t, _ in ticks], [name for _, name in ticks])
        ax.invert_yaxis()
        ax.grid(axis="y", visible=False)
        ax.axvline(cap, color="0.4", linestyle=":", linewidth=1.4,
                   label=f"search ends ({cap:.0f})")
        ax.set_xlabel("true / modelled inertia of the axis, J_t / J_m [-]")
        ax.set_title(title)
        legend_outside(fig, ncols=3)
    return fig
