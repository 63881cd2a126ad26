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


def simulate(
    sys, T, X0, U=0.0, *, progress: Callable[[float], None] | None = None, chunks: int = 1,
    engine: str = "python-control", record_every: int = 1,
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
        Initial state.
    U : float or array_like
        Inputs: a constant (scalar or one value per input) or an array
        ``(ninputs, len(T))``.
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
    if engine == "fast":
        from . import engine as fast

        try:
            return fast.simulate_fast(sys, T, X0, U, progress=progress, chunks=chunks,
                                      record_every=record_every, on_chunk=on_chunk)
        except fast.UnsupportedSystem as reason:
            warnings.warn(f"fast engine not used, running python-control instead: {reason}",
                          stacklevel=2)
    T = np.asarray(T, dtype=float)
    U = np.asarray(U, dtype=float)
    chunks = max(1, min(int(chunks), len(T) - 1))
    bounds = np.linspace(0, len(T) - 1, chunks + 1).round().astype(int)
    x = np.asarray(X0, dtype=float)
    pieces = []
    for k in range(chunks):
        i0, i1 = bounds[k], bounds[k + 1]
        Uk = U[..., i0 : i1 + 1] if U.ndim == 2 else U
        resp = ct.input_output_response(sys, T[i0 : i1 + 1], Uk, x, squeeze=False)
        first = 0 if k == 0 else 1  # the previous chunk already holds this sample
        arrays = (resp.time, resp.outputs, resp.states, resp.inputs)
        pieces.append([a[..., first:] for a in arrays])
        x = resp.states[:, -1]
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
    return ct.TimeResponseData(
        time, outputs, states, inputs,
        output_labels=sys.output_labels, state_labels=sys.state_labels,
        input_labels=sys.input_labels, sysname=sys.name, issiso=sys.issiso(),
        title="Input/output response for " + sys.name, plot_inputs=sys.ninputs > 0,
    )

