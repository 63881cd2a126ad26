"""Running diagrams: initial states built by block name, and long runs with progress.

Both wrap :func:`control.input_output_response`; the results are ordinary
:class:`control.TimeResponseData`.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import control as ct
import numpy as np


def initial_state(sys, **by_block) -> np.ndarray:
    """State vector of an interconnect, given per block name.

    Blocks not named start from their ``x0`` attribute when they have one
    (controlkit blocks with a natural initial state, such as the FRIT tuner's
    ``P(0) = gamma I``), otherwise from zero.

    Parameters
    ----------
    sys : control.InterconnectedSystem or control.NonlinearIOSystem
        The diagram (or a single block).
    **by_block : array_like
        Initial state of the block with that name.

    Returns
    -------
    numpy.ndarray
        The stacked initial state, in ``sys.state_labels`` order.

    Examples
    --------
    >>> from controlkit.diagrams.spacecraft import output_zeroing_loop
    >>> initial_state(output_zeroing_loop(), plant=[1, 0, 0, 0]).tolist()
    [1.0, 0.0, 0.0, 0.0]
    """
    subsystems = getattr(sys, "syslist", [sys])
    names = {s.name for s in subsystems}
    unknown = set(by_block) - names
    if unknown:
        raise ValueError(
            f"no block named {sorted(unknown)} in {sys.name}; blocks: {sorted(names)}"
        )
    parts = []
    for s in subsystems:
        if s.nstates == 0:
            continue
        value = by_block.get(s.name, getattr(s, "x0", np.zeros(s.nstates)))
        value = np.asarray(value, dtype=float).reshape(-1)
        if value.size != s.nstates:
            raise ValueError(
                f"initial state of block {s.name!r} must have {s.nstates} values "
                f"({s.state_labels}), got {value.size}"
            )
        parts.append(value)
    return np.concatenate(parts) if parts else np.zeros(0)


ENGINES = ("fast", "python-control")


def check_arguments(sys, T, X0, U=0.0):
    """``T``, ``X0`` and ``U`` checked and shaped once, the same way for both engines.

    Parameters
    ----------
    sys : control.InputOutputSystem
        The system they are meant for.
    T, X0, U : array_like
        As for :func:`simulate`.

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
        Naming the argument, what it must be and what it is.

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
    from .sampling import TimeGrid

    discrete = sys.isdtime(strict=True) and sys.dt is not True
    if isinstance(T, TimeGrid):  # a lazy grid stays lazy (long streamed runs)
        if T.size == 0 or not np.isfinite(T.Ts) or T.Ts <= 0:
            raise ValueError(f"T must be a non-empty grid with a positive step, got {T.size} "
                             f"samples of {T.Ts:g}")
        if discrete and T.size > 1 and not np.isclose(T.Ts, sys.dt):
            raise ValueError(f"time steps of T must equal the sampling time {sys.dt} of "
                             f"{sys.name!r}, got steps from {T.Ts:g} to {T.Ts:g}")
    else:
        T = np.asarray(T, dtype=float)
        if T.ndim != 1 or T.size == 0:
            raise ValueError(f"T must be a non-empty 1-D array of time points, "
                             f"got shape {T.shape}")
        if not np.isfinite(T).all():
            raise ValueError("T must hold finite time points")
        steps = np.diff(T)
        if (steps <= 0).any():
            raise ValueError("T must be increasing")
        if discrete and T.size > 1 and not np.allclose(steps, sys.dt):
            raise ValueError(f"time steps of T must equal the sampling time {sys.dt} of "
                             f"{sys.name!r}, got steps from {steps.min():g} to "
                             f"{steps.max():g}")
    X0 = np.asarray(X0 if X0 is not None else 0.0, dtype=float)
    if X0.ndim == 0 and sys.nstates != 1 and X0 == 0:
        X0 = np.zeros(sys.nstates)
    X0 = X0.reshape(-1)
    if X0.size != sys.nstates:
        labels = ", ".join(sys.state_labels) if sys.nstates <= 6 else f"{sys.nstates} states"
        raise ValueError(f"X0 must have {sys.nstates} values ({labels or 'none'}), "
                         f"got {X0.size}")
    if not np.isfinite(X0).all():
        raise ValueError("X0 must be finite")
    n, N = sys.ninputs, T.size
    U = np.asarray(U, dtype=float)
    if U.ndim == 0 or U.ndim == 1 and U.size == n:
        # a view: a constant input costs no memory per step
        U = np.broadcast_to(U.reshape(-1, 1), (n, N))
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


