"""The generic driver: one compiled loop for every diagram, the diagram given as data.

The evaluator here (see :mod:`.loops` for the four functions) reads the diagram from a
:class:`.plan.Plan`'s arrays and calls each kernel through the address of its entry
(:mod:`.entries`), with borrowed views (:mod:`.views`). Its argument types never change,
so it is compiled once, cached on disk, and every newly wired diagram runs compiled from
its first call; a diagram's own module (:mod:`.codegen`) is faster per step and replaces
it once compiled. The arithmetic is the generated module's, operation for operation, so
both give the same numbers.

Without numba the driver is not used (the generated module runs as Python instead).

numba's disk cache knows a function by its own file only, and this driver pastes in the
loops and the integrator from other modules: the engine therefore runs a copy of this
module named after the sources of all of them (:func:`.loader.driver`), so that an edit
of any of them compiles a new driver. Its imports are absolute for that reason.
"""

from __future__ import annotations

import numpy as np

from controlkit import _jit
from controlkit.engines.fast import loops, rk
from controlkit.engines.fast.plan import (
    CONTINUOUS,
    DISCRETE,
    EVERY,
    FT,
    KIND,
    NP,
    NU,
    NX,
    NY,
    OUT,
    P0,
    SAMPLED,
    SUB,
    U0,
    UPD,
    X0,
    Y0,
)
from controlkit.engines.fast.views import borrow

jit = _jit.jit

if _jit.HAVE_NUMBA:
    from numba import types
    from numba.core import cgutils
    from numba.extending import intrinsic

    from controlkit.engines.fast.entries import ENTRY_SIGNATURE

    _ENTRY_TYPE = types.FunctionType(ENTRY_SIGNATURE)

    @intrinsic
    def _entry_at(typingctx, address):
        """The entry compiled at ``address``, as a function value the loop can call."""
        if not isinstance(address, types.Integer):
            return None

        def codegen(context, builder, signature, args):
            value = cgutils.create_struct_proxy(_ENTRY_TYPE)(context, builder)
            value.c_addr = context.get_constant_null(types.voidptr)
            value.py_addr = context.get_constant_null(types.voidptr)
            value.jit_addr = builder.inttoptr(args[0], context.get_value_type(types.voidptr))
            return value._getvalue()

        return _ENTRY_TYPE(address), codegen
else:  # never called without numba: the engine runs the generated module as Python
    def _entry_at(address):
        raise RuntimeError("the generic driver needs numba")


def plan_arguments(plan, addresses) -> tuple:
    """The tuple of arrays the driver's evaluator reads (its ``plan`` argument).

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> p = prepare(cmg_loop()).plan
    >>> len(plan_arguments(p, np.zeros(len(p.kernels), dtype=np.int64)))
    11
    """
    return (plan.table, plan.h, plan.order, *plan.inputs, *plan.outputs,
            np.asarray(addresses, dtype=np.int64), plan.continuous)


@jit
def _gather(b, table, ys, U, col, ui, ptr, cols, gain):
    """Block ``b``'s inputs: ``ui = connect_map ys + input_map U[:, col]`` (its rows)."""
    ny = ys.shape[0]
    for r in range(table[b, U0], table[b, U0] + table[b, NU]):
        s = 0.0
        for q in range(ptr[r], ptr[r + 1]):
            c = cols[q]
            s += gain[q] * (ys[c] if c < ny else U[c - ny, col])
        ui[r] = s


