"""The reference backend: :func:`control.input_output_response`, in chunks.

Chunks only add progress reports: a discrete system's each restart from the state the
previous one reached, so it gives the numbers of one run, bit for bit; a continuous
system runs in one piece (a restarted solver would take other steps: other numbers than
the fast engine's, which integrates the whole horizon), its progress reported at its end.
A sampled-data diagram, which python-control cannot run, runs on
:func:`simulate_sampled_data`.
"""

from __future__ import annotations

from types import SimpleNamespace

import control as ct
import numpy as np

from .._checks import Diverged
from ..compat import SYSTEM_CALLS
from .contract import chunk_bounds, read_only, recorded_indices, response


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
    from ..sampled_data import SampledDataSystem  # (imported with the diagram's build)

    kept = None if record_every == 1 else recorded_indices(len(T), record_every)
    T = np.asarray(T, dtype=float)
    if isinstance(sys, SampledDataSystem):
        run = simulate_sampled_data(sys, T, X0, U, params=params)
        time, outputs, states, inputs = run.t, run.y, run.x, run.u
        if progress is not None:
            progress(1.0)
    else:
        time, outputs, states, inputs = _in_chunks(
            sys, T, X0, U, params, progress, chunks if sys.isdtime(strict=True) else 1)
    _stop_if_not_finite(sys, time, outputs, states)
    if on_chunk is not None:  # this path holds the whole run anyway
        on_chunk(*read_only(time, outputs, states))
    if kept is not None:
        time, outputs, states, inputs = (time[kept], outputs[:, kept], states[:, kept],
                                         inputs[:, kept])
    return response(sys, time, outputs, states, inputs)


def _stop_if_not_finite(sys, time, outputs, states) -> None:
    """:class:`~controlkit._checks.Diverged` where a state or an output of a diagram's run
    became NaN or infinite, as the fast engine stops there (a system alone answers as
    python-control's does on both engines: ``sin(t) / t`` is NaN at 0 by design)."""
    bad = ~(np.isfinite(states).all(axis=0) & np.isfinite(outputs).all(axis=0))
    if bad.any() and getattr(sys, "syslist", None) is not None:
        k = int(np.argmax(bad))
        labels = [label for label, value in zip(sys.state_labels + sys.output_labels,
                                                np.concatenate([states[:, k], outputs[:, k]]),
                                                strict=True) if not np.isfinite(value)]
        error = Diverged(f"{', '.join(labels[:3])} of {sys.name!r} became non-finite at "
                         f"t = {time[k]:g} s (the loop diverged, or a block's equation is "
                         f"undefined there)")
        error.time = float(time[k])
        raise error


def _in_chunks(sys, T, X0, U, params, progress, chunks):
    """``time, outputs, states, inputs`` of python-control's run of ``sys`` in ``chunks``."""
    bounds = chunk_bounds(len(T) - 1, chunks)  # chunks share their end samples
    x = np.asarray(X0, dtype=float)
    pieces = []
    for k, (i0, i1) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        with SYSTEM_CALLS:
            resp = ct.input_output_response(sys, T[i0 : i1 + 1], U[:, i0 : i1 + 1], x,
                                            params=params, squeeze=False)
        first = 0 if k == 0 else 1  # the previous chunk already holds this sample
        states = resp.x if resp.x is not None else np.zeros((0, resp.time.size))
        arrays = (resp.time, resp.outputs, states, resp.inputs)
        pieces.append([a[..., first:] for a in arrays])
        x = states[:, -1]
        if progress is not None:
            progress(i1 / max(len(T) - 1, 1))
    return (np.concatenate(a, axis=-1) for a in zip(*pieces, strict=True))


