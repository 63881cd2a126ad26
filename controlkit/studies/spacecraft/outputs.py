"""Tables, metrics and the paper-style Fig. 5-10 of the spacecraft study."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ...blocks.spacecraft import POINTING_REQUIREMENT_DEG, pointing_error_deg
from ...outputs.common import figure_spec, select_stems, signal
from . import scenario

#: CSV columns of ``controlkit reproduce spacecraft``, in order.
COLUMNS = ("time", "h1", "h2", "pointing_error_deg", "u1", "u2",
           "K11", "K12", "K21", "K22", "q0", "q1", "q2", "q3")


def table(resp) -> dict[str, np.ndarray]:
    """The CSV columns of :data:`COLUMNS` from a closed-loop response.

    ``K`` columns are 0 where the loop has no compensator.

    Examples
    --------
    >>> list(table(scenario.run("ideal", horizon=0.2))) == list(COLUMNS)
    True
    """
    q = np.vstack([signal(resp, f"q[{i}]") for i in range(4)])
    labels = list(resp.output_labels)
    K = [signal(resp, f"K[{i}]") if f"K[{i}]" in labels else np.zeros_like(resp.time)
         for i in range(4)]
    columns = [resp.time, q[1], q[2], pointing_error_deg(q),
               signal(resp, "u[0]"), signal(resp, "u[1]"), *K, *q]
    return dict(zip(COLUMNS, columns, strict=True))


def metrics(resp) -> dict:
    """Headline numbers of one case.

    Returns
    -------
    dict
        ``final_pointing_error_deg``, ``max_pointing_error_last_half_deg``,
        ``requirement_met_last_half`` (``<= 0.05`` deg), ``peak_abs_u1_rad_s``,
        ``peak_abs_u2_rad_s``, ``final_h``, ``final_K`` (row-major, 0 without MEC),
        ``horizon_s``.

    Examples
    --------
    >>> m = metrics(scenario.run("ideal", horizon=1.0))
    >>> round(m["horizon_s"], 6)
    1.0
    """
    return metrics_from_table(table(resp))


def metrics_from_table(cols) -> dict:
    """:func:`metrics` from the columns of :func:`table` (computed once by the caller).

    Examples
    --------
    >>> metrics_from_table(table(scenario.run("ideal", horizon=1.0)))["horizon_s"]
    1.0
    """
    t, err = cols["time"], cols["pointing_error_deg"]
    last_half = t >= t[-1] / 2
    worst = float(err[last_half].max())
    return {
        "horizon_s": float(t[-1]),
        "final_pointing_error_deg": float(err[-1]),
        "max_pointing_error_last_half_deg": worst,
        "requirement_deg": POINTING_REQUIREMENT_DEG,
        "requirement_met_last_half": bool(worst <= POINTING_REQUIREMENT_DEG),
        "peak_abs_u1_rad_s": float(np.abs(cols["u1"]).max()),
        "peak_abs_u2_rad_s": float(np.abs(cols["u2"]).max()),
        "final_h": [float(cols["h1"][-1]), float(cols["h2"][-1])],
        "final_K": [float(cols[k][-1]) for k in ("K11", "K12", "K21", "K22")],
    }


#: Where the figures come from, in every title: the CMG thesis numbers its figures too,
#: and results/ holds both studies' "Fig. 5".
SOURCE = "spacecraft paper"
# (file stem, title, y label, columns)
FIGURES = (
    ("fig05_h1", f"Fig. 5 of the {SOURCE}: output h1", "h1 = q1 [-]", ("h1",)),
    ("fig06_h2", f"Fig. 6 of the {SOURCE}: output h2", "h2 = q2 [-]", ("h2",)),
    ("fig07_pointing_error", f"Fig. 7 of the {SOURCE}: pointing error of the antenna",
     "pointing error [deg]", ("pointing_error_deg",)),
    ("fig08_K", f"Fig. 8 of the {SOURCE}: compensation gain K", "K [1/s]",
     ("K11", "K12", "K21", "K22")),
    ("fig09_u1", f"Fig. 9 of the {SOURCE}: input u1", "u1 [rad/s]", ("u1",)),
    ("fig10_u2", f"Fig. 10 of the {SOURCE}: input u2", "u2 [rad/s]", ("u2",)),
)
#: Colour of each entry of ``K`` in Fig. 8 (Okabe-Ito: told apart in colour-blind
#: vision and in greyscale print, together with the line styles).
K_COLORS = {"K11": "#0072B2", "K12": "#E69F00", "K21": "#009E73", "K22": "#CC79A7"}
#: Line style of each entry of ``K`` in Fig. 8, with one case; with several cases the
#: style tells the cases apart.
K_STYLES = {"K11": "-", "K12": "--", "K21": "-.", "K22": ":"}
#: Line style of each case in Fig. 8 when several cases have a compensator.
CASE_STYLES = ("-", "--", ":", "-.")
#: Lowest pointing error Fig. 7's log axis may show, in degrees: the axis starts at the
#: power of ten below the smallest error drawn (the ideal case reaches 3e-7 deg at
#: 20 000 s), but no lower than this.
FIG7_FLOOR_DEG = 1e-9
# ~4 000 points per curve: identical at slide size, and quick to draw
_POINTS = 4000


def figure_columns(stem: str) -> tuple[str, ...]:
    """The table columns :func:`figure` reads to draw ``stem``.

    Examples
    --------
    >>> figure_columns("fig05_h1")
    ('time', 'h1')
    """
    return ("time", *figure_spec(FIGURES, stem)[3])


def figure(tables: dict[str, dict[str, np.ndarray]], stem: str):
    """One of the paper's Fig. 5-10 as a slide-sized :class:`matplotlib.figure.Figure`.

    The ideal case (no model error) is dashed and drawn on top; the legend sits below the
    axes. Fig. 7 has a log axis with the 0.05 deg requirement, reaching down to the
    smallest error drawn; Fig. 8 shows only the cases with a compensator, one colour
    (:data:`K_COLORS`) per entry of ``K`` and, with several cases, one line style per
    case.

    Parameters
    ----------
    tables : dict
        Case name (a key of ``scenarios.spacecraft.CASES``) to its :func:`table` columns.
    stem : str
        Which figure: a file stem of :data:`FIGURES`, e.g. ``"fig07_pointing_error"``.

    Returns
    -------
    matplotlib.figure.Figure
        Displayed inline in a notebook; :func:`figures` saves it.

    Examples
    --------
    >>> fig = figure({"ideal": table(scenario.run("ideal", horizon=10.0))}, "fig07_pointing_error")
    >>> fig.axes[0].get_yscale()
    'log'
    """
    from ...outputs.style import IDEAL_STYLE, legend_outside, log_scale, new_figure, slide_style

    _, title, ylabel, cols = figure_spec(FIGURES, stem)
    unknown = [name for name in tables if name not in scenario.CASES]
    if unknown:
        raise ValueError(f"tables has unknown cases {unknown}; known: {list(scenario.CASES)}")
    shown = tables
    if stem == "fig08_K":  # only the cases that have a compensator
        shown = {n: c for n, c in tables.items() if scenario.CASES[n].compensator != "none"}
    # the ideal case last, so its dashed line lies on top of the others
    order = sorted(shown, key=lambda n: n == "ideal")
    with slide_style():
        fig, (ax,) = new_figure()
        for number, name in enumerate(order):
            columns, case = shown[name], scenario.CASES[name]
            every = slice(None, None, max(1, len(columns["time"]) // _POINTS))
            if len(cols) == 1:
                style = dict(IDEAL_STYLE) if name == "ideal" else {}
                ax.plot(columns["time"][every], columns[cols[0]][every], color=case.color,
                        label=case.label, **style)
                continue
            for col in cols:  # Fig. 8: a colour per entry of K, a style per case
                style = K_STYLES[col] if len(shown) == 1 else CASE_STYLES[
                    number % len(CASE_STYLES)]
                ax.plot(columns["time"][every], columns[col][every], color=K_COLORS[col],
                        linestyle=style, linewidth=2.0,
                        label=col if number == 0 or len(shown) == 1 else None)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        if stem == "fig07_pointing_error":
            log_scale(ax)
            ax.axhline(POINTING_REQUIREMENT_DEG, color="k", linestyle=":", linewidth=1.6,
                       label=f"requirement {POINTING_REQUIREMENT_DEG} deg", zorder=6)
            top = max([1.0] + [float(np.max(c["pointing_error_deg"])) for c in shown.values()])
            positive = [float(np.min(e[e > 0])) for c in shown.values()
                        if ((e := np.asarray(c["pointing_error_deg"])) > 0).any()]
            low = min(positive, default=POINTING_REQUIREMENT_DEG / 10)
            ax.set_ylim(max(FIG7_FLOOR_DEG, 10.0 ** np.floor(np.log10(low))), 2 * top)
        if stem == "fig08_K":
            if not shown:
                ax.text(0.5, 0.5, "no case with a compensator", transform=ax.transAxes,
                        ha="center", va="center")
            elif len(shown) > 1:  # one line style per case, named once
                from matplotlib.lines import Line2D

                for number, name in enumerate(order):
                    ax.add_line(Line2D([], [], color="0.25",
                                       linestyle=CASE_STYLES[number % len(CASE_STYLES)],
                                       label=scenario.CASES[name].label))
        if ax.get_legend_handles_labels()[0]:
            legend_outside(fig, ncols=4 if stem == "fig08_K" else None)
    return fig


def figures(tables: dict[str, dict[str, np.ndarray]], outdir, *, stems=None) -> list[Path]:
    """Save the paper's Fig. 5-10 for the cases in ``tables`` (PNG at 200 dpi and SVG).

    Fig. 8 (``K``) is saved only when a case with a compensator is present.

    Parameters
    ----------
    tables : dict
        Case name to its :func:`table` columns.
    outdir : str or pathlib.Path
        Folder for ``fig05_h1.png``, ``fig05_h1.svg`` and the others.
    stems : sequence of str, optional
        Only these figures (file stems of :data:`FIGURES`); default all.

    Returns
    -------
    list of pathlib.Path
        The files written, each PNG followed by its SVG.

    Examples
    --------
    >>> import tempfile
    >>> paths = figures({"ideal": table(scenario.run("ideal", horizon=1.0))}, tempfile.mkdtemp())
    >>> [p.name for p in paths][:3]
    ['fig05_h1.png', 'fig05_h1.svg', 'fig06_h2.png']
    """
    from ...outputs.style import save

    outdir = Path(outdir)
    written = []
    drawn = figure_stems(tables)
    for stem in select_stems(FIGURES, stems):
        if stem in drawn:
            written += save(figure(tables, stem), outdir / f"{stem}.png")
    return written


def figure_stems(cases) -> tuple[str, ...]:
    """The figures drawn for ``cases``: all, but Fig. 8 (``K``) only with a compensator.

    Examples
    --------
    >>> figure_stems(["ideal", "without_mec"])[-2:]
    ('fig09_u1', 'fig10_u2')
    >>> "fig08_K" in figure_stems(["proposed"])
    True
    """
    has_k = any(scenario.CASES[case].compensator != "none" for case in cases)
    return tuple(spec[0] for spec in FIGURES if spec[0] != "fig08_K" or has_k)


class StreamingMetrics:
    """:func:`metrics` accumulated chunk by chunk over a streamed run, every sample counted.

    Pass an instance as ``on_chunk`` of :func:`controlkit.studies.spacecraft.scenario.run`; the
    maxima and final values are the very ones :func:`metrics` computes from the whole run.

    Parameters
    ----------
    labels : sequence of str
        The loop's output labels.
    horizon : float
        The run's final time (for "the last half").

    Examples
    --------
    >>> watch = StreamingMetrics(scenario.build_loop("ideal").output_labels, 10.0)
    >>> resp = scenario.run("ideal", horizon=10.0, on_chunk=watch, record_every=10)
    >>> watch.metrics() == metrics(scenario.run("ideal", horizon=10.0))
    True
    """

    def __init__(self, labels, horizon):
        self.labels, self.half = list(labels), float(horizon) / 2
        self.worst = self.peak_u1 = self.peak_u2 = -np.inf
        self.last = None

    def __call__(self, time, outputs, states):
        from types import SimpleNamespace

        cols = table(SimpleNamespace(time=time, outputs=outputs, output_labels=self.labels))
        late = time >= self.half
        if late.any():
            self.worst = max(self.worst, float(cols["pointing_error_deg"][late].max()))
        self.peak_u1 = max(self.peak_u1, float(np.abs(cols["u1"]).max()))
        self.peak_u2 = max(self.peak_u2, float(np.abs(cols["u2"]).max()))
        self.last = {name: values[-1:] for name, values in cols.items()}

    def metrics(self) -> dict:
        """The metrics of the samples seen so far (the whole run once it has ended)."""
        if self.last is None:
            raise ValueError("no samples yet: the run has not started")
        out = metrics_from_table(self.last)
        out.update({"max_pointing_error_last_half_deg": self.worst,
                    "requirement_met_last_half": bool(self.worst <= POINTING_REQUIREMENT_DEG),
                    "peak_abs_u1_rad_s": self.peak_u1, "peak_abs_u2_rad_s": self.peak_u2})
        return out