@jit
def evaluate(t, x, U, col, P, ys, ui, held, k, plan):
    """The evaluator's ``evaluate`` (see :mod:`.loops`), from the plan's arrays.

    Examples
    --------
    See :func:`run_discrete`, which calls it.
    """
    table, _, order, ptr, cols, gain = plan[0], plan[1], plan[2], plan[3], plan[4], plan[5]
    addresses = plan[9]
    for j in range(order.shape[0]):
        b = order[j]
        if table[b, FT]:
            _gather(b, table, ys, U, col, ui, ptr, cols, gain)
        y0, ny = table[b, Y0], table[b, NY]
        held_here = table[b, KIND] == DISCRETE or table[b, KIND] == SAMPLED
        if held_here and not (k >= 0 and k % table[b, EVERY] == 0):
            for q in range(ny):
                ys[y0 + q] = held[y0 + q]
            continue
        f = _entry_at(addresses[table[b, OUT]])
        f(t, borrow(x, table[b, X0], table[b, NX]), borrow(ui, table[b, U0], table[b, NU]),
          borrow(P, table[b, P0], table[b, NP]), borrow(ys, y0, ny))
        if ny > 0 and np.isnan(ys[y0]):
            return b
        if held_here:
            for q in range(ny):
                held[y0 + q] = ys[y0 + q]
    for b in range(table.shape[0]):
        if not table[b, FT]:
            _gather(b, table, ys, U, col, ui, ptr, cols, gain)
    return -1


@jit
def outputs(ys, ui, Y, j, plan):
    """The evaluator's ``outputs``: the diagram's outputs into ``Y[:, j]``.

    Examples
    --------
    See :func:`run_discrete`, which calls it.
    """
    ptr, cols, gain = plan[6], plan[7], plan[8]
    ny = ys.shape[0]
    for r in range(Y.shape[0]):
        s = 0.0
        for q in range(ptr[r], ptr[r + 1]):
            c = cols[q]
            s += gain[q] * (ys[c] if c < ny else ui[c - ny])
        Y[r, j] = s


@jit
def update(t, x, ui, P, xn, k, plan, scratch):
    """The evaluator's ``update``: discrete updates and RK4 steps of the firing blocks.

    The RK4 steps are :func:`controlkit.kernels.common.rk4_step`'s, operation for
    operation.

    Examples
    --------
    See :func:`run_discrete`, which calls it.
    """
    table, h_of, addresses = plan[0], plan[1], plan[9]
    for i in range(x.shape[0]):
        xn[i] = x[i]
    for b in range(table.shape[0]):
        kind, n = table[b, KIND], table[b, NX]
        if table[b, UPD] < 0 or n == 0 or not (kind == DISCRETE or kind == SAMPLED):
            continue
        if not (k >= 0 and k % table[b, EVERY] == 0):
            continue
        f = _entry_at(addresses[table[b, UPD]])
        x0 = table[b, X0]
        xb, ub = borrow(x, x0, n), borrow(ui, table[b, U0], table[b, NU])
        pb = borrow(P, table[b, P0], table[b, NP])
        if kind == DISCRETE:
            f(t, xb, ub, pb, borrow(xn, x0, n))
            continue
        h = h_of[b]
        k1, k2, k3 = borrow(scratch, 0, n), borrow(scratch, n, n), borrow(scratch, 2 * n, n)
        k4, xt, xs = borrow(scratch, 3 * n, n), borrow(scratch, 4 * n, n), borrow(xn, x0, n)
        for i in range(table[b, SUB]):
            ts = t + i * h
            f(ts, xs, ub, pb, k1)
            for q in range(n):
                xt[q] = xs[q] + (h / 2) * k1[q]
            f(ts + h / 2, xt, ub, pb, k2)
            for q in range(n):
                xt[q] = xs[q] + (h / 2) * k2[q]
            f(ts + h / 2, xt, ub, pb, k3)
            for q in range(n):
                xt[q] = xs[q] + h * k3[q]
            f(ts + h, xt, ub, pb, k4)
            for q in range(n):
                xs[q] = xs[q] + (h / 6) * (k1[q] + 2 * k2[q] + 2 * k3[q] + k4[q])


@jit
def derivatives(t, x, ui, P, dx, plan):
    """The evaluator's ``derivatives``: the continuous blocks' right-hand sides.

    Examples
    --------
    See :func:`run_continuous`, which calls it.
    """
    table, addresses = plan[0], plan[9]
    for b in range(table.shape[0]):
        if table[b, KIND] != CONTINUOUS:
            continue
        f = _entry_at(addresses[table[b, UPD]])
        x0, n = table[b, X0], table[b, NX]
        f(t, borrow(x, x0, n), borrow(ui, table[b, U0], table[b, NU]),
          borrow(P, table[b, P0], table[b, NP]), borrow(dx, x0, n))


