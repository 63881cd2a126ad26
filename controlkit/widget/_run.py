"""Running an edited diagram: the one simulation call, initial states, scopes and measures."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import control as ct
import numpy as np

from ._code import interconnect_specs


def simulate(sys, T, X0, U=0.0):
    """Simulate ``sys``: the one place where the editor calls a simulator.

    :func:`controlkit.input_output_response`: compiled where it can be (a diagram it
    cannot compile runs on python-control, with a warning that the editor shows), and a
    continuous plant under a discrete controller runs too.

    Parameters
    ----------
    sys : control.InterconnectedSystem
    T : numpy.ndarray
        Time points.
    X0 : numpy.ndarray
        Initial state, ``sys.nstates`` values.
    U : float or numpy.ndarray
        Inputs, as for :func:`control.input_output_response`.

    Returns
    -------
    control.TimeResponseData
    """
    from controlkit.simulation import input_output_response

    U = np.asarray(U, dtype=float)
    if U.ndim == 1 and U.size == sys.ninputs:  # one value per input, held over the run
        U = np.repeat(U.reshape(-1, 1), len(T), axis=1)
    return input_output_response(sys, T, U, X0)


def time_points(horizon, dt):
    """The time grid of a run: every sample of a discrete diagram, 2001 points otherwise.

    Examples
    --------
    >>> time_points(1.0, 0.25).tolist()
    [0.0, 0.25, 0.5, 0.75, 1.0]
    """
    horizon = float(horizon)
    if not np.isfinite(horizon) or horizon <= 0:
        raise ValueError(f"horizon must be a positive number of seconds, got {horizon}")
    if dt is not None and dt is not True and dt > 0:
        steps = int(round(horizon / dt))
        if steps < 1:
            raise ValueError(f"horizon must be at least one sample ({dt} s), got {horizon}")
        return np.arange(steps + 1) * float(dt)
    return np.linspace(0.0, horizon, 2001)


def stacked_state(sys, initial):
    """The initial state of ``sys`` from ``{block: values}``, else each block's ``x0``, else 0.

    Examples
    --------
    >>> import control as ct
    >>> a = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="a", inputs="u", outputs="y")
    >>> b = ct.ss([[-2.0]], [[1.0]], [[1.0]], [[0.0]], name="b", inputs="y", outputs="z")
    >>> stacked_state(ct.interconnect([a, b], inputs="u", outputs="z"), {"b": [3.0]}).tolist()
    [0.0, 3.0]
    """
    parts = []
    for s in sys.syslist:
        if not s.nstates:
            continue
        value = initial.get(s.name, getattr(s, "x0", None))
        value = np.zeros(s.nstates) if value is None else np.asarray(value, dtype=float)
        value = value.reshape(-1)
        if value.size != s.nstates:
            raise ValueError(f"initial state of block {s.name!r} must have {s.nstates} values "
                             f"({', '.join(s.state_labels)}), got {value.size}")
        parts.append(value)
    return np.concatenate(parts) if parts else np.zeros(0)


@dataclass
class Measure:
    """A quantity computed from recorded signals, checked against a limit.

    ``function`` takes an array ``(len(signals), N)`` and returns ``N`` values; the
    summary is the largest absolute value over the last half of the run
    (``over="last half"``) or over all of it (``"all"``).
    """

    name: str
    signals: list
    function: object
    unit: str = ""
    limit: float | None = None
    over: str = "last half"
    log: bool = False

    def evaluate(self, time, values):
        y = np.asarray(self.function(values), dtype=float).reshape(-1)
        if y.shape != time.shape:
            raise ValueError(f"measure {self.name!r} must return one value per time point "
                             f"({time.size}), got shape {y.shape}")
        part = y[len(y) // 2:] if self.over == "last half" else y
        worst = float(np.max(np.abs(part))) if part.size else float("nan")
        met = None if self.limit is None else bool(worst <= self.limit)
        where = "over the last half" if self.over == "last half" else "over the run"
        text = f"{self.name}: worst {where} {worst:.4g} {self.unit}".rstrip()
        if self.limit is not None:
            text += (f" {'<=' if met else '>'} {self.limit:g} {self.unit}: requirement "
                     f"{'met' if met else 'missed'}")
        return y, {"name": self.name, "worst": worst, "limit": self.limit, "met": met,
                   "unit": self.unit, "text": text, "log": self.log}


def run_diagram(model, *, horizon, initial, inputs, measures, scopes, points=1500):
    """Run the edited diagram; what the editor's scopes draw.

    Every output of every block is recorded (so any signal can be scoped without
    running again); scopes and measures take theirs from the result.

    Returns
    -------
    dict
        ``time``, ``traces`` ``[{name, y}]`` (at most ``points`` evenly spaced time
        points; the measures' summaries use every sample), ``measures``, ``steps``,
        ``seconds``, ``warnings``.
    """
    sys, recorded = recording_system(model)
    T = time_points(horizon, sys.dt)
    X0 = stacked_state(sys, initial)
    unknown = sorted(set(inputs) - set(sys.input_labels))
    if unknown:
        raise ValueError(f"inputs {unknown} are not inputs of the diagram; its inputs: "
                         f"{sys.input_labels}")
    U = np.array([float(inputs.get(name, 0.0)) for name in sys.input_labels])
    started = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        resp = simulate(sys, T, X0=X0, U=U if U.size else 0.0)
    seconds = time.perf_counter() - started
    index = {label: i for i, label in enumerate(recorded)}
    outputs = np.asarray(resp.outputs).reshape(len(recorded), -1)
    keep = _buckets(resp.time.size, points)
    traces = []
    for name in scopes:
        if name in index:
            traces.append({"name": name, "y": _rounded(outputs[index[name]][keep])})
    summaries = []
    for m in measures:
        missing = [s for s in m.signals if s not in index]
        if missing:
            summaries.append({"name": m.name, "text": f"{m.name}: not measured, the diagram "
                              f"has no signal {', '.join(missing)}", "met": None,
                              "worst": None, "limit": m.limit, "unit": m.unit, "log": m.log})
            continue
        values = outputs[[index[s] for s in m.signals]]
        y, summary = m.evaluate(resp.time, values)
        summary["y"] = _rounded(y[keep])
        summaries.append(summary)
    notes = sorted({str(w.message) for w in caught if "Unused" not in str(w.message)})
    return {"time": _rounded(resp.time[keep]), "traces": traces, "measures": summaries,
            "steps": int(resp.time.size - 1), "seconds": seconds, "warnings": notes}


def recording_system(model):
    """The diagram with every block output as an output, and their names ``block.signal``.

    (python-control allows no dot in a signal name: the outputs are called ``y[0]``...)
    """
    sys = model.system()
    names, specs = [], []
    for s in sys.syslist:
        for label in s.output_labels:
            names.append(f"{s.name}.{label}")
            specs.append((s.name, label, 1.0))
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"Unused (input|output)", category=UserWarning)
        connections, inplist, inputs, _, _ = interconnect_specs(model)
        recording = ct.interconnect(
            sys.syslist, connections=connections or False, inplist=inplist, inputs=inputs,
            outlist=specs, outputs=[f"y[{k}]" for k in range(len(specs))],
            name=f"{model.name}_recorded")
    return recording, names


def _buckets(n, points):
    """At most ``points`` evenly spaced indices of ``n`` samples, first and last included.

    Examples
    --------
    >>> _buckets(10, 4).tolist()
    [0, 3, 6, 9]
    """
    if n <= points:
        return np.arange(n)
    idx = np.unique(np.linspace(0, n - 1, points).round().astype(int))
    return idx


def _rounded(values):
    return [float(f"{v:.6g}") if np.isfinite(v) else None for v in np.asarray(values, float)]
