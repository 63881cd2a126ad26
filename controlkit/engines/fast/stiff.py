"""Stiff methods (``LSODA``, ``BDF``, ``Radau``): scipy's solvers on the compiled diagram.

scipy's implicit solvers are not rewritten here: :func:`run_stiff` calls
:func:`scipy.integrate.solve_ivp` between the instants of the discrete blocks, as
:func:`.loops.continuous_run` does with the compiled explicit methods, with the
diagram's compiled right-hand side (its module's, or the driver's) in place of
python-control's, which sweeps every block in Python at every evaluation.
"""

from __future__ import annotations

import numpy as np
import scipy.integrate

from ..contract import response as base_response
from .instants import _eval_instants, _instants
from .loops import INTEGRATOR_FAILED


def run_stiff(job, T, U, X0, t_eval, method, solver):
    """:func:`.continuous.run_continuous` with one of scipy's stiff methods.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> stiff = ct.ss([[-1000.0]], [[1000.0]], [[1.0]], [[0.0]], name="fast",
    ...               inputs="u", outputs="y")
    >>> loop = ct.interconnect([stiff], inputs="u", outputs="y")
    >>> T = np.linspace(0.0, 1.0, 3)
    >>> resp = run_stiff(prepare(loop), T, np.ones((1, 3)), np.zeros(1), T, "BDF", {})
    >>> bool(abs(resp.outputs[-1] - 1.0) < 1e-3)
    True
    """

    sys, plan = job.sys, job.plan
    functions, plan_args = _compiled_evaluator(job)
    evaluate, outputs, update, rhs = functions
    instants, h = _instants(sys, T[0], T[-1])
    eval_instant = _eval_instants(t_eval, instants, h)
    m, nx = t_eval.size, sys.nstates
    Y, X, Uo = np.zeros((sys.noutputs, m)), np.zeros((nx, m)), np.zeros((sys.ninputs, m))
    ys, ui, held = np.zeros(plan.ny), np.zeros(plan.nu), np.zeros(plan.ny)
    widest = max([1, *plan.table[:, 1].tolist()])
    xn, scratch, xt, dx = np.empty(nx), np.empty(5 * widest), np.empty(nx), np.zeros(nx)
    ubuf = np.empty((U.shape[0], 1))
    cidx = plan.continuous
    x = np.array(X0, dtype=float)
    args = (plan_args, x, xt, cidx, T, U, ubuf, job.P, ys, ui, held, dx)

    def fun(t, y):
        out = np.empty(cidx.size)
        rhs(t, np.ascontiguousarray(y, dtype=float), args, out)
        return out

    def record(j, t, state, fire):
        _interpolate(T, U, t, ubuf)
        failed = evaluate(t, state, ubuf, 0, job.P, ys, ui, held, fire, plan_args)
        if failed >= 0:
            _fail(job, t, failed)
        outputs(ys, ui, Y, j, plan_args)
        X[:, j] = state
        Uo[:, j] = ubuf[:, 0]

    i = 0
    for k, t in enumerate(instants):
        _interpolate(T, U, t, ubuf)
        failed = evaluate(t, x, ubuf, 0, job.P, ys, ui, held, k, plan_args)
        if failed >= 0:
            _fail(job, t, failed)
        while i < m and eval_instant[i] == k:
            outputs(ys, ui, Y, i, plan_args)
            X[:, i], Uo[:, i] = x, ubuf[:, 0]
            i += 1
        update(t, x, ui, job.P, xn, k, plan_args, scratch)
        x[:] = xn
        last = k + 1 == instants.size
        t1 = T[-1] if last else instants[k + 1]
        if not cidx.size or not t1 > t:
            continue
        stop = i
        while stop < m and eval_instant[stop] < 0 and (
                t_eval[stop] < t1 or last and t_eval[stop] <= t1):
            stop += 1
        # the last interval as python-control's one call (the points by t_eval); the
        # others need the state at their end: dense output, points from the interpolant
        sol = scipy.integrate.solve_ivp(fun, (t, t1), x[cidx], method=method,
                                        t_eval=t_eval[i:stop] if last else None,
                                        dense_output=not last, **solver)
        if not sol.success:
            raise RuntimeError(f"{sys.name!r}: {method} failed between t = {t:g} s and "
                               f"{t1:g} s: {sol.message}")
        for j in range(i, stop):
            xt[:] = x
            xt[cidx] = sol.y[:, j - i] if last else sol.sol(t_eval[j])
            record(j, t_eval[j], xt.copy(), -1)
        i = stop
        if not last:
            x[cidx] = sol.y[:, -1]
    return base_response(sys, t_eval, Y, X, Uo)


def _compiled_evaluator(job):
    """``(evaluate, outputs, update, rhs)`` and their plan argument, compiled."""
    from . import loader

    if job.injected:
        ns = loader.load_python(job.source, job.injected)
        return (ns.evaluate, ns.outputs, ns.update, ns.rhs), ()
    module = loader.load(job.source)
    if loader.is_compiled(module.run_discrete) or loader.is_compiled(
            getattr(module, "run_continuous", None)):
        return (module.evaluate, module.outputs, module.update, module.rhs), ()
    generic = loader.driver()
    return (generic.evaluate, generic.outputs, generic.update, generic.rhs), job.generic_plan()


def _interpolate(T, U, t, out):
    idx = min(max(int(np.searchsorted(T, t)), 1), T.size - 1)
    dt = (t - T[idx - 1]) / (T[idx] - T[idx - 1])
    out[:, 0] = U[:, idx - 1] * (1.0 - dt) + U[:, idx] * dt


def _fail(job, t, index):
    from .diagnose import explain_nan

    if index == INTEGRATOR_FAILED:
        raise RuntimeError(f"{job.sys.name!r}: the integration failed at t = {t:g} s")
    explain_nan(job.sys, job.blocks, t, index)
