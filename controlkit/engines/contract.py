"""What every simulation backend shares: argument checks, chunking, the result.

A backend (one module of :mod:`controlkit.engines`, found through its registry)
takes the arguments checked here, may refuse a system it cannot run by raising
:class:`UnsupportedSystem` with the reason, and returns the
:class:`control.TimeResponseData` built by :func:`response`, so a result looks
the same whichever backend made it.
"""

from __future__ import annotations

import numbers

import control as ct
import numpy as np

from .. import _checks
from ..blocks.contract import check_initial_state
from ..blocks.sampling import TimeGrid


class UnsupportedSystem(ValueError):
    """The fast engine cannot run this system (the message names the block and why).

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> from controlkit.engines.fast import simulate
    >>> try:
    ...     simulate(spacecraft_plant(), [0.0, 0.1], [1.0, 0.0, 0.0, 0.0])
    ... except UnsupportedSystem as reason:
    ...     print(reason)
    'plant' is a single block; the fast engine runs interconnects
    """


def check_arguments(sys, T, X0, U=0.0):
    """``T``, ``X0`` and ``U`` of a run of ``sys`` (as for
    :func:`controlkit.simulation.simulate`) checked and shaped once, for every engine.

    Returns
    -------
    T : numpy.ndarray
        Time points, 1-D, finite, increasing (spaced by ``sys.dt`` if discrete).
    X0 : numpy.ndarray
        Initial state with exactly ``sys.nstates`` values (never zero-padded).
    U : numpy.ndarray
        Inputs, shape ``(ninputs, len(T))`` (a read-only view when constant).

    Raises
    ------
    ValueError
        Naming the argument, what it must be and what it is (an initial state that a
        block refuses, such as a quaternion that is not of unit norm, names the block).

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.ss([[0.5]], [[1.0, 1.0]], [[1.0]], [[0.0, 0.0]], dt=1)
    >>> T, X0, U = check_arguments(sys, [0, 1, 2], [1.0], [1.0, -1.0])  # U per input
    >>> U.tolist()
    [[1.0, 1.0, 1.0], [-1.0, -1.0, -1.0]]
    >>> check_arguments(sys, [0, 1, 2], [1.0, 0.0])
    Traceback (most recent call last):
    ...
    ValueError: X0 must have 1 values (x[0]), got 2
    """

    if isinstance(T, TimeGrid):  # a lazy grid stays lazy (long streamed runs)
        if T.size == 0 or not np.isfinite(T.Ts) or T.Ts <= 0:
            raise ValueError(f"T must be a non-empty grid with a positive step, got {T.size} "
                             f"samples of {T.Ts:g}")
        shortest = longest = T.Ts
    else:
        T = _checks.float_array("T", T)
        if T.ndim != 1 or T.size == 0:
            raise ValueError(f"T must be a non-empty 1-D array of time points, "
                             f"got shape {T.shape}")
        if not np.isfinite(T).all():
            raise ValueError("T must hold finite time points")
        steps = np.diff(T)
        if (steps <= 0).any():
            raise ValueError("T must be increasing")
        shortest, longest = (steps.min(), steps.max()) if steps.size else (0.0, 0.0)
    # np.isclose(step, dt) holds on an interval of steps: the extremes decide for all
    if (sys.isdtime(strict=True) and sys.dt is not True and T.size > 1
            and not np.allclose([shortest, longest], sys.dt)):
        raise ValueError(f"time steps of T must equal the sampling time {sys.dt} of "
                         f"{sys.name!r}, got steps from {shortest:g} to {longest:g}")
    if (sys.isdtime(strict=True) and sys.dt is True and T.size > 1
            and not np.allclose([shortest, longest], T[1] - T[0])):
        raise ValueError(f"time steps of T must be equal (the sampling time of {sys.name!r} "
                         f"is dt=True), got steps from {shortest:g} to {longest:g}")
    X0 = _checks.float_array("X0", X0 if X0 is not None else 0.0)
    if X0.ndim == 0 and sys.nstates != 1 and X0 == 0:
        X0 = np.zeros(sys.nstates)
    X0 = X0.reshape(-1)
    if X0.size != sys.nstates:
        labels = ", ".join(sys.state_labels) if sys.nstates <= 6 else f"{sys.nstates} states"
        raise ValueError(f"X0 must have {sys.nstates} values ({labels or 'none'}), got {X0.size}")
    if not np.isfinite(X0).all():
        raise ValueError("X0 must be finite")
    check_initial_state(sys, X0)
    n, N = sys.ninputs, T.size
    U = _checks.float_array("U", U)
    if U.ndim == 0 or U.ndim == 1 and U.size == n:
        if not np.isfinite(U).all():  # checked before it is spread over every time point
            raise ValueError("U must be finite")
        # a view: a constant input costs no memory per step
        return T, X0, np.broadcast_to(U.reshape(-1, 1), (n, N))
    elif U.ndim == 1 and n == 1 and U.size == N:
        U = U.reshape(1, N)
    elif U.shape != (n, N):
        raise ValueError(f"U must be a scalar, one value per input ({n}), or an array of "
                         f"shape ({n}, {N}) (inputs by time points), got shape {U.shape}")
    if not np.isfinite(U).all():
        raise ValueError("U must be finite")
    return T, X0, U


