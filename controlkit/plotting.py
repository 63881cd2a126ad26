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


#: The kinds of response whose default is one axes per output, as python-control draws them:
#: ``trace_types`` of :func:`control.step_response`, ``impulse_response``,
#: ``initial_response``.
PER_OUTPUT = ("step", "impulse", "initial")


def _is_response(resp):
    return hasattr(resp, "time") and hasattr(resp, "output_labels")


def _responses(resp):
    """``resp`` as ``[(name, response)]``: one response, a list of them or a dict by name.

    A list's responses are named by their systems (``resp.sysname``), as python-control's
    legends name them; a name that repeats gets its place in the list, ``"G (2)"``.
    """
    if _is_response(resp):
        return [(None, resp)]
    if isinstance(resp, Mapping):
        named = list(resp.items())
    elif isinstance(resp, Sequence) and not isinstance(resp, str):
        names = [getattr(r, "sysname", None) or f"response {i}" for i, r in enumerate(resp)]
        named = [(name if names.count(name) == 1 else f"{name} ({i + 1})", r)
                 for i, (name, r) in enumerate(zip(names, resp, strict=True))]
    else:
        named = None
    if not named:
        raise ValueError("resp must be a control.TimeResponseData (the result of "
                         "step_response, input_output_response, ...), or a non-empty list or "
                         f"dict of them, got {_describe(resp)}")
    for name, r in named:
        if not _is_response(r):
            raise ValueError(f"resp[{name!r}] must be a control.TimeResponseData, got "
                             f"{_describe(r)}")
    return named


def _describe(value):
    if isinstance(value, np.ndarray):  # resp[0], resp[1]: python-control's legacy (t, y)
        return (f"an array of shape {value.shape} (resp[0], resp[1] are the response "
                f"unpacked as time and outputs: pass the response itself)")
    return type(value).__name__


def _traces(name, resp):
    """The traces of one response as ``[(name, {kind: 2-D samples})]``.

    A step or impulse response of a system with several inputs holds one trace per input
    (``resp.y[:, i, :]``), labelled as python-control labels them (``"From u[0]"``); each
    is drawn as a response of its own. Responses with one trace keep their ``name``.
    """
    n = len(resp.time)
    ntraces = getattr(resp, "ntraces", 0) or 0
    labels = list(getattr(resp, "trace_labels", None) or [])
    found = []
    for i in range(max(ntraces, 1)):
        data = {}
        for kind in ("outputs", "states", "inputs"):
            values = getattr(resp, kind, None)
            count = len(getattr(resp, f"{kind[:-1]}_labels", None) or [])
            if values is None or not count:
                continue
            values = np.asarray(values, dtype=float)
            if ntraces:  # (signals, traces, time), or squeezed for a single input/output
                values = values.reshape(count, ntraces, n)[:, i, :]
            data[kind] = values.reshape(count, n)
        trace = labels[i] if i < len(labels) and labels[i] else f"trace {i}"
        label = name if ntraces <= 1 else trace if name is None else f"{name}, {trace}"
        found.append((label, data))
    return found


def _columns(resp, data, derived):
    """Every signal of a trace (outputs, then states, then inputs) as label -> samples."""
    columns = {}
    n = len(resp.time)
    for kind, values in data.items():
        labels = list(getattr(resp, f"{kind[:-1]}_labels"))
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


def _kind(resp):
    """``"step"``, ``"impulse"``, ``"initial"``, ``"forced"`` or None (python-control's)."""
    types = getattr(resp, "trace_types", None)
    return types[0] if types else None


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


