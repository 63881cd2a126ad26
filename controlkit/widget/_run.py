"""Running an edited diagram: python-control's arguments, the one simulation call, scopes
and measures."""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np

from ._sources import values
from ._specs import interconnect_specs

#: Time points of a continuous (or sampled-data) run.
CONTINUOUS_POINTS = 2001
#: The most samples a page's run may ask for (memory: every block output is recorded).
MAX_SAMPLES = 2_000_000


def simulate(sys, T, X0, U=0.0):
    """Simulate ``sys``: the one place where the editor calls a simulator.

    :func:`controlkit.input_output_response`: compiled where it can be (a diagram it
    cannot compile runs on python-control, with a warning that the editor shows);
    continuous, discrete and sampled-data diagrams (:func:`controlkit.interconnect`).

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

    return input_output_response(sys, T, U, X0)


def time_points(horizon, dt):
    """The time grid of a run: every sample of a discrete diagram, 2001 points otherwise.

    Examples
    --------
    >>> time_points(1.0, 0.25).tolist()
    [0.0, 0.25, 0.5, 0.75, 1.0]
    """
    steps, dt = _steps(horizon, dt)
    if steps is None:
        return np.linspace(0.0, float(horizon), CONTINUOUS_POINTS)
    return np.arange(steps + 1) * dt


def time_expression(horizon, dt):
    """:func:`time_points` as the exported code writes it.

    Examples
    --------
    >>> time_expression(20.0, 0.1), time_expression(5.0, 0)
    ('np.arange(201) * 0.1', 'np.linspace(0.0, 5.0, 2001)')
    """
    steps, dt = _steps(horizon, dt)
    if steps is None:
        return f"np.linspace(0.0, {float(horizon)!r}, {CONTINUOUS_POINTS})"
    return f"np.arange({steps + 1}) * {dt!r}"


def _steps(horizon, dt):
    """``(steps, period)`` of a discrete run, ``(None, None)`` of a continuous one."""
    horizon = float(horizon)
    if not np.isfinite(horizon) or horizon <= 0:
        raise ValueError(f"horizon must be a positive number of seconds, got {horizon}")
    if dt is None or dt is True or dt <= 0:
        return None, None
    dt = float(dt)
    steps = int(round(horizon / dt))
    if steps < 1:
        raise ValueError(f"horizon must be at least one sample ({dt} s), got {horizon}")
    if steps > MAX_SAMPLES:
        raise ValueError(f"horizon must be at most {MAX_SAMPLES:,} samples of {dt:g} s "
                         f"({MAX_SAMPLES * dt:g} s), got {horizon:g} s")
    return steps, dt


def run_arguments(model, sys=None):
    """python-control's ``input_output_response`` arguments that the page builds.

    Parameters
    ----------
    model : DiagramModel
        The diagram, with its run's setup (``horizon``, ``sources``, ``initial``).
    sys : control.InterconnectedSystem, optional
        The built diagram (:meth:`~DiagramModel.system`); needed for ``X0``.

    Returns
    -------
    dict
        ``T`` (time points), ``U`` (one row per input of the interconnect, in its
        order, or ``0.0`` without inputs), ``X0`` (when ``sys`` is given: the states set
        in the page, else each block's ``x0``, else zero; see
        :func:`controlkit.initial_state`), ``params`` (none is given at run time: each
        block keeps its own), and for the code writer ``dt`` and ``sources``
        (``[(input, source)]``).

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.widget import DiagramModel
    >>> lag = ct.ss(-1.0, 1.0, 1.0, 0.0, name="lag", inputs="u", outputs="y")
    >>> model = DiagramModel.from_interconnect(ct.interconnect([lag], inputs="u",
    ...                                                        outputs="y"))
    >>> model.horizon = 2.0
    >>> model.set_source("u", "step", value=1.0, time=1.0)
    >>> args = run_arguments(model, model.system())
    >>> args["T"].size, args["U"][0, [0, 1000, 2000]].tolist(), args["X0"].tolist()
    (2001, [0.0, 1.0, 1.0], [0.0])
    """
    dt = model.run_period()
    T = time_points(model.horizon, dt)
    labels = interconnect_specs(model)[2]
    sources = [(label, model.source_of(label)) for label in labels]
    U = np.array([values(src, T) for _, src in sources]) if sources else 0.0
    arguments = {"T": T, "U": U, "params": {}, "dt": dt, "sources": sources}
    if sys is not None:
        from controlkit.simulation import initial_state

        arguments["X0"] = initial_state(sys, **model.initial)
    return arguments


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


def run_diagram(model, *, measures, scopes, points=1500):
    """Run the edited diagram with its setup; what the editor's scopes draw.

    Every output of every block is recorded (so any signal can be scoped without
    running again); scopes and measures take theirs from the result.

    Returns
    -------
    results : dict
        ``time``, ``traces`` ``[{name, y}]`` (at most ``points`` evenly spaced time
        points; the measures' summaries use every sample), ``measures``, ``steps``,
        ``seconds``, ``warnings``.
    response : control.TimeResponseData
        The run itself, every sample; its outputs are the block outputs, in the order
        of ``response.output_labels`` (``"block.signal"``).
    """
    sys, recorded = recording_system(model)
    arguments = run_arguments(model, sys)
    started = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        resp = simulate(sys, arguments["T"], arguments["X0"], arguments["U"])
    seconds = time.perf_counter() - started
    index = {label: i for i, label in enumerate(recorded)}
    outputs = np.asarray(resp.outputs).reshape(len(recorded), -1)
    keep = _buckets(resp.time.size, points)
    traces = [_trace(name, resp.time, outputs[index[name]], keep)
              for name in scopes if name in index]
    summaries = []
    for m in measures:
        missing = [s for s in m.signals if s not in index]
        if missing:
            summaries.append({"name": m.name, "text": f"{m.name}: not measured, the diagram "
                              f"has no signal {', '.join(missing)}", "met": None,
                              "worst": None, "limit": m.limit, "unit": m.unit, "log": m.log})
            continue
        y, summary = m.evaluate(resp.time, outputs[[index[s] for s in m.signals]])
        summary["y"] = _rounded(y[keep])
        summaries.append(summary)
    notes = sorted({str(w.message) for w in caught if "Unused" not in str(w.message)})
    resp.output_labels = recorded
    results = {"time": _rounded(resp.time[keep]), "traces": traces, "measures": summaries,
               "steps": int(resp.time.size - 1), "seconds": seconds, "warnings": notes}
    return results, resp


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
    recording = model.system(outlist=specs, outputs=[f"y[{k}]" for k in range(len(specs))],
                             name=f"{model.name}_recorded")
    return recording, names


def _trace(name, time, y, keep):
    """A scoped signal: its points for the chart and, from every sample, its final value and
    its largest excursion (the value farthest from zero, and when)."""
    finite = np.isfinite(y)
    summary = {"final": None, "peak": None, "peak_time": None}
    if finite.any():
        k = int(np.nanargmax(np.where(finite, np.abs(y), -np.inf)))
        summary = {"final": _rounded(y[-1:])[0], "peak": _rounded(y[k:k + 1])[0],
                   "peak_time": _rounded(time[k:k + 1])[0]}
    return {"name": name, "y": _rounded(y[keep]), **summary}


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