def chunk_bounds(n: int, chunks: int) -> np.ndarray:
    """Where ``n`` steps are cut into ``chunks`` near-equal runs (at least one step each).

    Examples
    --------
    >>> chunk_bounds(10, 3).tolist()
    [0, 3, 7, 10]
    >>> chunk_bounds(2, 5).tolist()
    [0, 1, 2]
    """
    return np.linspace(0, n, max(1, min(int(chunks), n)) + 1).round().astype(int)


def recorded_indices(N: int, record_every: int) -> np.ndarray:
    """Indices kept when every ``record_every``-th of ``N`` samples is recorded (and the last).

    Examples
    --------
    >>> recorded_indices(10, 4).tolist()
    [0, 4, 8, 9]
    """
    if isinstance(record_every, bool) or not isinstance(record_every, int | np.integer) \
            or record_every < 1:
        raise ValueError(f"record_every must be an integer >= 1, got {record_every!r}")
    kept = np.arange(0, N, int(record_every))
    return kept if N == 0 or kept[-1] == N - 1 else np.append(kept, N - 1)


def read_only(*arrays) -> tuple:
    """Read-only views of ``arrays``: what ``on_chunk`` is handed, so that a callback does
    not change the run's result by accident (one that sets them writable again does).

    Examples
    --------
    >>> read_only(np.zeros(2))[0].flags.writeable
    False
    """
    views = tuple(np.asarray(a).view() for a in arrays)
    for view in views:
        view.flags.writeable = False
    return views


def response(sys, time, outputs, states, inputs, **overrides) -> ct.TimeResponseData:
    """The :class:`control.TimeResponseData` of a run of ``sys``, as python-control labels it.

    Signal labels from ``sys``, its name, and ``plot_inputs`` only when it has inputs
    (python-control's ``.plot()`` fails on an empty input panel).

    Parameters
    ----------
    sys : control.InputOutputSystem
        The simulated system.
    time : array_like
        Sample times, shape ``(N,)``.
    outputs, states, inputs : numpy.ndarray
        Shapes ``(noutputs, N)``, ``(nstates, N)`` and ``(ninputs, N)``.
    **overrides
        Other keywords of :class:`control.TimeResponseData` (``title``, ``sysname``).

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.nlsys(None, lambda t, x, u, p: u, inputs=1, outputs=1, name="gain")
    >>> resp = response(sys, np.arange(2.0), np.ones((1, 2)), np.zeros((0, 2)), np.ones((1, 2)))
    >>> resp.title, resp.output_labels
    ('Input/output response for gain', ['y[0]'])
    """
    options = dict(output_labels=sys.output_labels, state_labels=sys.state_labels,
                   input_labels=sys.input_labels, sysname=sys.name, issiso=sys.issiso(),
                   title="Input/output response for " + sys.name, plot_inputs=sys.ninputs > 0)
    return ct.TimeResponseData(time, outputs, states, inputs, **{**options, **overrides})


