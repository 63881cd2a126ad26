"""The reference backend: :func:`control.input_output_response`, in chunks.

Chunks only add progress reports: each restarts from the state the previous one
reached, so a discrete system run in chunks gives the numbers of one run, bit for bit.
"""

from __future__ import annotations

import control as ct
import numpy as np

from .contract import chunk_bounds, recorded_indices, response


def simulate(sys, T, X0, U, *, params=None, progress=None, chunks=1, record_every=1,
             on_chunk=None) -> ct.TimeResponseData:
    """Run ``sys`` with :func:`control.input_output_response`, chunk by chunk.

    Arguments as :func:`controlkit.simulation.simulate`, already checked
    (:func:`controlkit.engines.contract.check_arguments`). The whole run is held in
    memory; ``on_chunk`` is called once with all of it, and ``record_every`` keeps
    every ``record_every``-th sample (and the last) of the result.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    >>> simulate(sys, np.arange(4.0), np.ones(1), np.zeros((0, 4)), chunks=2).outputs.tolist()
    [[1.0, 0.5, 0.25, 0.125]]
    """
    kept = None if record_every == 1 else recorded_indices(len(T), record_every)
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
    time, outputs, states, inputs = (np.concatenate(a, axis=-1)
                                     for a in zip(*pieces, strict=True))
    if on_chunk is not None:  # this path holds the whole run anyway
        on_chunk(time, outputs, states)
    if kept is not None:
        time, outputs, states, inputs = (time[kept], outputs[:, kept], states[:, kept],
                                         inputs[:, kept])
    return response(sys, time, outputs, states, inputs)


