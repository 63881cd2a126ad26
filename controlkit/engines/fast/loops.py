"""The simulation loops, written once for every diagram and both kinds of evaluator.

A loop here is a template: numba pastes it into its caller (``inline="always"``), where
the *evaluator* it is handed is a compile-time constant. There are two evaluators with
the same four functions, and so two callers of each template:

- the generic driver (:mod:`.driver`), whose evaluator reads the diagram from arrays and
  calls the kernels through their addresses: compiled once for every diagram;
- a diagram's own module (:mod:`.codegen`), whose evaluator is the diagram written out
  line by line with the kernels pasted in: compiled per wiring, the fastest.

The evaluator's functions (``plan`` is the driver's tuple of arrays, unused by a
generated evaluator):

``evaluate(t, x, U, col, P, ys, ui, held, k, plan) -> int``
    Every block's output into ``ys`` in evaluation order, each block's inputs into
    ``ui``. The diagram's inputs are ``U[:, col]``. At instant ``k >= 0`` a discrete
    block that fires (``k % every == 0``) computes its output and stores it in
    ``held``, one that does not gives ``held``; between instants (``k < 0``) every
    discrete block gives ``held``. Returns the index of a block whose output is NaN
    (a kernel's failure signal, block contract rule 6), else -1.
``outputs(ys, ui, Y, j, plan)``
    The diagram's outputs into ``Y[:, j]``.
``update(t, x, ui, P, xn, k, plan, scratch)``
    ``xn``: the next state of the discrete and sampled blocks that fire at instant
    ``k`` (a copy of ``x`` elsewhere).
``derivatives(t, x, ui, P, dx, plan)``
    The continuous blocks' right-hand sides into ``dx`` at their states' places.

Semantics (:mod:`controlkit.sampled_data`): at each instant the signals are evaluated
(firing discrete blocks fresh, the others held), the evaluation times on the instant are
recorded (the state before the update, as python-control reports a discrete system),
the firing blocks update, and the continuous states are integrated to the next instant
by :func:`controlkit.engines.fast.rk.solve_interval` (a fresh ``solve_ivp`` per
interval). A diagram with no discrete block has one interval, ``[T[0], T[-1]]``: one
``solve_ivp`` call, as python-control makes.
"""

from __future__ import annotations

import numpy as np

from ..._jit import jit
from . import rk

#: ``status`` codes beyond a block index: the integrator failed (its code in status[2]).
INTEGRATOR_FAILED = -2


@jit(inline=True)
def interpolate(T, U, t, out):
    """``out[:, 0] = u(t)``, linear between the points of ``T`` as python-control does.

    python-control's ``ufun``: the index is ``searchsorted(T, t, "left")`` clipped to
    ``[1, len(T) - 1]``, so times outside ``T`` extrapolate the end segments.

    Examples
    --------
    >>> from controlkit._jit import python_function
    >>> out = np.zeros((1, 1))
    >>> python_function(interpolate)(np.array([0.0, 1.0]), np.array([[0.0, 2.0]]), 0.25,
    ...                              out).tolist()
    [[0.5]]
    """
    n = T.shape[0]
    idx = np.searchsorted(T, t)
    if idx < 1:
        idx = 1
    if idx > n - 1:
        idx = n - 1
    dt = (t - T[idx - 1]) / (T[idx] - T[idx - 1])
    for i in range(U.shape[0]):
        out[i, 0] = U[i, idx - 1] * (1.0 - dt) + U[i, idx] * dt
    return out


@jit(inline=True)
def discrete_run(evaluate, update, outputs, plan, T, x, U, P, Y, X, status, k0, k1, ys,
                 ui, held, xn, scratch):
    """Steps ``k0 .. k1 - 1`` of a discrete diagram (python-control's order); ``x`` in/out.

    At step ``k``: the state is recorded, every output computed (a NaN stops the run with
    ``status = [k, block]``), the diagram's outputs recorded, the states updated.
    """
    nx = x.shape[0]
    for k in range(k0, k1):
        t = T[k]
        for i in range(nx):
            X[i, k] = x[i]
        failed = evaluate(t, x, U, k, P, ys, ui, held, k, plan)
        if failed >= 0:
            status[0] = k
            status[1] = failed
            return
        outputs(ys, ui, Y, k, plan)
        update(t, x, ui, P, xn, k, plan, scratch)
        for i in range(nx):
            x[i] = xn[i]


@jit(inline=True)
def _record(evaluate, outputs, plan, t, x, T, U, ubuf, P, ys, ui, held, j, Y, X, Uo):
    """The diagram at evaluation time ``j`` between instants (discrete outputs held)."""
    interpolate(T, U, t, ubuf)
    failed = evaluate(t, x, ubuf, 0, P, ys, ui, held, -1, plan)
    outputs(ys, ui, Y, j, plan)
    for i in range(x.shape[0]):
        X[i, j] = x[i]
    for i in range(ubuf.shape[0]):
        Uo[i, j] = ubuf[i, 0]
    return failed


