"""Plotting the signals of a response that a student cares about: :func:`plot`.

python-control's ``resp.plot()`` draws every output and input of a response on a
subplot of its own: for the spacecraft's MEC loop that is 12 to 16 squashed axes.
:func:`plot` draws the signals asked for, by label, on a shared time axis in the unit
asked for, with units on the axes, legends outside the data, and the slide style of
the papers' figures (:mod:`controlkit.outputs.style`).
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

#: Seconds per unit of the time axis, for ``time_unit``.
TIME_UNITS = {"ms": 1e-3, "s": 1.0, "min": 60.0, "h": 3600.0, "d": 86400.0}
#: Samples per curve above which a curve is drawn as its envelope (min and max per
#: bucket, in time order): the same picture at slide size, quicker to draw.
MAX_POINTS = 20_000
_SLICE = re.compile(r"(?P<base>.+)\[(?P<start>\d*):(?P<stop>\d*)\]")
_INDEXED = re.compile(r"(?P<base>.+)\[\d+\]")


@dataclass
class ResponsePlot:
    """What :func:`plot` drew: the figure, its axes and the signals on each.

    Attributes
    ----------
    figure : matplotlib.figure.Figure
    axes : list of matplotlib.axes.Axes
        One per entry of ``signals``, top to bottom, sharing the time axis.
    signals : list of list of str
        The labels drawn on each axes, after the patterns were matched.

    Examples
    --------
    >>> import control as ct, numpy as np
    >>> lag = ct.nlsys(lambda t, x, u, p: -x + u, lambda t, x, u, p: x, inputs="u",
    ...                outputs="y", states="x", name="lag")
    >>> resp = ct.input_output_response(lag, np.linspace(0, 5, 51), 1.0)
    >>> plot(resp, ["y", "u"]).signals
    [['y'], ['u']]
    """

    figure: object
    axes: list
    signals: list

    def __repr__(self):
        return f"ResponsePlot({len(self.axes)} axes: {self.signals})"


def match_signals(pattern: str, labels: Sequence[str]) -> list[str]:
    """The labels that ``pattern`` names, in the order of ``labels``.

    A pattern is a label (``"q[0]"``); a base name, for all its elements (``"q"`` is
    ``q[0]..q[3]``); a python-control slice (``"q[1:3]"`` is ``q[1], q[2]``); or a
    glob with ``*`` and ``?`` (``"mu*"``: ``mu[0], mu[1], mu_n[0], mu_n[1]``;
    ``"q[*]"``: every ``q[i]``). Brackets are literal except in a slice.

    Parameters
    ----------
    pattern : str
    labels : sequence of str
        The signals available.

    Returns
    -------
    list of str
        Never empty.

    Raises
    ------
    ValueError
        When no label matches; the message lists the labels.

    Examples
    --------
    >>> labels = ["q[0]", "q[1]", "q[2]", "mu[0]", "mu_n[0]", "T1"]
    >>> match_signals("q", labels), match_signals("q[1:3]", labels)
    (['q[0]', 'q[1]', 'q[2]'], ['q[1]', 'q[2]'])
    >>> match_signals("mu*", labels), match_signals("T1", labels)
    (['mu[0]', 'mu_n[0]'], ['T1'])
    """
    if not isinstance(pattern, str) or not pattern:
        raise ValueError(f"a signal must be a non-empty label or pattern, got {pattern!r}")
    labels = list(labels)
    if pattern in labels:
        return [pattern]
    found = []
    sliced = _SLICE.fullmatch(pattern)
    if sliced:
        start = int(sliced["start"] or 0)
        stop = int(sliced["stop"]) if sliced["stop"] else None
        found = [label for label in labels
                 if (m := re.fullmatch(rf"{re.escape(sliced['base'])}\[(\d+)\]", label))
                 and start <= int(m[1]) and (stop is None or int(m[1]) < stop)]
    elif "*" in pattern or "?" in pattern:
        glob = "".join(".*" if c == "*" else "." if c == "?" else re.escape(c)
                       for c in pattern)
        found = [label for label in labels if re.fullmatch(glob, label)]
    else:
        found = [label for label in labels
                 if (m := _INDEXED.fullmatch(label)) and m["base"] == pattern]
    if not found:
        raise ValueError(f"no signal matches {pattern!r}; signals: {labels}")
    return found


def _columns(resp, derived):
    """Every signal of ``resp`` (outputs, then states, then inputs) as label -> samples."""
    if getattr(resp, "ntraces", 0):
        raise ValueError(f"plot draws one response at a time; this one has {resp.ntraces} "
                         f"traces: pass resp[i] or one response per trace in a dict")
    columns = {}
    n = len(resp.time)
    for kind in ("outputs", "states", "inputs"):
        labels = list(getattr(resp, f"{kind[:-1]}_labels", None) or [])
        values = getattr(resp, kind, None)
        if not labels or values is None:
            continue
        values = np.asarray(values, dtype=float).reshape(len(labels), n)
        for label, row in zip(labels, values, strict=True):
            columns.setdefault(label, row)
    for name, spec in (derived or {}).items():
        if not (isinstance(spec, tuple) and len(spec) == 2 and callable(spec[0])):
            raise ValueError(f"derived[{name!r}] must be (function, signals), e.g. "
                             f"(pointing_error_deg, 'q'), got {spec!r}")
        function, sources = spec
        sources = [sources] if isinstance(sources, str) else list(sources)
        chosen = [label for s in sources for label in match_signals(s, list(columns))]
        value = np.asarray(function(np.vstack([columns[c] for c in chosen])), dtype=float)
        if value.shape != (n,):
            raise ValueError(f"derived[{name!r}] must give one value per time point "
                             f"({n}), got shape {value.shape}")
        columns[name] = value
    return columns


def _envelope(time, values, max_points):
    """``values`` thinned to about ``max_points`` samples, keeping each bucket's min and max."""
    if values.size <= max_points:
        return time, values
    per = int(np.ceil(2 * values.size / max_points))
    n = values.size // per
    blocks = values[: n * per].reshape(n, per)
    lo, hi = blocks.argmin(axis=1), blocks.argmax(axis=1)
    first, second = np.minimum(lo, hi), np.maximum(lo, hi)
    index = (np.arange(n) * per)[:, None] + np.stack([first, second], axis=1)
    index = np.append(index.ravel(), np.arange(n * per, values.size))
    return time[index], values[index]