def simulate_sampled_data(sys, T, X0, U, *, params=None, t_eval=None, method="RK45",
                          solve_ivp_kwargs=None):
    """Run a :class:`~controlkit.sampled_data.SampledDataSystem` in plain Python.

    The reference semantics of a diagram of continuous, discrete and static blocks
    (:mod:`controlkit.sampled_data`), written for clarity: at each instant ``t_k =
    T[0] + k h`` (``h`` the shortest period) the signals are evaluated with the
    discrete blocks that fire computing a fresh output (held until they fire again),
    then the firing blocks update their state, then :func:`scipy.integrate.solve_ivp`
    integrates the continuous blocks from ``t_k`` to ``t_{k+1}`` with the held outputs.
    At an instant the reported state is the one before the update, as python-control
    reports a discrete system; between instants, the updated one. Inputs are
    interpolated linearly between the points of ``T``, as python-control does.

    Parameters
    ----------
    sys : controlkit.sampled_data.SampledDataSystem
    T : numpy.ndarray
        Time points of ``U``, increasing.
    X0 : numpy.ndarray
        Initial state.
    U : numpy.ndarray
        Inputs, shape ``(ninputs, len(T))``.
    params : dict, optional
        As for :func:`control.input_output_response`.
    t_eval : numpy.ndarray, optional
        Where the response is reported (default ``T``), within ``[T[0], T[-1]]``.
    method : str
        :func:`scipy.integrate.solve_ivp`'s method between instants.
    solve_ivp_kwargs : dict, optional
        Further arguments of :func:`scipy.integrate.solve_ivp` (``rtol``, ``atol``,
        ``max_step``, ...).

    Returns
    -------
    control.TimeResponseData

    Examples
    --------
    A continuous integrator under a discrete gain of 0.5 at 1 s: between instants the
    state ramps with the held gain output.

    >>> import control as ct
    >>> from controlkit.sampled_data import interconnect
    >>> plant = ct.ss(0, 1, 1, 0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[-0.5]], dt=1.0, name="gain", inputs="y", outputs="u")
    >>> loop = interconnect([plant, gain], outputs="y")
    >>> T = np.linspace(0.0, 2.0, 5)
    >>> resp = simulate_sampled_data(loop, T, np.ones(1), np.zeros((0, 5)))
    >>> resp.outputs.round(6).tolist()
    [[1.0, 0.75, 0.5, 0.375, 0.25]]
    """
    import scipy.integrate

    t_eval = T if t_eval is None else np.asarray(t_eval, dtype=float)
    kwargs = dict(solve_ivp_kwargs or {})
    sys._update_params(params)
    blocks = _sampled_data_blocks(sys)
    h = sys.base_period
    instants = T[0] + np.arange(int(np.floor((T[-1] - T[0]) / h * (1 + 1e-12))) + 1) * h
    at_instant = _instant_of(t_eval, instants, h)
    held = {}  # discrete block index -> its held output
    x = np.array(X0, dtype=float)
    ninputs = sys.connect_map.shape[0]
    Y = np.zeros((sys.noutputs, t_eval.size))
    X = np.zeros((sys.nstates, t_eval.size))
    Uout = np.zeros((sys.ninputs, t_eval.size))

    def ufun(t):  # python-control's interpolation of the inputs
        idx = np.clip(np.searchsorted(T, t, side="left"), 1, len(T) - 1)
        if len(T) == 1:
            return U[:, 0]
        frac = (t - T[idx - 1]) / (T[idx] - T[idx - 1])
        return U[:, idx - 1] * (1.0 - frac) + U[:, idx] * frac

    def signals(t, x, fresh):
        """Inputs and outputs of every block at ``t`` (python-control's sweep), the
        discrete blocks not in ``fresh`` giving their held output."""
        u = ufun(t)
        ulist = sys.input_map @ u
        ylist = np.zeros(sys.connect_map.shape[1])
        for _ in range(len(blocks) + 1):
            for b in blocks:
                if b.discrete and b.index not in fresh:
                    ylist[b.y] = held[b.index]
                else:
                    ylist[b.y] = np.asarray(b.system._out(t, x[b.x], ulist[b.u]),
                                            dtype=float).reshape(-1)
            new = sys.connect_map @ ylist + sys.input_map @ u
            if np.array_equal(new, ulist):
                return u, ulist, ylist
            ulist = new
        raise RuntimeError(f"algebraic loop in {sys.name!r} at t = {t:g} s")

    def record(j, t, x, fresh):
        u, ulist, ylist = signals(t, x, fresh)
        Y[:, j] = sys.output_map @ np.concatenate([ylist, ulist[:ninputs]])
        X[:, j] = x
        Uout[:, j] = u

    continuous = [b for b in blocks if not b.discrete and b.system.nstates]
    for k, t_k in enumerate(instants):
        firing = {b.index for b in blocks if b.discrete and k % b.every == 0}
        _, ulist, ylist = signals(t_k, x, firing)
        for b in blocks:
            if b.index in firing:
                held[b.index] = ylist[b.y].copy()
        for j in np.nonzero(at_instant == k)[0]:
            record(j, t_k, x, firing)
        for b in blocks:  # the firing blocks update their state
            if b.index in firing and b.system.nstates:
                x[b.x] = b.system._rhs(t_k, x[b.x], ulist[b.u])
        t_next = instants[k + 1] if k + 1 < len(instants) else T[-1]
        inside = np.nonzero((at_instant < 0) & (t_eval > t_k) & (t_eval <= t_next))[0]
        if t_next <= t_k or not continuous:
            for j in inside:
                record(j, t_eval[j], x, set())
            continue
        index = np.concatenate([x_index for b in continuous for x_index in [b.x_index]])

        def rhs(t, xc, index=index):
            xt = x.copy()
            xt[index] = xc
            _, ulist, _ = signals(t, xt, set())
            dx = np.zeros(sys.nstates)
            for b in continuous:
                dx[b.x] = b.system._rhs(t, xt[b.x], ulist[b.u])
            return dx[index]

        sol = scipy.integrate.solve_ivp(rhs, (t_k, t_next), x[index], method=method,
                                        dense_output=bool(inside.size), **kwargs)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed between {t_k:g} s and {t_next:g} s: "
                               f"{sol.message}")
        for j in inside:
            xt = x.copy()
            xt[index] = sol.sol(t_eval[j])
            record(j, t_eval[j], xt, set())
        x[index] = sol.y[:, -1]
    return response(sys, t_eval, Y, X, Uout)


class _Placed:
    """A block of a sampled-data diagram with its slices in the stacked vectors."""

    def __init__(self, index, system, x0, u0, y0, base):
        self.index, self.system = index, system
        self.x = slice(x0, x0 + system.nstates)
        self.x_index = np.arange(x0, x0 + system.nstates)
        self.u = slice(u0, u0 + system.ninputs)
        self.y = slice(y0, y0 + system.noutputs)
        self.discrete = system.isdtime(strict=True) and system.dt is not True
        self.every = round(system.dt / base) if self.discrete else 0


def _sampled_data_blocks(sys):
    blocks, x0, u0, y0 = [], 0, 0, 0
    for i, s in enumerate(sys.syslist):
        blocks.append(_Placed(i, s, x0, u0, y0, sys.base_period))
        x0, u0, y0 = x0 + s.nstates, u0 + s.ninputs, y0 + s.noutputs
    return blocks


def _instant_of(t_eval, instants, h):
    """For each evaluation time, the index of the instant it falls on (within a
    billionth of the period, so that rounding never moves a point across an instant),
    else -1."""
    k = np.rint((t_eval - instants[0]) / h).astype(int)
    on = (k >= 0) & (k < len(instants)) & (
        np.abs(t_eval - instants[0] - k * h) <= 1e-9 * h)
    return np.where(on, k, -1)
