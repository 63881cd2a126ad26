"""Running a diagram on the fast engine: compile, then run in chunks or streamed."""

from __future__ import annotations

import control as ct
import numpy as np

from ..contract import (
    UnsupportedSystem,
    check_arguments,
    chunk_bounds,
    python_control_arguments,
    recorded_indices,
    result_flags,
)
from ..contract import response as base_response
from .codegen import evaluation_order, generate
from .diagnose import explain_divergence, explain_failure
from .loader import load
from .tiers import blocks_of


def compile_system(sys, params=None, *, steps=None, start=None):
    """Generate (and compile, with numba) the simulation loop of an interconnect.

    With ``steps`` (the length of the run it is for), a loop not compiled yet runs as
    Python while the runs are short (:data:`COMPILE_AFTER_STEPS`). ``start`` is the run's
    ``(t0, X0, U0)``, where compiled user functions are checked against Python's.

    Raises
    ------
    UnsupportedSystem
        Naming the block that has no kernel, or the algebraic loop.

    Returns
    -------
    run : callable
        ``run(T, X0, U, P, Y, X, status, k0, k1) -> state at k1``.
    blocks : list
        The blocks with their offsets in the stacked state, signals and parameters.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> run, blocks = compile_system(cmg_loop())
    >>> [b.system.name for b in blocks]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    blocks = blocks_of(sys, params, start)
    order = evaluation_order(sys, blocks)
    return load(*generate(sys, blocks, order), steps=steps), blocks


#: Steps simulated per chunk when a run is streamed (bounds the memory of long runs).
STREAM_CHUNK_STEPS = 20_000


def simulate(sys, T, X0, U=0.0, *, params=None, progress=None, chunks=1,
                  record_every=1, on_chunk=None) -> ct.TimeResponseData:
    """Simulate a discrete interconnect of controlkit blocks without python-control's sweeps.

    Same arguments and result as :func:`control.input_output_response` for
    a discrete system (plus ``progress``, ``chunks``, ``record_every`` and
    ``on_chunk`` as in :func:`controlkit.simulation.simulate`). With
    ``record_every > 1`` or ``on_chunk`` the run is streamed: it proceeds in
    chunks of :data:`STREAM_CHUNK_STEPS` steps through fixed buffers, so memory
    does not grow with the horizon.

    Raises
    ------
    UnsupportedSystem
        When a block cannot be compiled (use the python-control path instead).

    Examples
    --------
    >>> from controlkit.studies.spacecraft.scenario import build_loop, initial_attitude
    >>> from controlkit.simulation import initial_state
    >>> loop = build_loop("ideal")
    >>> X0 = initial_state(loop, plant=initial_attitude())
    >>> resp = simulate(loop, np.arange(3) * 0.1, X0)
    >>> resp.outputs.shape
    (10, 3)
    """
    T, X0, U = check_arguments(sys, T, X0, U)  # a lazy TimeGrid stays lazy, U a view
    run, blocks = compile_system(sys, params, steps=T.size, start=(T[0], X0, U[:, 0]))
    streamed = record_every != 1 or on_chunk is not None
    if not streamed:
        T = np.ascontiguousarray(T, dtype=float)
    N = T.size
    P = np.concatenate([b.kernel.params for b in blocks] + [np.zeros(0)])
    kept = recorded_indices(N, record_every)
    if streamed:
        return _stream(sys, run, blocks, T, X0, U, P, kept, on_chunk, progress, params)
    U = np.ascontiguousarray(U)
    Y = np.zeros((sys.noutputs, N))
    X = np.zeros((sys.nstates, N))
    status = np.array([-1, -1])
    bounds = chunk_bounds(N, chunks)
    x = X0
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        x = run(T, x, U, P, Y, X, status, k0, k1)
        if status[0] >= 0:
            explain_failure(sys, blocks, T, X, U, status, params)
        if not np.isfinite(x).all():
            explain_divergence(sys, blocks, T, X, x, k1, U, params)
        if progress is not None:
            progress(k1 / N)
    return base_response(sys, T, Y, X, U)


def _stream(sys, run, blocks, T, x, U, P, kept, on_chunk, progress, params=None):
    """Run the compiled loop chunk by chunk on slices of ``T`` and ``U``; keep ``kept`` only.

    The generated loop indexes its arrays from ``k0``, so each chunk runs on views of
    ``T`` and ``U`` with ``k0 = 0`` into buffers reused from chunk to chunk.
    """
    N = T.size
    step = min(STREAM_CHUNK_STEPS, max(N, 1))
    Yb, Xb = np.zeros((sys.noutputs, step)), np.zeros((sys.nstates, step))
    Y, X = np.zeros((sys.noutputs, kept.size)), np.zeros((sys.nstates, kept.size))
    status = np.array([-1, -1])
    for k0 in range(0, N, step):
        k1 = min(N, k0 + step)
        Tc, Uc = T[k0:k1], np.ascontiguousarray(U[:, k0:k1])
        x = run(Tc, x, Uc, P, Yb, Xb, status, 0, k1 - k0)
        if status[0] >= 0:
            explain_failure(sys, blocks, Tc, Xb, Uc, status, params)
        if not np.isfinite(x).all():
            explain_divergence(sys, blocks, Tc, Xb, x, k1 - k0, Uc, params)
        if on_chunk is not None:
            on_chunk(Tc, Yb[:, :k1 - k0], Xb[:, :k1 - k0])
        mine = (kept >= k0) & (kept < k1)
        Y[:, mine] = Yb[:, kept[mine] - k0]
        X[:, mine] = Xb[:, kept[mine] - k0]
        if progress is not None:
            progress(k1 / N)
    return base_response(sys, T[kept], Y, X, U[:, kept])


def response(sys, T, U, X0, **options) -> ct.TimeResponseData:
    """The fast engine behind :func:`controlkit.input_output_response` (same arguments).

    Raises
    ------
    UnsupportedSystem
        For what the engine does not run (the caller then runs python-control).

    Examples
    --------
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x + u, inputs=1, states=1, outputs=1, dt=1)
    >>> loop = ct.interconnect([sys], inputs="u[0]", outputs="y[0]")
    >>> response(loop, np.arange(3.0), 1.0, 1.0).outputs.tolist()
    [1.0, 1.5, 1.75]
    """
    if not isinstance(sys, ct.InterconnectedSystem) or not sys.isdtime(strict=True):
        raise UnsupportedSystem(f"{sys.name!r} is not a discrete interconnect")
    T, U, X0, t_eval, _, _ = python_control_arguments(sys, T, U, X0, options)
    if t_eval is not T and not np.array_equal(t_eval, T):
        raise UnsupportedSystem("evaluation times other than T")
    resp = simulate(sys, T, X0, U, params=options.get("params"))
    return response_of(sys, resp, options)


def response_of(sys, resp, options) -> ct.TimeResponseData:
    """``resp`` with python-control's result flags (params, transpose, return_x, squeeze)."""
    return base_response(sys, resp.time, resp.outputs, resp.states, resp.inputs,
                         **result_flags(options))
