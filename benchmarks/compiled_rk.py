"""The integrator compiled as one ``solve_ivp`` call, for the benchmarks of the integrator.

``tests/rk_problems.py``'s ``solve_ivp`` runs it as Python (the step machine on arrays,
the right-hand side a Python call): a diagram's module is what runs it compiled. The
benchmarks of the integrator alone need it compiled as a module calls it: a numba
function with the right-hand side a compile-time constant, receiving the step machine
compiled once and kept in the store (:func:`controlkit.engines.fast.store.step_machine`).
"""

from __future__ import annotations

import numpy as np

from controlkit import _jit
from controlkit.engines.fast import rk, store

_SOLVERS: dict = {}


def solver(rhs, linked=False):
    """A compiled ``solve(machine, args, method, t0, t1, y0, rtol, atol, t_eval, y_eval,
    y_end, work)`` integrating ``rhs`` (a :func:`controlkit._jit.jit` function) as
    one ``solve_ivp`` call: the machine received by pointer, or with ``linked`` compiled
    into the caller (``rk.machine``; then ``machine`` is ignored)."""
    key = (rhs, linked)
    if key not in _SOLVERS:
        numba = _jit.numba_module()
        if linked:
            machine_global = rk.machine

            @numba.njit
            def solve(machine, args, method, t0, t1, y0, rtol, atol, t_eval, y_eval, y_end,
                      work):
                return rk.solve_interval(machine_global, rhs, args, method, t0, t1, y0, rtol,
                                         atol, np.inf, 0.0, t_eval, 0, True, y_eval, y_end,
                                         work, 0, False)
        else:
            @numba.njit
            def solve(machine, args, method, t0, t1, y0, rtol, atol, t_eval, y_eval, y_end,
                      work):
                return rk.solve_interval(machine, rhs, args, method, t0, t1, y0, rtol, atol,
                                         np.inf, 0.0, t_eval, 0, True, y_eval, y_end, work,
                                         0, False)
        _SOLVERS[key] = solve
    return _SOLVERS[key]


def solve_ivp(rhs, t_span, y0, method="RK45", t_eval=None, args=(), rtol=1e-3, atol=1e-6,
              linked=False):
    """``tests/rk_problems.py``'s ``solve_ivp``, compiled (same steps, same numbers);
    returns ``y`` (scipy's layout), ``status``, ``n_accepted``, ``nfev``."""
    y0 = np.asarray(y0, dtype=float)
    n = y0.shape[0]
    t_eval = np.zeros(0) if t_eval is None else np.ascontiguousarray(t_eval, dtype=float)
    y_eval = np.full((t_eval.shape[0], n), np.nan)
    work = rk.make_workspace(n, 0, t_eval.shape[0])
    machine = None if linked else store.step_machine()
    status, served = solver(rhs, linked)(
        machine, args, rk.METHOD_INDEX[method], float(t_span[0]), float(t_span[1]), y0,
        float(rtol), np.full(n, float(atol)), t_eval, y_eval, np.empty(n), work)
    return {"y": y_eval[:served].T, "status": int(status),
            "n_accepted": int(work.ints[rk.N_ACCEPTED]), "nfev": int(work.ints[rk.NFEV])}