def simulate_sampled_data(sys, T, X0, U, *, params=None, t_eval=None, method="RK45",
                          solve_ivp_kwargs=None):
    """Run a :class:`~controlkit.sampled_data.SampledDataSystem` in plain Python.

    The reference semantics of a diagram of continuous, discrete and static blocks
    (docs/sampled-data.md, *Semantics*): the instants' loop every engine runs
    (:func:`controlkit.engines.fast.loops.continuous_run`), here as Python, with each
    block computed by its own python-control functions (``output`` and ``dynamics``) in
    python-control's sweep (every block's output again until the signals settle),
    and :func:`scipy.integrate.solve_ivp` between instants.

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
        ``rtol``, ``atol``, ``max_step``, ``first_step`` of
        :func:`scipy.integrate.solve_ivp`.

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
    from .fast.continuous import _Run
    from .fast.loops import scipy_loop

    sweep = _Sweep(sys, params)
    run = _Run(sys, sweep, np.asarray(T, dtype=float), U, X0,
               np.asarray(T if t_eval is None else t_eval, dtype=float), method,
               solve_ivp_kwargs or {})
    # (scipy's solve_ivp between instants, under numpy's error mode as the caller set it)
    with SYSTEM_CALLS:  # (python-control's systems keep a call's params on themselves)
        scipy_loop(sweep.evaluate, sweep.update, sweep.outputs, sweep.derivatives, None,
                   *run.loop_arguments(None, method))
    return response(sys, run.times, run.Y, run.X, run.Uo)


class _Sweep:
    """The evaluator of :mod:`controlkit.engines.fast.loops` made of python-control's own
    block functions, in python-control's sweep: every block's output, again and again,
    until the signals settle (no order known beforehand)."""

    def __init__(self, sys, params):
        from .fast.tiers import _local_params

        self.sys = sys
        self.blocks, xs, us, ys = [], 0, 0, 0
        for s in sys.syslist:
            local = (None if isinstance(s, ct.StateSpace)  # (python-control's LTI takes none)
                     else _local_params(sys, s, params))
            discrete = s.isdtime(strict=True) and s.dt is not True
            every = round(s.dt / sys.base_period) if discrete else 0
            self.blocks.append((s, slice(xs, xs + s.nstates), slice(us, us + s.ninputs),
                                slice(ys, ys + s.noutputs), local, every))
            xs, us, ys = xs + s.nstates, us + s.ninputs, ys + s.noutputs
        # (what the run's arrays are made from, as of a plan: fast.continuous._Run)
        self.ny, self.nu, self.calls_users = ys, us, False
        self.rows = [SimpleNamespace(NX=s.nstates) for s in sys.syslist]
        self.continuous = np.array([i for s, xi, *_ , every in self.blocks if not every
                                    for i in range(xi.start, xi.stop)], dtype=np.int64)

    def evaluate(self, t, x, U, col, P, ys, ui, held, k):
        sys, u = self.sys, U[:, col]
        ulist = np.dot(sys.input_map, u)  # (python-control's products, to the zero's sign)
        for _ in range(len(self.blocks) + 1):
            for s, xi, ui_, yi, local, every in self.blocks:
                fresh = not every or (k >= 0 and k % every == 0)
                ys[yi] = (np.asarray(s.output(t, x[xi], ulist[ui_], local), dtype=float)
                          .reshape(-1) if fresh else held[yi])
                if every and fresh:
                    held[yi] = ys[yi]
            new = sys.connect_map @ ys + np.dot(sys.input_map, u)
            if np.array_equal(new, ulist):
                ui[:] = ulist
                return -1
            ulist = new
        raise RuntimeError(f"algebraic loop in {sys.name!r} at t = {t:g} s")

    def outputs(self, ys, ui, Y, j):
        Y[:, j] = self.sys.output_map @ np.concatenate([ys, ui])

    def update(self, t, x, ui, P, xn, k, scratch):
        xn[:] = x
        for s, xi, ui_, _, local, every in self.blocks:
            if every and s.nstates and k >= 0 and k % every == 0:
                xn[xi] = s.dynamics(t, x[xi], ui[ui_], local)

    def derivatives(self, t, x, ui, P, dx):
        for s, xi, ui_, _, local, every in self.blocks:
            if not every and s.nstates:
                dx[xi] = s.dynamics(t, x[xi], ui[ui_], local)
