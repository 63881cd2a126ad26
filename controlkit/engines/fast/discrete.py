"""Discrete diagrams on the fast engine: python-control's discrete simulation, in pieces.

:func:`simulate` runs a discrete diagram step by step through its module (as Python or
compiled, :mod:`.run`), in pieces of about a tenth of a second, streamed through fixed
buffers when only some samples are kept (a long horizon then needs memory for those
only). Diagrams with continuous states, or of several rates, go to :mod:`.continuous`.
"""

from __future__ import annotations

import control as ct
import numpy as np

from ..contract import UnsupportedSystem, check_arguments, chunk_bounds, recorded_indices
from ..contract import response as base_response
from .diagnose import diverged, explain_failure, sampled_block_blew_up
from .pieces import Pieces, interrupted, now, quiet_numbers, same_numbers, where_they_part
from .run import CHECKED, Runner
from .tiers import NotCompiled

#: Steps simulated per chunk when a run is streamed (bounds the memory of long runs).
STREAM_CHUNK_STEPS = 20_000


def simulate(sys, T, X0, U=0.0, *, params=None, progress=None, chunks=1,
             record_every=1, on_chunk=None, compile=None) -> ct.TimeResponseData:
    """Simulate a diagram as python-control does, on the fast engine.

    Same arguments and result as :func:`control.input_output_response` for a discrete
    system (plus ``progress``, ``chunks``, ``record_every`` and ``on_chunk`` as in
    :func:`controlkit.simulation.simulate`, and ``compile`` as in
    :func:`controlkit.input_output_response`). With ``record_every > 1`` or
    ``on_chunk`` the run is streamed: it proceeds in chunks of
    :data:`STREAM_CHUNK_STEPS` steps through fixed buffers, so memory does not grow
    with the horizon. A diagram with continuous states runs through
    :func:`.continuous.run_continuous` with ``T`` as its evaluation times.

    Raises
    ------
    UnsupportedSystem
        When the diagram cannot run on the fast engine (a single block, a system it does
        not know).
    KeyboardInterrupt
        On Ctrl-C, with the response so far on its ``response`` attribute.

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
    if not isinstance(sys, ct.InterconnectedSystem):
        name = getattr(sys, "name", type(sys).__name__)
        raise UnsupportedSystem(f"{name!r} is a single block; the fast engine runs interconnects")
    T, X0, U = check_arguments(sys, T, X0, U)  # a lazy TimeGrid stays lazy, U a view
    if not sys.isdtime(strict=True):  # continuous states: the instants' loop
        from .continuous import run_continuous

        T = np.asarray(T, dtype=float)
        return run_continuous(sys, T, U, X0, params=params, compile=compile,
                              progress=progress, record_every=record_every,
                              on_chunk=on_chunk)
    N = len(T)
    runner = Runner(sys, params, compile, N)
    kept = recorded_indices(N, record_every)
    streamed = record_every > 1 or on_chunk is not None
    step = STREAM_CHUNK_STEPS if streamed else N
    Y, X = np.zeros((sys.noutputs, kept.size)), np.zeros((sys.nstates, kept.size))
    # (streamed: each chunk written into buffers, its kept samples copied out)
    Yb, Xb = (np.zeros((sys.noutputs, step)), np.zeros((sys.nstates, step))) if streamed \
        else (Y, X)
    reports = set(chunk_bounds(N - 1, chunks)[1:].tolist()) if progress else set()
    x = X0.astype(float)
    pieces, start, done_steps = Pieces(), now(), 0
    first = runner.check_first()  # a compiled module new here: compared on the first piece
    for c0 in range(0, N, step):
        c1 = min(c0 + step, N)
        Tc = np.ascontiguousarray(T[c0:c1], dtype=float)
        Uc = np.require(U[:, c0:c1], dtype=float, requirements=["C", "W"])
        k = 0
        if first is not None:
            k, x = _switch(runner, first, Tc, x, Uc, Yb, Xb, 0, c1 - c0, pieces)
            first = None
        while k < c1 - c0:
            k1 = min(k + pieces.next(), c1 - c0)
            began = now()
            try:
                x = _piece(runner, Tc, x, Uc, Yb, Xb, k, k1)
            except KeyboardInterrupt as stop:
                if streamed:  # the samples kept so far, this chunk's too
                    mine = (kept >= c0) & (kept < c0 + k)
                    Y[:, mine], X[:, mine] = Yb[:, kept[mine] - c0], Xb[:, kept[mine] - c0]
                n = int(np.count_nonzero(kept < c0 + k))
                raise interrupted(stop, base_response(
                    sys, np.asarray(T[kept[:n]], dtype=float), Y[:, :n], X[:, :n],
                    U[:, kept[:n]])) from None
            pieces.took(k1 - k, now() - began)
            done_steps = c0 + k1
            k = k1
            if not runner.decided:
                new = runner.decide(now() - start, done_steps / N)
                if new is not None:
                    k, x = _switch(runner, new, Tc, x, Uc, Yb, Xb, k, c1 - c0, pieces)
                    done_steps = c0 + k
            if progress is not None:
                for bound in sorted(b for b in reports if b <= done_steps):
                    reports.discard(bound)
                    progress(bound / max(N - 1, 1))
        if on_chunk is not None:
            on_chunk(Tc, Yb[:, :c1 - c0], Xb[:, :c1 - c0])
        if streamed:
            mine = (kept >= c0) & (kept < c1)
            Y[:, mine], X[:, mine] = Yb[:, kept[mine] - c0], Xb[:, kept[mine] - c0]
    if progress is not None and reports:
        progress(1.0)
    resp = base_response(sys, T[kept] if streamed else np.asarray(T, dtype=float), Y, X,
                         U[:, kept] if streamed else U)
    runner.finished(now() - start)
    resp.engine_mode = "compiled" if runner.compiled else "python"
    return resp


def _run(job, args):
    """``job``'s ``run_discrete`` on ``args``: its compiled entry or its Python one."""
    if job.compiled:
        return job.entry("run_discrete", args)(*args)
    with quiet_numbers():
        return job.functions().run_discrete(*args)