@jit
def rhs(t, y, args, out):
    """The integrator's right-hand side (:func:`.loops.rhs_template` of this evaluator).

    Examples
    --------
    See :func:`run_continuous`, which calls it.
    """
    loops.rhs_template(evaluate, derivatives, t, y, args, out)


@jit
def _sizes(table):
    ny, nu, widest = 0, 0, 1
    for b in range(table.shape[0]):
        ny += table[b, NY]
        nu += table[b, NU]
        widest = max(widest, table[b, NX])
    return ny, nu, widest


if _jit.HAVE_NUMBA:
    import numba as _numba

    _entry_point = _numba.njit(cache=True, nogil=True)
else:
    def _entry_point(function):
        return function


@_entry_point
def run_discrete(T, X0, U, P, Y, X, status, k0, k1, plan):
    """Steps ``k0 .. k1 - 1`` of a discrete diagram; returns the state at ``k1``.

    The loop is :func:`.loops.discrete_run`; ``plan`` is :func:`plan_arguments`.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    >>> loop = ct.interconnect([sys], outputs="y[0]")
    >>> job = prepare(loop)
    >>> Y, X = np.zeros((1, 3)), np.zeros((1, 3))
    >>> run_discrete(np.arange(3.0), np.ones(1), np.zeros((0, 3)), job.P, Y, X,
    ...              np.full(3, -1), 0, 3, job.generic_plan()).tolist()
    [0.125]
    >>> Y.tolist()
    [[1.0, 0.5, 0.25]]
    """
    table = plan[0]
    ny, nu, widest = _sizes(table)
    x = X0.copy()
    ys, ui, held = np.zeros(ny), np.zeros(nu), np.zeros(ny)
    xn, scratch = np.empty(x.shape[0]), np.empty(5 * widest)
    loops.discrete_run(evaluate, update, outputs, plan, T, x, U, P, Y, X, status, k0, k1,
                       ys, ui, held, xn, scratch)
    return x


@_entry_point
def run_continuous(machine, instants, fire0, k0, k1, t_final, T, U, t_eval, eval_instant,
                   ctrl, Y, X, Uo, x, held, P, method, rtol, atol, max_step, first_step, exact,
                   status, plan):
    """Instants ``k0 .. k1 - 1`` of a diagram with continuous states (:mod:`.loops`).

    ``x`` and ``held`` are updated in place; see :func:`.loops.continuous_run`.
    ``machine`` is the integrator's step machine as a function value
    (:func:`controlkit.engines.fast.rk.machine_function`).

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.engines.fast.continuous import run_continuous as run
    >>> plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="p", inputs="u",
    ...               outputs="y")
    >>> loop = ct.interconnect([plant], inputs="u", outputs="y")
    >>> T = np.linspace(0, 1, 3)
    >>> resp = run(prepare(loop), T, np.ones((1, 3)), np.zeros(1), generic=True)
    >>> resp.outputs.round(5).tolist()
    [0.0, 0.39349, 0.63211]
    """
    table, cidx = plan[0], plan[10]
    ny, nu, widest = _sizes(table)
    nx, nc, m = x.shape[0], cidx.shape[0], t_eval.shape[0]
    ys, ui = np.zeros(ny), np.zeros(nu)
    xn, scratch, xt, dx = np.empty(nx), np.empty(5 * widest), np.empty(nx), np.zeros(nx)
    yc, y_eval = np.empty(nc), np.empty((m, nc))
    ubuf = np.empty((U.shape[0], 1))
    work = rk.make_workspace(nc, 0, m)
    args = (plan, x, xt, cidx, T, U, ubuf, P, ys, ui, held, dx)
    loops.continuous_run(
        evaluate, update, outputs, rhs, machine, plan, args,
        (instants, fire0, k0, k1, t_final, T, U, t_eval, eval_instant), (Y, X, Uo),
        (x, P, held), (ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work),
        (method, rtol, atol, max_step, first_step, exact), ctrl, status)


if _jit.HAVE_NUMBA:
    _parallel_entry = _numba.njit(cache=True, nogil=True, parallel=True)
    _prange = _numba.prange
else:
    _parallel_entry, _prange = _entry_point, range


