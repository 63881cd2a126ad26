"""Tables, metrics and the thesis-style Fig. 3-6 of the CMG study."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...blocks.cmg import T1_MAX, T2_MAX
from ...outputs.common import figure_spec, select_stems, signal

#: CSV columns of ``controlkit reproduce cmg``, in order.
COLUMNS = ("time", "q1", "q2", "q4", "w1", "w2", "w4", "q2d", "q4d", "T1", "T2",
           "a1", "a2", "a3", "a4")


def table(resp) -> dict[str, np.ndarray]:
    """CSV columns (:data:`COLUMNS`); ``T1, T2`` are the torques applied after saturation.

    Examples
    --------
    >>> from controlkit.studies.cmg.scenario import run
    >>> list(table(run(horizon=0.005)))[:4]
    ['time', 'q1', 'q2', 'q4']
    """
    cols = {"time": resp.time}
    cols.update({name: signal(resp, name) for name in COLUMNS[1:]})
    cols["_T1_cmd"], cols["_T2_cmd"] = signal(resp, "T1_cmd"), signal(resp, "T2_cmd")
    return cols


def csv_columns(cols):
    """The public CSV columns of a :func:`table` (drops the commanded torques).

    Examples
    --------
    >>> list(csv_columns({"time": [0.0], "_T1_cmd": [1.0]}))
    ['time']
    """
    return {k: v for k, v in cols.items() if not k.startswith("_")}


def metrics(resp) -> dict:
    """Tracking after 1 s, torque use and final estimates of one run.

    Examples
    --------
    >>> from controlkit.studies.cmg.scenario import run
    >>> sorted(metrics(run(horizon=0.01)))[:2]
    ['final_estimates', 'final_q2_error_rad']
    """
    return metrics_from_table(table(resp))


def metrics_from_table(c) -> dict:
    """:func:`metrics` from the columns of :func:`table` (computed once by the caller).

    Examples
    --------
    >>> from controlkit.studies.cmg.scenario import run
    >>> metrics_from_table(table(run(horizon=0.01)))["horizon_s"]
    0.01
    """
    after = c["time"] >= min(1.0, c["time"][-1])
    return {
        "horizon_s": float(c["time"][-1]),
        "max_abs_q2_error_after_1s_rad": float(np.abs(c["q2"] - c["q2d"])[after].max()),
        "max_abs_q4_error_after_1s_rad": float(np.abs(c["q4"] - c["q4d"])[after].max()),
        "final_q2_error_rad": float(c["q2"][-1] - c["q2d"][-1]),
        "final_q4_error_rad": float(c["q4"][-1] - c["q4d"][-1]),
        "peak_abs_T1_applied_Nm": float(np.abs(c["T1"]).max()),
        "peak_abs_T2_applied_Nm": float(np.abs(c["T2"]).max()),
        "peak_abs_T1_commanded_Nm": float(np.abs(c["_T1_cmd"]).max()),
        "peak_abs_T2_commanded_Nm": float(np.abs(c["_T2_cmd"]).max()),
        "fraction_T1_saturated": float(np.mean(np.abs(c["_T1_cmd"]) > T1_MAX)),
        "fraction_T2_saturated": float(np.mean(np.abs(c["_T2_cmd"]) > T2_MAX)),
        "final_estimates": [float(c[f"a{i}"][-1]) for i in range(1, 5)],
        "max_abs_estimates": [float(np.abs(c[f"a{i}"]).max()) for i in range(1, 5)],
    }


#: Where the figures come from, in every title: the spacecraft paper numbers its figures
#: too, and results/ holds both studies' "Fig. 5".
SOURCE = "CMG thesis"
FIGURES = (
    ("fig3_q2", f"Fig. 3 of the {SOURCE}: gimbal 2 angle q2", "q2 [rad]", "q2", "q2d", None),
    ("fig4_q4", f"Fig. 4 of the {SOURCE}: gimbal 4 angle q4", "q4 [rad]", "q4", "q4d", None),
    ("fig5_T1", f"Fig. 5 of the {SOURCE}: motor 1 torque T1", "T1 [N m]", "T1", None, T1_MAX),
    ("fig6_T2", f"Fig. 6 of the {SOURCE}: motor 2 torque T2", "T2 [N m]", "T2", None, T2_MAX),
)
_COLORS = {"thesis": "tab:blue", "strong_friction": "tab:orange"}
#: Legend text of each case: these curves are our simulation, not the thesis's measurements.
LABELS = {"thesis": "simulation", "strong_friction": "simulation, strong friction"}
#: Width of the moving window of Fig. 5 (T1 switches every sample), in seconds.
T1_WINDOW_S = 0.05
#: Length of Fig. 5's zoomed window on the raw switching torque, in seconds.
T1_ZOOM_S = 0.03


def _label(name):
    return LABELS.get(name, f"simulation, {name}")


def window_stats(time, values, width):
    """Moving mean, minimum and maximum of ``values`` over consecutive windows.

    Parameters
    ----------
    time, values : array_like
        Equal-length samples.
    width : float
        Window length in the units of ``time`` (> 0).

    Returns
    -------
    centre, mean, low, high : numpy.ndarray
        One entry per window.

    Examples
    --------
    >>> c, m, lo, hi = window_stats([0, 1, 2, 3], [1, -1, 1, -1], 2.0)
    >>> m.tolist(), lo.tolist(), hi.tolist()
    ([0.0, 0.0], [-1.0, -1.0], [1.0, 1.0])
    """
    time, values = np.asarray(time, dtype=float), np.asarray(values, dtype=float)
    if not width > 0:
        raise ValueError(f"width must be > 0, got {width!r}")
    if time.shape != values.shape or time.size < 2:
        raise ValueError("time and values must be equal-length 1-D arrays of >= 2 samples")
    per = max(1, int(round(width / float(np.median(np.diff(time))))))
    n = time.size // per
    if n == 0:
        return time[:1], values[:1], values[:1], values[:1]
    blocks = values[: n * per].reshape(n, per)
    centre = time[: n * per].reshape(n, per).mean(axis=1)
    return centre, blocks.mean(axis=1), blocks.min(axis=1), blocks.max(axis=1)


def figure_columns(stem: str) -> tuple[str, ...]:
    """The table columns :func:`figure` reads to draw ``stem``.

    Examples
    --------
    >>> figure_columns("fig3_q2")
    ('time', 'q2', 'q2d')
    """
    _, _, _, col, ref, _ = figure_spec(FIGURES, stem)
    return ("time", col) if ref is None else ("time", col, ref)


def figure(tables, stem):
    """One of the thesis-style Fig. 3-6 as a slide-sized :class:`matplotlib.figure.Figure`.

    - Fig. 3-4 (gimbal angles): the simulated angle with the reference dashed on top, and
      below it ``|q - q_d|`` on a log axis, where the tracking error is visible: each
      sample faint (the transients), the maximum over 50 ms windows solid and darker,
      each named in the legend; where the error is exactly zero (before the reference
      moves) the axis says so.
    - Fig. 5 (T1, switching every sample): the moving mean over :data:`T1_WINDOW_S` with
      its min-max band and the motor range, and a zoomed window of the raw samples.
    - Fig. 6 (T2): the same mean and band, scaled to the data; the motor range, far
      outside, is stated in the title.

    Parameters
    ----------
    tables : dict
        Case name to its :func:`table` columns.
    stem : str
        A file stem of :data:`FIGURES`, e.g. ``"fig5_T1"``.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from controlkit.studies.cmg.scenario import run
    >>> fig = figure({"thesis": table(run(horizon=0.5))}, "fig3_q2")
    >>> fig.axes[1].get_yscale()
    'log'
    """
    from matplotlib.lines import Line2D

    from ...outputs.style import IDEAL_STYLE, legend_outside, log_scale, new_figure, slide_style

    _, title, ylabel, col, ref, limit = figure_spec(FIGURES, stem)
    if not tables:
        raise ValueError("tables must hold at least one case")
    first = next(iter(tables.values()))
    with slide_style():
        if ref is not None:
            fig, (ax, err_ax) = new_figure(2, height_ratios=(3, 2))
            from matplotlib.colors import to_rgb

            several = len(tables) > 1
            for name, c in tables.items():
                color = _COLORS.get(name, "tab:green")
                darker = tuple(0.55 * v for v in to_rgb(color))
                case = f", {_label(name)}" if several else ""
                ax.plot(c["time"], c[col], color=color, label=f"{col} ({_label(name)})")
                err = np.abs(c[col] - c[ref])
                step_ms = 1000 * float(np.median(np.diff(c["time"])))
                err_ax.plot(c["time"], np.where(err > 0, err, np.nan), color=color,
                            linewidth=0.6, alpha=0.45,
                            label=f"|{col} \N{MINUS SIGN} {ref}| every {step_ms:g} ms{case}")
                centre, _, _, high = window_stats(c["time"], err, T1_WINDOW_S)
                err_ax.plot(centre, np.where(high > 0, high, np.nan), color=darker,
                            linewidth=2.0, label=f"its maximum over "
                                                 f"{1000 * T1_WINDOW_S:g} ms{case}")
                moving = c["time"][err > 0]
                if not several and moving.size and moving[0] > c["time"][0] + 0.05 * (
                        c["time"][-1] - c["time"][0]):
                    err_ax.text(0.01, 0.5, f"0 until t = {moving[0]:.3g} s",
                                transform=err_ax.transAxes, ha="left", va="center",
                                color="0.35", fontsize=12)
            ax.plot(first["time"], first[ref], color="k", label=f"{ref} (reference)",
                    **IDEAL_STYLE)
            log_scale(err_ax)
            err_ax.set_ylabel(f"|{col} \N{MINUS SIGN} {ref}| [rad]")
            err_ax.set_xlabel("time [s]")
        else:  # torques switch every sample: a moving mean with its min-max band
            if stem == "fig5_T1":
                fig, (ax, zoom) = new_figure(2, height_ratios=(3, 2), sharex=False)
            else:
                fig, (ax,) = new_figure()
            for name, c in tables.items():
                color = _COLORS.get(name, "tab:green")
                centre, mean, low, high = window_stats(c["time"], c[col], T1_WINDOW_S)
                ax.fill_between(centre, low, high, color=color, alpha=0.25, linewidth=0,
                                label=f"min-max over {1000 * T1_WINDOW_S:g} ms")
                ax.plot(centre, mean, color=color,
                        label=f"{col} ({_label(name)}), {1000 * T1_WINDOW_S:g} ms mean")
            ax.set_xlabel("time [s]")
            if stem == "fig5_T1":
                t0 = _zoom_start(first["time"])
                for name, c in tables.items():
                    inside = (c["time"] >= t0) & (c["time"] <= t0 + T1_ZOOM_S)
                    zoom.step(c["time"][inside], c[col][inside], where="post", marker=".",
                              markersize=4, color=_COLORS.get(name, "tab:green"),
                              linewidth=1.0)
                zoom.set_title(f"raw samples from t = {t0:g} s: sgn(s) switches every "
                               "sample", fontsize=12)
                zoom.set_xlabel("time [s]")
                zoom.set_ylabel(ylabel)
                ax.axvspan(t0, t0 + T1_ZOOM_S, color="0.5", alpha=0.3)
        if limit is not None:
            peak = max(float(np.abs(c[col]).max()) for c in tables.values())
            if peak >= 0.5 * limit:  # the range is part of the picture: draw it
                for sign in (1, -1):
                    ax.axhline(sign * limit, color="r", linestyle=":", linewidth=1.6,
                               label="motor range" if sign == 1 else None)
            else:  # far outside the data: say it instead of squashing the curve
                title = f"{title}\n(motor range \N{PLUS-MINUS SIGN}{limit:g} N m, off this scale)"
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        legend = legend_outside(fig, ncols=2)
        for handle in legend.legend_handles:  # the faint per-sample line, legible as a swatch
            if isinstance(handle, Line2D) and handle.get_linewidth() < 1.0:
                handle.set_linewidth(3.0)
    return fig


def _zoom_start(time):
    """Start of Fig. 5's zoomed window: half way through the run, on a sample."""
    middle = time[0] + 0.5 * (time[-1] - time[0])
    return float(time[np.searchsorted(time, middle)])


def figures(tables, outdir, *, stems=None) -> list[Path]:
    """Save Fig. 3-6 (:func:`figure`) as PNG at 200 dpi and SVG.

    ``stems`` (file stems of :data:`FIGURES`) limits the figures drawn; default all.

    Examples
    --------
    >>> import tempfile
    >>> from controlkit.studies.cmg.scenario import run
    >>> paths = figures({"thesis": table(run(horizon=0.1))}, tempfile.mkdtemp())
    >>> [p.name for p in paths if p.suffix == ".png"]
    ['fig3_q2.png', 'fig4_q4.png', 'fig5_T1.png', 'fig6_T2.png']
    """
    from ...outputs.style import save

    written = []
    for stem in select_stems(FIGURES, stems):
        written += save(figure(tables, stem), Path(outdir) / f"{stem}.png")
    return written
