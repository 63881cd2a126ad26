"""One look for every result figure: sized, lettered and saved for a lecture slide.

The figures are built as :class:`matplotlib.figure.Figure` objects with no pyplot
state and no backend switch, so the same code draws into a notebook (displayed
inline), a worker process or a file. Saved figures are 8 x 4.5 inches (16:9), a PNG
at :data:`PNG_DPI` dots per inch (1600 x 900 pixels) and a vector SVG beside it;
text is 12-14 pt at that size, so it stays legible when the figure fills a slide.
"""

from __future__ import annotations

import contextlib
import os
import re
from pathlib import Path

from matplotlib import rcParams
from matplotlib.ticker import LogFormatterSciNotation

#: Saved figure size in inches, the shape of a 16 by 9 slide.
SLIDE_SIZE = (8.0, 4.5)
#: Resolution of the saved PNG (the pHYs chunk records it).
PNG_DPI = 200
#: Vector formats written next to every PNG.
VECTOR_FORMATS = ("svg",)
#: Matplotlib settings of the result figures (fonts in points at the saved size).
RC = {
    "font.size": 12.0,
    "axes.titlesize": 14.0,
    "axes.labelsize": 13.0,
    "xtick.labelsize": 12.0,
    "ytick.labelsize": 12.0,
    "legend.fontsize": 12.0,
    "figure.titlesize": 14.0,
    "lines.linewidth": 1.6,
    "axes.grid": True,
    "grid.alpha": 0.3,
    "legend.frameon": False,
    "svg.fonttype": "none",  # text stays text: editable, and a third quicker to write
    "path.simplify": True,
}
#: Style of the ideal (model-exact) curve, drawn last so it lies on top.
IDEAL_STYLE = {"linestyle": (0, (5, 3)), "linewidth": 2.0, "zorder": 5}


def slide_style():
    """Context manager applying :data:`RC` while a figure is built and saved.

    Examples
    --------
    >>> import matplotlib
    >>> with slide_style():
    ...     matplotlib.rcParams["font.size"]
    12.0
    """
    import matplotlib

    return matplotlib.rc_context(RC)


def new_figure(nrows=1, *, size=SLIDE_SIZE, sharex=True, height_ratios=None):
    """A slide-sized figure with ``nrows`` stacked axes and constrained layout.

    Call it inside :func:`slide_style` so the fonts apply.

    Parameters
    ----------
    nrows : int
        Number of stacked axes (>= 1).
    size : tuple of float
        Width and height in inches.
    sharex : bool
        Share the time axis between the rows.
    height_ratios : sequence of float, optional
        Relative row heights.

    Returns
    -------
    fig : matplotlib.figure.Figure
    axes : list of matplotlib.axes.Axes

    Examples
    --------
    >>> fig, axes = new_figure(2)
    >>> len(axes), fig.get_size_inches().tolist()
    (2, [8.0, 4.5])
    """
    from matplotlib.figure import Figure

    if isinstance(nrows, bool) or not isinstance(nrows, int) or nrows < 1:
        raise ValueError(f"nrows must be an integer >= 1, got {nrows!r}")
    fig = Figure(figsize=size, layout="constrained")
    axes = fig.subplots(nrows, 1, sharex=sharex, squeeze=False,
                        gridspec_kw={"height_ratios": height_ratios})[:, 0]
    return fig, list(axes)


_SUPERSCRIPT = str.maketrans("0123456789-", "⁰¹²³⁴⁵⁶⁷⁸⁹⁻")
# what matplotlib's log formatter writes: [sign] base^{exponent}, [sign] coeff\times
# base^{exponent}, or a number
_POWER = re.compile(r"\$\\mathdefault\{(-?)(?:([0-9.]+)\\times)?([0-9]+)(?:\^\{(-?[0-9]+)\})?\}\$")


