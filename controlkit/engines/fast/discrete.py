"""Discrete diagrams on the fast engine: python-control's discrete simulation, in pieces.

:func:`simulate` runs a discrete diagram step by step through its module (as Python or
compiled, :mod:`.run`), in pieces of about a tenth of a second, streamed through fixed
buffers when only some samples are kept (a long horizon then needs memory for those
only). Diagrams with continuous states, or of several rates, go to :mod:`.continuous`.
"""

from __future__ import annotations

import control as ct
import numpy as np

from ..contract import (
    UnsupportedSystem,
    check_arguments,
    chunk_bounds,
    read_only,
    recorded_indices,
)
from ..contract import response as base_response
from .diagnose import diverged, explain_failure, sampled_block_blew_up
from .pieces import Pieces, interrupted, now, quiet_numbers, where_they_part
from .run import Runner

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
    pieces, start = Pieces(), now()
    for c0 in range(0, N, step):
        c1 = min(c0 + step, N)
        if on_chunk is not None and c0:  # (the callback may keep the last chunk's arrays)
            Yb, Xb = np.zeros_like(Yb), np.zeros_like(Xb)
        run = _Steps(np.ascontiguousarray(T[c0:c1], dtype=float),
                     np.require(U[:, c0:c1], dtype=float, requirements=["C", "W"]), Yb, Xb, x)
        while run.position < run.times.size:
            k, began, checking = run.position, now(), runner.to_check
            try:
                runner.piece(run, pieces.next())
            except KeyboardInterrupt as stop:
                if streamed:  # the samples kept so far, this chunk's too
                    mine = (kept >= c0) & (kept < c0 + k)
                    Y[:, mine], X[:, mine] = Yb[:, kept[mine] - c0], Xb[:, kept[mine] - c0]
                n = int(np.count_nonzero(kept < c0 + k))
                raise interrupted(stop, base_response(
                    sys, np.asarray(T[kept[:n]], dtype=float), Y[:, :n], X[:, :n],
                    U[:, kept[:n]])) from None
            if not checking:  # (a check runs its piece twice: not the pace of pieces)
                pieces.took(run.position - k, now() - began)
            _said(runner.job, run)
            if not runner.decided:  # (a compiled job chosen: checked on the next piece)
                runner.decide(now() - start, (c0 + run.position) / N)
            if progress is not None:
                for bound in sorted(b for b in reports if b <= c0 + run.position):
                    reports.discard(bound)
                    progress(bound / max(N - 1, 1))
        x = run.x
        if on_chunk is not None:
            on_chunk(*read_only(run.times, Yb[:, :c1 - c0], Xb[:, :c1 - c0]))
        if streamed:
            mine = (kept >= c0) & (kept < c1)
            Y[:, mine], X[:, mine] = Yb[:, kept[mine] - c0], Xb[:, kept[mine] - c0]
    if progress is not None and reports:
        progress(1.0)
    resp = base_response(sys, T[kept] if streamed else np.asarray(T, dtype=float), Y, X,
                         U[:, kept] if streamed else U)
    runner.finished(now() - start)
    resp.engine_mode = runner.mode
    return resp


class _Steps:
    """A chunk of a discrete run (see :func:`simulate`): its times, inputs and results, the
    state ``x`` after its first ``position`` steps, and the status a failing step leaves
    (its step and block); :meth:`.run.Runner.piece` and :meth:`~.run.Runner.check` run it."""

    def __init__(self, times, U, Y, X, x):
        self.times, self.U, self.Y, self.X, self.x, self.position = times, U, Y, X, x, 0
        self.status = np.full(2, -1, dtype=np.int64)

    def piece(self, job, steps):
        k1 = min(self.position + steps, self.times.size)
        args = (self.times, self.x, self.U, job.P, self.Y, self.X, self.status,
                self.position, k1)
        if job.compiled:
            self.x = job.entry("run_discrete", args)(*args)
        else:
            with quiet_numbers():
                self.x = job.functions().run_discrete(*args)
        self.position = k1

    def snapshot(self):
        return [self.x.copy(), np.array([self.position]), self.status.copy()]

    def restore(self, saved):
        self.x, self.position, self.status[:] = saved[0].copy(), int(saved[1][0]), saved[2]

    def stopped(self) -> bool:
        return bool(self.status[0] >= 0 or not np.isfinite(self.x).all())

    def handed_back(self) -> bool:
        return False

    def written(self, n0, n1):
        return [self.Y[:, n0:n1].copy(), self.X[:, n0:n1].copy()]

    def where(self, job, n0, n1, mine, theirs) -> str:
        a, b = self.times[n0], self.times[n1 - 1]
        return (f"at t = {a:g} s" if n1 - n0 == 1 else f"between t = {a:g} and {b:g} s") + \
            where_they_part(job.blocks, self.times[n0:n1], mine[1], theirs[1])

    def put_back(self, written, n0, n1):
        self.Y[:, n0:n1], self.X[:, n0:n1] = written


def _said(job, run) -> None:
    """Raise what stopped ``run``'s last piece, in the words of the block that stopped it."""
    times, X, U, status = run.times, run.X, run.U, run.status
    if status[0] >= 0:
        k = int(status[0])
        _blown_up(job, times, X, U, k, X[:, k])
        explain_failure(job, times[k], X[:, k], U[:, k], status[1])
    if not np.isfinite(run.x).all():
        k = _blown_up(job, times, X, U, run.position, run.x)
        raise diverged(job, times[min(k, times.size - 1)], run.x)


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