def _by_label(table, labels, argument):
    """``{pattern: value}`` as ``{label: value}`` (the first pattern naming a label wins)."""
    if table is None:
        return {}
    if not isinstance(table, Mapping):
        raise ValueError(f"{argument} must be a dict of signal pattern to value, got {table!r}")
    found = {}
    for pattern, value in table.items():
        for label in match_signals(pattern, labels):
            found.setdefault(label, value)
    return found


def plot(resp, signals=None, *, time_unit="s", log=(), units=None, derived=None, lines=None,
         styles=None, title=None, size=None, max_points=MAX_POINTS) -> ResponsePlot:
    """Draw chosen signals of one or several responses, one axes per entry, time shared.

    Parameters
    ----------
    resp : control.TimeResponseData, or dict of str to it
        A response (:func:`controlkit.input_output_response`,
        :func:`control.input_output_response`, :func:`controlkit.simulation.simulate`),
        or several by name, drawn on the same axes in different colours (for instance
        ``{"ideal": r1, "without MEC": r2}``).
    signals : sequence, optional
        One entry per axes, top to bottom: a label or pattern (see
        :func:`match_signals`: ``"h[0]"``, ``"q"``, ``"q[1:3]"``, ``"mu*"``), or a list
        of them drawn together. Outputs, states and inputs are all found by label.
        Default: every output, one axes per base name.
    time_unit : {"ms", "s", "min", "h", "d"}
        Unit of the time axis.
    log : sequence of str
        Signals (labels or patterns) whose axes are logarithmic; a signal that is
        negative somewhere is drawn as its magnitude ``|x|`` there.
    units : dict, optional
        Unit of the y axis by signal pattern, e.g. ``{"u": "rad/s", "h": "-"}``.
    derived : dict, optional
        Signals computed from others: ``{name: (function, signals)}``; ``function``
        receives the matched signals stacked row by row (shape ``(n, len(time))``) and
        returns one value per time point, e.g.
        ``{"pointing error": (pointing_error_deg, "q")}``. Usable in ``signals``,
        ``log``, ``units`` and ``lines``.
    lines : dict, optional
        Horizontal reference lines by signal pattern: ``{pattern: value}`` or
        ``{pattern: (value, label)}``, e.g. a requirement.
    styles : dict, optional
        Line styles by response name (several responses) or by signal pattern (one
        response), e.g. ``{"ideal": "--"}``: a curve that lies on another stays visible.
        Curves given a style are drawn last, on top.
    title : str, optional
        Title above the top axes.
    size : tuple of float, optional
        Figure size in inches; default 8 inches wide (a 16:9 slide at 4.5 inches high)
        and 1.6 inches per axes beyond the second.
    max_points : int
        Curves longer than this are drawn as their min-max envelope (:data:`MAX_POINTS`).

    Returns
    -------
    ResponsePlot
        ``.figure``, ``.axes`` and the ``.signals`` drawn on each axes. The figure is
        made with pyplot, so a notebook shows it and a script shows it on
        ``plt.show()``.

    Raises
    ------
    ValueError
        A signal or pattern that names nothing (the message lists the signals), an
        unknown ``time_unit``, a ``derived`` entry of the wrong shape.

    Notes
    -----
    Colours: with one response, each signal on an axes has its own colour, named in a
    legend to the right of the axes. With several responses, each response has its
    colour, named once in a legend under the figure (with the reference lines), and the
    signals of one axes have their own line styles, named to the right of the axes.

    Examples
    --------
    A first-order lag ``x' = (u - x) / tau`` under a step, time in minutes:

    >>> import control as ct, numpy as np
    >>> lag = ct.nlsys(lambda t, x, u, p: (u - x) / 60.0, lambda t, x, u, p: x,
    ...                inputs="u", outputs="y", states="x", name="lag")
    >>> resp = ct.input_output_response(lag, np.linspace(0, 600, 601), 1.0)
    >>> shown = plot(resp, ["y", "u"], time_unit="min", units={"y": "m", "u": "m"})
    >>> shown.axes[-1].get_xlabel(), shown.axes[0].get_ylabel()
    ('time [min]', 'y [m]')
    >>> error = {"error": (lambda y: 1.0 - y[0], "y")}
    >>> plot(resp, ["error"], derived=error, log=["error"]).axes[0].get_yscale()
    'log'
    """
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from .outputs.style import PowerOfTenFormatter, slide_style

    if time_unit not in TIME_UNITS:
        raise ValueError(f"time_unit must be one of {list(TIME_UNITS)}, got {time_unit!r}")
    if isinstance(max_points, bool) or not isinstance(max_points, int) or max_points < 2:
        raise ValueError(f"max_points must be an integer >= 2, got {max_points!r}")
    if isinstance(log, str):
        log = [log]
    runs = dict(resp) if isinstance(resp, Mapping) else {None: resp}
    if not runs:
        raise ValueError("resp must be a response or a non-empty dict of responses")
    tables = {name: (np.asarray(r.time, dtype=float) / TIME_UNITS[time_unit],
                     _columns(r, derived)) for name, r in runs.items()}
    known = list(next(iter(tables.values()))[1])
    if signals is None:
        first = next(iter(runs.values()))
        signals = list(dict.fromkeys(
            (m["base"] if (m := _INDEXED.fullmatch(label)) else label)
            for label in first.output_labels))
    if isinstance(signals, str):
        signals = [signals]
    rows = []
    for entry in signals:
        patterns = [entry] if isinstance(entry, str) else list(entry)
        rows.append(list(dict.fromkeys(label for p in patterns
                                       for label in match_signals(p, known))))
    log_labels = {label for p in log for label in match_signals(p, known)}
    if styles is not None and not isinstance(styles, Mapping):
        raise ValueError(f"styles must be a dict of name to line style, got {styles!r}")
    styles = dict(styles or {})
    if len(runs) > 1:
        unknown = [name for name in styles if name not in runs]
        if unknown:
            raise ValueError(f"styles names unknown responses {unknown}; responses: "
                             f"{list(runs)}")
        style_of = styles
    else:
        style_of = _by_label(styles, known, "styles")
    unit_of, line_of = _by_label(units, known, "units"), _by_label(lines, known, "lines")
    several = len(runs) > 1
    width, height = size or (8.0, max(4.5, 1.6 * len(rows) + 1.3))
    with slide_style():
        fig, axes = plt.subplots(len(rows), 1, figsize=(width, height), sharex=True,
                                 squeeze=False, layout="constrained")
        axes = list(axes[:, 0])
        colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
        dashes = ["-", "--", "-.", ":"]
        below = {}  # the figure's legend, with several runs: a colour per run, the lines
        for ax, row in zip(axes, rows, strict=True):
            is_log = any(label in log_labels for label in row)
            beside = []  # this axes' legend: its signals (and lines, with one run)
            for r, (run, (time, columns)) in enumerate(tables.items()):
                for s, label in enumerate(row):
                    if label not in columns:
                        raise ValueError(f"response {run!r} has no signal {label!r}")
                    values, shown = columns[label], label
                    if is_log and np.any(values < 0):
                        values, shown = np.abs(values), f"|{label}|"
                    t, v = _envelope(time, values, max_points)
                    colour = colours[(r if several else s) % len(colours)]
                    style = dashes[s % len(dashes)] if several else "-"
                    given = style_of.get(run if several else label)
                    (curve,) = ax.plot(t, v, color=colour, linestyle=given or style,
                                       zorder=3 if given else 2)
                    if several:
                        below.setdefault(str(run), Line2D([], [], color=colour,
                                                          linestyle=given or "-"))
                        if r == 0 and len(row) > 1:
                            beside.append((Line2D([], [], color="0.3", linestyle=style), shown))
                    else:
                        beside.append((curve, shown))
            for label in row:
                if label in line_of:
                    value = line_of[label]
                    value, text = value if isinstance(value, tuple) else (value, f"{value:g}")
                    ref = ax.axhline(value, color="k", linestyle=":", linewidth=1.6, zorder=6)
                    if several:
                        below.setdefault(text, ref)
                    elif text not in [t for _, t in beside]:
                        beside.append((ref, text))
            unit = next((unit_of[label] for label in row if label in unit_of), None)
            bases = list(dict.fromkeys(
                (m["base"] if (m := _INDEXED.fullmatch(label)) else label) for label in row))
            ax.set_ylabel(", ".join(bases) + (f" [{unit}]" if unit else ""))
            if is_log:
                ax.set_yscale("log")
                ax.yaxis.set_major_formatter(PowerOfTenFormatter())
            if len(beside) > 1:  # one curve alone: the y label says what it is
                ax.legend(*zip(*beside, strict=True), loc="center left",
                          bbox_to_anchor=(1.01, 0.5))
        axes[-1].set_xlabel(f"time [{time_unit}]")
        if title:
            axes[0].set_title(title)
        if below:
            fig.legend(list(below.values()), list(below), loc="outside lower center",
                       ncols=min(len(below), 4))
    return ResponsePlot(fig, axes, rows)