def _piece(runner, T, x, U, Y, X, k0, k1):
    """Steps ``k0 .. k1 - 1``: the state after them (failures explained)."""
    job = runner.job
    status = np.full(2, -1, dtype=np.int64)
    args = (T, x, U, job.P, Y, X, status, k0, k1)
    try:
        x1 = _run(job, args)
    except NotCompiled as why:  # numba's compile failed: the run is Python's
        runner.python_from_now(str(why))
        return _piece(runner, T, x, U, Y, X, k0, k1)
    except Exception:
        if not job.compiled:
            raise
        # compiled code stopped (an index out of range, a parameter missing): the same
        # steps as Python raise Python's own error, with the block and the time
        x1 = _replay(runner, T, x, U, Y, X, status, k0, k1)
    else:  # a NaN, or a state gone non-finite: Python's error, or Python's numbers
        if job.compiled and (status[0] >= 0 or not np.isfinite(x1).all()):
            x1 = _replay(runner, T, x, U, Y, X, status, k0, k1)
    job = runner.job
    if status[0] >= 0:
        k = int(status[0])
        _blown_up(job, T, X, U, k, X[:, k])
        explain_failure(job, T[k], X[:, k], U[:, k], status[1])
    if not np.isfinite(x1).all():
        k = _blown_up(job, T, X, U, k1, x1)
        raise diverged(job, T[min(k, T.size - 1)], x1)
    return x1


def _blown_up(job, T, X, U, k, x):
    """The first step whose state is non-finite, up to step ``k`` (whose state is ``x``):
    a sampled block that blew up there from a finite state says so itself (raises)."""
    states = np.column_stack([X[:, :k], x])
    bad = np.nonzero(~np.isfinite(states).all(axis=0))[0]
    first = int(bad[0]) if bad.size else k
    if bad.size and first >= 1:
        sampled_block_blew_up(job, T[first - 1], X[:, first - 1], U[:, first - 1],
                              first - 1, states[:, first])
    return first


def _replay(runner, T, x, U, Y, X, status, k0, k1):
    """Run steps ``k0 .. k1 - 1`` as Python (from ``x``); from then on the run is Python.

    A compiled piece that stopped is run again as Python: Python's error is raised from
    here if there is one; if there is none, Python's numbers stand and the run goes on
    as Python (compiled code and Python part ways here, and Python is the meaning)."""
    runner.compiled = None
    status[:] = -1
    return _run(runner.python, (T, x, U, runner.python.P, Y, X, status, k0, k1))


def _switch(runner, job, T, x, U, Y, X, k, n, pieces):
    """Compile ``job`` and check it against Python on the next piece; returns where the
    run stands after that piece ``(k, x)``, compiled from then on if they agree."""
    k1 = min(k + pieces.next(), n)
    if k1 <= k:
        return k, x
    status = np.full(2, -1, dtype=np.int64)
    x_python = _run(runner.python, (T, x, U, runner.python.P, Y, X, status, k, k1))
    Yp, Xp = Y[:, k:k1].copy(), X[:, k:k1].copy()
    if status[0] >= 0 or not np.isfinite(x_python).all():
        # Python stopped or diverged in this piece: said by the piece run again
        runner.decided = True
        return k, x
    args = (T, x, U, job.P, Y, X, np.full(2, -1, dtype=np.int64), k, k1)
    try:
        x_compiled = job.entry("run_discrete", args)(*args)
    except NotCompiled as why:
        Y[:, k:k1], X[:, k:k1] = Yp, Xp
        runner.python_from_now(str(why))
        return k1, x_python
    except Exception as error:  # noqa: BLE001 - the run goes on as Python
        runner.differs(job, f"its compiled module failed ({type(error).__name__}: {error})")
        Y[:, k:k1], X[:, k:k1] = Yp, Xp
        return k1, x_python
    if not (same_numbers(Y[:, k:k1], Yp) and same_numbers(X[:, k:k1], Xp)):
        runner.differs(job, f"its compiled numbers differ from Python's between t = "
                            f"{T[k]:g} and {T[k1 - 1]:g} s"
                            + where_they_part(job.blocks, T[k:k1], X[:, k:k1], Xp))
        Y[:, k:k1], X[:, k:k1] = Yp, Xp
        return k1, x_python
    runner.compiled = job
    CHECKED.add(job.source)
    return k1, x_compiled