@jit(inline=True)
def rhs_template(evaluate, derivatives, t, y, args, out):
    """The continuous states' derivatives at ``(t, y)``: the integrator's right-hand side.

    ``args = (plan, x, xt, cidx, T, U, ubuf, P, ys, ui, held, dx)``: the full state
    ``x`` gives the held discrete states, ``y`` the continuous ones (at ``cidx``).
    """
    plan, x, xt, cidx, T, U, ubuf, P, ys, ui, held, dx = args
    for i in range(x.shape[0]):
        xt[i] = x[i]
    for q in range(cidx.shape[0]):
        xt[cidx[q]] = y[q]
    interpolate(T, U, t, ubuf)
    evaluate(t, xt, ubuf, 0, P, ys, ui, held, -1, plan)
    derivatives(t, xt, ui, P, dx, plan)
    for q in range(cidx.shape[0]):
        out[q] = dx[cidx[q]]


@jit(inline=True)
def continuous_run(evaluate, update, outputs, rhs, machine, plan, rhs_args, times, results,
                   state, buffers, solver, ctrl, status):
    """Instants ``k0 .. k1 - 1`` of a diagram with continuous states; ``x``, ``held`` in/out.

    The arguments come grouped in tuples (Python passes a call of more than 30
    arguments as ``*args``, which numba cannot paste in):
    ``times = (instants, fire0, k0, k1, t_final, T, U, t_eval, eval_instant)``,
    ``results = (Y, X, Uo)``, ``state = (x, P, held)``,
    ``buffers = (ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work)``,
    ``solver = (method, rtol, atol, max_step, first_step, exact)``.
    ``instants[k]`` is the ``k``-th instant (``fire0 + k`` its number for the firing
    rule); after the last one the integration runs to ``t_final``. ``ctrl[0]`` is the
    next evaluation time to serve (in/out). On failure ``status`` is ``[time index,
    block, 0, 0]`` for a NaN output, or ``[time index, INTEGRATOR_FAILED, code, steps]``
    (``steps``: the projected steps of a run stopped as :data:`.rk.STIFF`).
    """
    instants, fire0, k0, k1, t_final, T, U, t_eval, eval_instant = times
    Y, X, Uo = results
    x, P, held = state
    ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work = buffers
    method, rtol, atol, max_step, first_step, exact = solver
    m = t_eval.shape[0]
    nx = x.shape[0]
    nc = cidx.shape[0]
    K = instants.shape[0]
    if k0 < k1:  # the integrator projects its progress over the run (its stiffness test)
        rk.set_horizon(work, instants[k0], t_final)
    for k in range(k0, k1):
        t = instants[k]
        interpolate(T, U, t, ubuf)
        failed = evaluate(t, x, ubuf, 0, P, ys, ui, held, fire0 + k, plan)
        if failed >= 0:
            status[0] = ctrl[0]
            status[1] = failed
            return
        i = ctrl[0]
        while i < m and eval_instant[i] == k:
            outputs(ys, ui, Y, i, plan)
            for q in range(nx):
                X[q, i] = x[q]
            for q in range(ubuf.shape[0]):
                Uo[q, i] = ubuf[q, 0]
            i += 1
        ctrl[0] = i
        update(t, x, ui, P, xn, fire0 + k, plan, scratch)
        for q in range(nx):
            x[q] = xn[q]
        last = k + 1 == K
        t1 = t_final if last else instants[k + 1]
        if nc == 0 or not t1 > t:
            continue
        stop = i  # the evaluation times this interval serves
        while stop < m and eval_instant[stop] < 0 and (
                t_eval[stop] < t1 or last and t_eval[stop] <= t1):
            stop += 1
        for q in range(nc):
            yc[q] = x[cidx[q]]
        code, served = rk.solve_interval(machine, rhs, rhs_args, method, t, t1, yc, rtol,
                                         atol, max_step, first_step, t_eval[:stop], i,
                                         last, y_eval[:stop], yc, work, exact)
        for j in range(i, served):
            for q in range(nx):
                xt[q] = x[q]
            for q in range(nc):
                xt[cidx[q]] = y_eval[j, q]
            failed = _record(evaluate, outputs, plan, t_eval[j], xt, T, U, ubuf, P, ys,
                             ui, held, j, Y, X, Uo)
            if failed >= 0:
                status[0] = j
                status[1] = failed
                return
        ctrl[0] = served
        for q in range(nc):  # on failure: the state where the integrator stopped
            x[cidx[q]] = yc[q]
        if code != rk.SUCCESS:
            status[0] = served
            status[1] = INTEGRATOR_FAILED
            status[2] = code
            status[3] = int(work.floats[rk.PROJECTED_STEPS])
            return
        for q in range(nc):
            x[cidx[q]] = yc[q]