def _names(row, labels):
    """How an axes names its signals: a whole vector by its base name (``h`` for ``h[0],
    h[1]``), an element by its label (``u[0]``), in the order of ``row``."""
    names = []
    for label in row:
        m = _INDEXED.fullmatch(label)
        whole = m and all(other in row for other in labels
                          if (n := _INDEXED.fullmatch(other)) and n["base"] == m["base"])
        names.append(m["base"] if whole else label)
    return list(dict.fromkeys(names))


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
    resp : control.TimeResponseData, or list or dict of them
        Any response python-control returns: :func:`control.step_response`,
        ``impulse_response``, ``initial_response``, ``forced_response``,
        ``input_output_response`` (and :func:`controlkit.input_output_response`,
        :func:`controlkit.simulation.simulate`). Several responses are drawn on the same
        axes in different colours: a dict names them (``{"ideal": r1, "without MEC":
        r2}``), a list (or python-control's ``TimeResponseList``) by their systems'
        names. A response with several traces (the step response of a system with
        several inputs) is drawn as one response per trace, named as python-control
        names them (``"From u[0]"``; ``"ideal, From u[0]"`` in a dict).
    signals : sequence, optional
        One entry per axes, top to bottom: a label or pattern (see
        :func:`match_signals`: ``"h[0]"``, ``"q"``, ``"q[1:3]"``, ``"mu*"``), or a list
        of them drawn together. Outputs, states and inputs are all found by label.
        Default: every output; one axes per output for step, impulse and initial
        responses (as ``resp.plot()`` draws them), else one axes per base name (the four
        ``q[i]`` together).
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
        Line styles by response name (several responses, or a response's traces) or by
        signal pattern (one response), e.g. ``{"ideal": "--"}``: a curve that lies on
        another stays visible. Curves given a style are drawn last, on top.
    title : str, optional
        Title above the top axes (TeX allowed). Default: none, except for step, impulse
        and initial responses, which keep python-control's (``"Step response for G"``).
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
        A ``resp`` that is not a response (or list or dict of them), a signal or
        pattern that names nothing (the message lists the signals), an unknown
        ``time_unit``, a ``derived`` entry of the wrong shape.

    Notes
    -----
    Colours: with one response, each signal on an axes has its own colour, named in a
    legend to the right of the axes. With several responses (or traces), each has its
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

    The step responses of a system with two inputs and two outputs: an axes per output,
    a colour per input:

    >>> G = ct.ss([[-1, 0.5], [0, -2]], np.eye(2), [[1, 0], [0.3, 1]], 0, name="G")
    >>> shown = plot(ct.step_response(G))
    >>> shown.signals, shown.axes[0].get_title()
    ([['y[0]'], ['y[1]']], 'Step response for G')
    >>> [t.get_text() for t in shown.figure.legends[0].get_texts()]
    ['From u[0]', 'From u[1]']
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
    responses = _responses(resp)
    tables, owner = {}, {}
    for name, r in responses:
        time = np.asarray(r.time, dtype=float) / TIME_UNITS[time_unit]
        for run, data in _traces(name, r):
            if run in tables:
                raise ValueError(f"two responses are both named {run!r}: name them apart")
            tables[run], owner[run] = (time, _columns(r, data, derived)), name
    first = responses[0][1]
    known = list(next(iter(tables.values()))[1])
    kinds = {_kind(r) for _, r in responses}
    per_output = len(kinds) == 1 and kinds <= set(PER_OUTPUT)
    if signals is None:  # python-control's step plots: an axes per output; else per vector
        signals = list(dict.fromkeys(
            label if per_output else m["base"] if (m := _INDEXED.fullmatch(label)) else label
            for label in first.output_labels))
    literal_title = title is None and per_output
    if literal_title:  # python-control's title, with the system's name as it is
        (kind,) = kinds
        title = first.title if len(responses) == 1 else f"{kind.capitalize()} responses"
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
    several = len(tables) > 1
    if several:
        names = list(dict.fromkeys(list(tables) + list(owner.values())))
        unknown = [name for name in styles if name not in names]
        if unknown:
            raise ValueError(f"styles names unknown responses {unknown}; responses: "
                             f"{list(tables)}")
        style_of = {run: styles.get(run, styles.get(owner[run])) for run in tables}
    else:
        style_of = _by_label(styles, known, "styles")
    unit_of, line_of = _by_label(units, known, "units"), _by_label(lines, known, "lines")
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
            ax.set_ylabel(", ".join(_names(row, known)) + (f" [{unit}]" if unit else ""))
            if is_log:
                ax.set_yscale("log")
                ax.yaxis.set_major_formatter(PowerOfTenFormatter())
            if len(beside) > 1:  # one curve alone: the y label says what it is
                ax.legend(*zip(*beside, strict=True), loc="center left",
                          bbox_to_anchor=(1.01, 0.5))
        axes[-1].set_xlabel(f"time [{time_unit}]")
        if title:
            axes[0].set_title(title, parse_math=not literal_title)
        if below:
            fig.legend(list(below.values()), list(below), loc="outside lower center",
                       ncols=min(len(below), 4))
    return ResponsePlot(fig, axes, rows)