@_parallel_entry
def run_discrete_many(T, X0s, U, Ps, Ys, Xs, statuses, plan):
    """One discrete run per row of ``X0s`` and ``Ps``, spread over the threads.

    Run ``r`` is :func:`run_discrete` from ``X0s[r]`` with the parameters ``Ps[r]`` into
    ``Ys[r]``, ``Xs[r]`` and ``statuses[r]``; each run has buffers of its own, so the
    runs are independent and each gives the numbers of a run of its own.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    >>> job = prepare(ct.interconnect([sys], outputs="y[0]"))
    >>> Ys, Xs = np.zeros((2, 1, 3)), np.zeros((2, 1, 3))
    >>> run_discrete_many(np.arange(3.0), np.array([[1.0], [2.0]]), np.zeros((0, 3)),
    ...                   np.zeros((2, 0)), Ys, Xs, np.full((2, 3), -1), job.generic_plan())
    >>> Ys[:, 0, :].tolist()
    [[1.0, 0.5, 0.25], [2.0, 1.0, 0.5]]
    """
    table = plan[0]
    ny, nu, widest = _sizes(table)
    for r in _prange(X0s.shape[0]):
        x = X0s[r].copy()
        ys, ui, held = np.zeros(ny), np.zeros(nu), np.zeros(ny)
        xn, scratch = np.empty(x.shape[0]), np.empty(5 * widest)
        loops.discrete_run(evaluate, update, outputs, plan, T, x, U, Ps[r], Ys[r], Xs[r],
                           statuses[r], 0, T.shape[0], ys, ui, held, xn, scratch)


@_parallel_entry
def run_continuous_many(machine, instants, t_final, T, U, t_eval, eval_instant, Ys, Xs, Uos,
                        X0s, Ps, method, rtol, atol, max_step, first_step, statuses, plan):
    """One run of :func:`run_continuous` per row of ``X0s`` and ``Ps``, over the threads.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast import rk
    >>> from controlkit.engines.fast.run import prepare
    >>> plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="p", inputs="u",
    ...               outputs="y")
    >>> job = prepare(ct.interconnect([plant], inputs="u", outputs="y"))
    >>> T = np.linspace(0.0, 1.0, 3)
    >>> Ys, Xs, Uos = np.zeros((2, 1, 3)), np.zeros((2, 1, 3)), np.zeros((2, 1, 3))
    >>> run_continuous_many(rk.machine_function(), T[:1], 1.0, T, np.ones((1, 3)), T,
    ...                     np.array([0, -1, -1]), Ys, Xs, Uos, np.array([[0.0], [1.0]]),
    ...                     np.tile(job.P, (2, 1)), 1, 1e-3, np.full(1, 1e-6), np.inf, 0.0,
    ...                     np.full((2, 3), -1), job.generic_plan())
    >>> Ys[:, 0, -1].round(4).tolist()
    [0.6321, 1.0]
    """
    table, cidx = plan[0], plan[10]
    ny, nu, widest = _sizes(table)
    nx, nc, m = X0s.shape[1], cidx.shape[0], t_eval.shape[0]
    for r in _prange(X0s.shape[0]):
        x = X0s[r].copy()
        held, ys, ui = np.zeros(ny), np.zeros(ny), np.zeros(nu)
        xn, scratch, xt, dx = np.empty(nx), np.empty(5 * widest), np.empty(nx), np.zeros(nx)
        yc, y_eval = np.empty(nc), np.empty((m, nc))
        ubuf = np.empty((U.shape[0], 1))
        work = rk.make_workspace(nc, 0, m)
        ctrl = np.zeros(1, dtype=np.int64)
        P = Ps[r]
        args = (plan, x, xt, cidx, T, U, ubuf, P, ys, ui, held, dx)
        loops.continuous_run(
            evaluate, update, outputs, rhs, machine, plan, args,
            (instants, 0, 0, instants.shape[0], t_final, T, U, t_eval, eval_instant),
            (Ys[r], Xs[r], Uos[r]), (x, P, held),
            (ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work),
            (method, rtol, atol, max_step, first_step, True), ctrl, statuses[r])