class PowerOfTenFormatter(LogFormatterSciNotation):
    """Log-axis tick labels as plain text with superscript digits: ``10⁻⁴``, ``2×10⁻⁴``.

    The labels of matplotlib's default log formatter (the same ticks labelled, the same
    numbers), written without mathtext: parsing ``$\\mathdefault{10^{-4}}$`` took 4-5 ms
    per label, once for the PNG and once more for the SVG (Fig. 7 took 0.26 s to draw
    and save, 0.20 s with these labels). In the SVG the label is one editable text. A
    label of another form is left to mathtext.

    Examples
    --------
    >>> f = PowerOfTenFormatter()
    >>> [f(1e-4), f(1e2), f(1.0), f(2e-4), f(-1e-3)]
    ['10⁻⁴', '10²', '10⁰', '2×10⁻⁴', '−10⁻³']
    """

    def __call__(self, x, pos=None):
        label = super().__call__(x, pos)
        match = _POWER.fullmatch(label)
        if match is None:
            return label
        sign, coeff, base, exponent = match.groups()
        minus = "\N{MINUS SIGN}" if sign and rcParams["axes.unicode_minus"] else sign
        mantissa = f"{coeff}\N{MULTIPLICATION SIGN}" if coeff else ""
        return f"{minus}{mantissa}{base}{(exponent or '').translate(_SUPERSCRIPT)}"


def log_scale(ax, axis="y"):
    """Put one axis of ``ax`` on a log scale labelled by :class:`PowerOfTenFormatter`.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    axis : {"y", "x"}

    Examples
    --------
    >>> fig, (ax,) = new_figure()
    >>> log_scale(ax)
    >>> ax.get_yscale(), type(ax.yaxis.get_major_formatter()).__name__
    ('log', 'PowerOfTenFormatter')
    """
    if axis not in ("x", "y"):
        raise ValueError(f"axis must be 'x' or 'y', got {axis!r}")
    getattr(ax, f"set_{axis}scale")("log")
    target = ax.yaxis if axis == "y" else ax.xaxis
    target.set_major_formatter(PowerOfTenFormatter())
    target.set_minor_formatter(PowerOfTenFormatter(labelOnlyBase=False))


def legend_outside(fig, axes=None, *, ncols=None):
    """One legend for the whole figure, below the axes so no data hides behind it.

    Entries are gathered from ``axes`` (default: all axes of ``fig``), duplicates once.

    Examples
    --------
    >>> fig, (ax,) = new_figure()
    >>> _ = ax.plot([0, 1], label="a"); _ = ax.plot([1, 0], label="b")
    >>> [t.get_text() for t in legend_outside(fig).get_texts()]
    ['a', 'b']
    """
    seen = {}
    for ax in axes if axes is not None else fig.axes:
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            seen.setdefault(label, handle)
    ncols = ncols or min(len(seen), 3) or 1
    return fig.legend(list(seen.values()), list(seen), loc="outside lower center", ncols=ncols)


def save(fig, path) -> list[Path]:
    """Write ``fig`` as a PNG at :data:`PNG_DPI` and as SVG beside it.

    Each file is written under a temporary name and renamed, so an interrupted run
    never leaves a truncated figure behind.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    path : str or pathlib.Path
        The PNG's path; the SVG gets the same stem.

    Returns
    -------
    list of pathlib.Path
        The PNG first, then the vector copies.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> fig, _ = new_figure()
    >>> [p.name for p in save(fig, pathlib.Path(tempfile.mkdtemp()) / "a.png")]
    ['a.png', 'a.svg']
    """
    path = Path(path)
    if path.suffix != ".png":
        raise ValueError(f"path must end in .png (the SVG is written beside it), got {path}")
    path.parent.mkdir(parents=True, exist_ok=True)
    written = []
    with slide_style():
        for target, fmt in [(path, "png")] + [
                (path.with_suffix(f".{v}"), v) for v in VECTOR_FORMATS]:
            # a name of this process's own: two runs writing one folder never share it
            partial = target.with_name(f".{target.name}.{os.getpid()}.partial")
            try:
                fig.savefig(partial, format=fmt, dpi=PNG_DPI if fmt == "png" else "figure")
                os.replace(partial, target)
            finally:
                with contextlib.suppress(FileNotFoundError):
                    partial.unlink()
            written.append(target)
            # the layout is in figure coordinates and does not depend on the dpi: keep the
            # PNG's for the vector copies instead of solving it again (a third of the time).
            # No engine at all, not "none": savefig runs a non-rendering draw of the whole
            # figure before saving whenever a figure has an engine, even one that does
            # nothing (a fifth of the SVG's time)
            fig.set_layout_engine(None)
    return written