def python_control_arguments(sys, T, U, X0, options):
    """``T, U, X0, t_eval, method, solve_ivp_kwargs`` read as python-control reads them.

    The input may be a list of per-signal parts, broadcast over time; a short initial
    state is padded with zeros (with python-control's warning); ``t_eval`` defaults to
    ``T``. Values python-control runs as they are and the engine does not (complex
    numbers, NaN and infinities, an initial state not of numbers) raise
    :class:`UnsupportedSystem`.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.nlsys(lambda t, x, u, p: -x + u, inputs=2, states=2, outputs=2)
    >>> T, U, X0, t_eval, method, _ = python_control_arguments(
    ...     sys, [0.0, 1.0, 2.0], [1.0, [2.0, 3.0, 4.0]], [1.0, 2.0], {})
    >>> U.tolist(), X0.tolist(), method
    ([[1.0, 1.0, 1.0], [2.0, 3.0, 4.0]], [1.0, 2.0], 'RK45')
    """
    from ..compat import inputs_and_state

    T = np.atleast_1d(np.asarray(T, dtype=float))
    if not np.isfinite(T).all():
        where = int(np.argmax(~np.isfinite(T)))
        raise ValueError(f"T (timepts) must hold finite time points; got {T[where]} at "
                         f"index {where}")
    kwargs = dict(options.get("solve_ivp_kwargs") or {})
    method = options.get("solve_ivp_method") or options.get("method") or kwargs.pop(
        "method", None) or "RK45"
    kwargs.pop("method", None)
    t_eval = options.get("evaluation_times", "T")
    if kwargs.get("t_eval") is not None:
        t_eval = kwargs.pop("t_eval")
    t_eval = T if isinstance(t_eval, str) and t_eval == "T" else np.asarray(t_eval, float)
    if isinstance(U, tuple | list) and len(U) != T.size:
        parts = []
        for i, u in enumerate(U):
            u = _real(np.array(u), "inputs").astype(float, copy=False)
            if u.ndim == 0 or u.ndim == 1 and u.shape[0] != T.shape[0]:
                u = np.outer(u, np.ones_like(T))
            elif not (u.ndim == 1 and u.shape[0] == T.shape[0]
                      or u.ndim == 2 and u.shape[1] == T.shape[0]):
                raise ValueError(f"Input element {i} has inconsistent shape")
            parts.append(u)
        U = np.vstack(parts)
    n = sys.ninputs
    legal = [(T.size,), (1, T.size)] if n is None or n == 1 else [(n, T.size)]
    U, X0 = inputs_and_state(U, legal, X0, sys.nstates)
    U = _real(np.asarray(U), "inputs").astype(float, copy=False).reshape(-1, T.size)
    if sys.nstates == 0:  # (python-control reads X0, None included, and leaves it)
        X0 = np.zeros(0)
    X0 = _real(np.asarray(X0), "initial state")
    if X0.dtype.kind not in "biuf" and not all(  # (None, or a list holding one: python-
            isinstance(v, numbers.Real) for v in X0.ravel().tolist()):  # control's error)
        raise UnsupportedSystem(f"an initial state of {X0.dtype} ({X0.tolist()!r:.40}), not "
                                f"numbers")
    X0 = X0.astype(float, copy=False)
    for name, values in (("X0", X0), ("U", U)):  # (the engine stops on them)
        if not np.isfinite(values).all():
            raise UnsupportedSystem(f"{name} holds {values[~np.isfinite(values)][0]}")
    return T, U, X0, t_eval, method, kwargs


def _real(values: np.ndarray, what: str) -> np.ndarray:
    """``values``, refused when complex: python-control integrates complex numbers as
    they are, where the engine's floats would drop their imaginary parts."""
    if values.dtype.kind == "c":
        raise UnsupportedSystem(f"complex {what} (python-control integrates them as complex "
                                f"numbers)")
    return values


def kept_state(X0, nstates):
    """The dtype other than 64-bit floats that python-control keeps a discrete run's
    initial state in (integers, ``float32``), or None.

    python-control reads a list of integers (``X0=[0, 1]``) or an array as it is (a short
    one is padded with float zeros, a scalar broadcast into floats) and hands it to the
    first step's functions: ``np.zeros_like(x)`` there fills integers, and ``0.9 * x[0]``
    of a ``float32`` state is a ``float32``.

    Examples
    --------
    >>> kept_state([0, 1], 2), kept_state([0, 1.0], 2), kept_state(0, 2)
    (dtype('int64'), None, None)
    >>> kept_state(np.zeros(2, dtype=np.float32), 2)
    dtype('float32')
    """
    if isinstance(X0, list | tuple):
        try:
            values = np.array([v for part in X0 for v in np.ravel(np.array(part))])
        except (TypeError, ValueError):
            return None
    elif isinstance(X0, np.ndarray):
        values = X0.reshape(-1)
    else:
        return None
    from .source.values import narrow  # (the fast engine's, imported when it runs)

    fits = values.size == (nstates or 0) and values.size > 0
    kept = values.dtype.kind in "biu" or values.dtype.kind in "fc" and narrow(values.dtype)
    return values.dtype if fits and kept else None


def result_flags(options) -> dict:
    """The keywords of :class:`control.TimeResponseData` that python-control passes on.

    Examples
    --------
    >>> result_flags({"params": {"k": 1.0}, "transpose": True})["transpose"]
    True
    """
    return {"params": options.get("params"), "transpose": options.get("transpose", False),
            "return_x": options.get("return_states", False),
            "squeeze": options.get("squeeze")}