def response(sys, time, outputs, states, inputs, **overrides) -> ct.TimeResponseData:
    """The :class:`control.TimeResponseData` of a run of ``sys``, as python-control labels it.

    Both simulators (and a run pieced together from parts) build their result here, so a
    result looks the same whichever made it: signal labels from ``sys``, its name, and
    ``plot_inputs`` only when it has inputs (``.plot()`` fails on an empty input panel).

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
    options = dict(
        output_labels=sys.output_labels, state_labels=sys.state_labels,
        input_labels=sys.input_labels, sysname=sys.name, issiso=sys.issiso(),
        title="Input/output response for " + sys.name, plot_inputs=sys.ninputs > 0,
    )
    return ct.TimeResponseData(time, outputs, states, inputs, **{**options, **overrides})


def simulate(
    sys, T, X0, U=0.0, *, params=None, progress: Callable[[float], None] | None = None,
    chunks: int = 1, engine: str = "python-control", record_every: int = 1,
    on_chunk: Callable | None = None,
) -> ct.TimeResponseData:
    """Simulate a system, optionally in chunks with progress reports.

    ``engine="python-control"`` runs :func:`control.input_output_response` (the
    reference). ``engine="fast"`` runs :func:`controlkit.engine.simulate_fast`,
    which gives the same response much faster for a discrete interconnect of
    controlkit blocks; a system it cannot compile runs on the python-control
    path with a warning naming the block.

    A discrete system run in chunks gives the same numbers, bit for bit, as one
    run: each chunk restarts from the state the previous one reached.

    Parameters
    ----------
    sys : control.InputOutputSystem
        System to simulate.
    T : array_like
        Time points (for a discrete system, multiples of ``sys.dt``).
    X0 : array_like
        Initial state, exactly ``sys.nstates`` values.
    U : float or array_like
        Inputs: a constant (scalar or one value per input) or an array
        ``(ninputs, len(T))``.
    params : dict, optional
        Parameter values, as for :func:`control.input_output_response`; a key
        no block reads is refused (:func:`controlkit.engine.check_params`).
    progress : callable, optional
        Called with the fraction done (0 < f <= 1) after each chunk.
    chunks : int
        Number of pieces the run is cut into (for progress reports).
    engine : {"python-control", "fast"}
        Which simulator to use (see above).
    record_every : int
        Keep every ``record_every``-th sample (and the last) in the result. On the fast
        engine the run is then streamed through fixed buffers, so a long horizon needs
        memory for the kept samples only.
    on_chunk : callable, optional
        ``on_chunk(time, outputs, states)``, called with every sample exactly once, in
        order, chunk by chunk and at full resolution: for metrics that need every step
        (a maximum, a peak) while only decimated samples are kept.

    Returns
    -------
    control.TimeResponseData
        As :func:`control.input_output_response` with ``return_x=True`` semantics:
        ``.states`` is filled.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    >>> simulate(sys, np.arange(4), [1.0], chunks=2).outputs.tolist()
    [[1.0, 0.5, 0.25, 0.125]]
    """
    if engine not in ENGINES:
        raise ValueError(f"engine must be one of {ENGINES}, got {engine!r}")
    from . import engine as fast

    T, X0, U = check_arguments(sys, T, X0, U)
    fast.check_params(sys, params)
    if engine == "fast":
        try:
            return fast.simulate_fast(sys, T, X0, U, params=params, progress=progress,
                                      chunks=chunks, record_every=record_every,
                                      on_chunk=on_chunk)
        except fast.UnsupportedSystem as reason:
            warnings.warn(f"fast engine not used, running python-control instead: {reason} "
                          f"(controlkit.engine.explain(sys) lists every block's tier)",
                          stacklevel=2)
    bounds = chunk_bounds(len(T) - 1, chunks)  # chunks share their end samples
    x = np.asarray(X0, dtype=float)
    pieces = []
    for k, (i0, i1) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        resp = ct.input_output_response(sys, T[i0 : i1 + 1], U[:, i0 : i1 + 1], x,
                                        params=params, squeeze=False)
        first = 0 if k == 0 else 1  # the previous chunk already holds this sample
        states = resp.x if resp.x is not None else np.zeros((0, resp.time.size))
        arrays = (resp.time, resp.outputs, states, resp.inputs)
        pieces.append([a[..., first:] for a in arrays])
        x = states[:, -1]
        if progress is not None:
            progress(i1 / (len(T) - 1))
    time, outputs, states, inputs = (np.concatenate(a, axis=-1) for a in zip(*pieces, strict=True))
    if on_chunk is not None:  # the reference path holds the whole run anyway
        on_chunk(time, outputs, states)
    if record_every != 1:
        from .engine import recorded_indices

        kept = recorded_indices(time.size, record_every)
        time, outputs, states = time[kept], outputs[:, kept], states[:, kept]
        inputs = inputs[:, kept]
    return response(sys, time, outputs, states, inputs)

