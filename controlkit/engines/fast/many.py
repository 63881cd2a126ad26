"""Many runs of one diagram in one compiled call, over all cores.

A sweep over a diagram's parameters or initial states runs the same compiled code with
other numbers: :func:`run_many` packs each run's parameters (users' functions are
compiled once for the types of their parameters, so the runs share their kernels) and
hands all runs to the driver's parallel entry points (:func:`.driver.run_discrete_many`,
:func:`.driver.run_continuous_many`), each run with buffers of its own, spread over
numba's threads. A run whose parameters change a kernel (a value of another type or
shape) runs on its own; a diagram with a block on the python tier runs its runs one
after the other.
"""

from __future__ import annotations

import numpy as np

from ..contract import UnsupportedSystem
from ..contract import response as base_response
from . import loader, rk
from .continuous import (
    EXPLICIT_METHODS,
    _integrator_error,
    _solver_options,
    run_continuous,
)
from .diagnose import explain_nan
from .instants import _eval_instants, _instants
from .loops import INTEGRATOR_FAILED
from .run import prepare, simulate


def run_many(sys, T, U, X0s, params_list, *, t_eval=None, method="RK45", **solver):
    """Runs of ``sys``, one per initial state and parameter set; their responses and errors.

    Parameters
    ----------
    sys : control.InterconnectedSystem
        Continuous, discrete or sampled-data.
    T, U : numpy.ndarray
        Time points and inputs ``(ninputs, len(T))``, shared by the runs.
    X0s : numpy.ndarray
        Initial states, ``(runs, nstates)``.
    params_list : list of dict or None
        Each run's ``params`` (as for :func:`control.input_output_response`).
    t_eval : numpy.ndarray, optional
        Evaluation times (default ``T``).
    method : str
        ``solve_ivp`` method for continuous states (compiled: RK45, RK23, DOP853).
    **solver
        ``rtol``, ``atol``, ``max_step``, ``first_step``.

    Returns
    -------
    responses : list of control.TimeResponseData or None
        None where the run failed.
    errors : list of Exception or None
        Why a run failed (the message of a run of its own), else None.

    Examples
    --------
    >>> import control as ct
    >>> plant = ct.nlsys(lambda t, x, u, params: -params["a"] * x + u, None, inputs="u",
    ...                  outputs="y", states=1, params={"a": 1.0}, name="plant")
    >>> loop = ct.interconnect([plant], inputs="u", outputs="y")
    >>> T = np.linspace(0.0, 1.0, 3)
    >>> responses, errors = run_many(loop, T, np.ones((1, 3)), np.zeros((2, 1)),
    ...                              [{"a": 1.0}, {"a": 2.0}])
    >>> [round(float(r.outputs[-1]), 4) for r in responses], errors
    ([0.6321, 0.4323], [None, None])
    """
    X0s = np.atleast_2d(np.asarray(X0s, dtype=float))
    runs = X0s.shape[0]
    t_eval = T if t_eval is None else np.ascontiguousarray(t_eval, dtype=float)
    jobs = _jobs(sys, T, U, X0s, params_list)
    responses, errors = [None] * runs, [None] * runs
    groups = {}
    for r, job in enumerate(jobs):
        if job.injected or not loader._jit.HAVE_NUMBA or (
                not sys.isdtime(strict=True) and method not in EXPLICIT_METHODS):
            groups.setdefault(("alone", r), []).append(r)
        else:
            groups.setdefault(tuple(id(k) for k in job.plan.kernels), []).append(r)
    for key, members in groups.items():
        if key[0] == "alone":
            for r in members:
                responses[r], errors[r] = _one(sys, jobs[r], T, U, X0s[r], params_list[r],
                                               t_eval, method, solver)
            continue
        done = (_discrete if sys.isdtime(strict=True) else _continuous)(
            sys, [jobs[r] for r in members], [params_list[r] for r in members], T, U,
            X0s[members], t_eval, method, solver)
        for r, (resp, error) in zip(members, done, strict=True):
            responses[r], errors[r] = resp, error
    return responses, errors


def _jobs(sys, T, U, X0s, params_list):
    """One job per run: the first prepared, the others sharing its kernels with their own
    parameters packed (:attr:`~controlkit.blocks.contract.BlockKernels.repack`), or
    prepared anew where their values would change a kernel."""
    from dataclasses import replace

    from .tiers import _local_params

    first = prepare(sys, params_list[0], (T[0], X0s[0], U[:, 0]))
    jobs = [first]
    for r, params in enumerate(params_list[1:], start=1):
        parts = []
        for b in first.blocks:
            if b.kernel.repack is None:
                parts.append(b.kernel.params)
                continue
            local = _local_params(sys, b.system, params)
            p = b.kernel.repack(local)
            if p is None or p.shape != b.kernel.params.shape:
                parts = None
                break
            parts.append(p)
        if parts is None or first.injected:
            jobs.append(prepare(sys, params, (T[0], X0s[r], U[:, 0])))
        else:
            jobs.append(replace(first, P=np.concatenate(parts + [np.zeros(0)]), how=""))
    return jobs


def _one(sys, job, T, U, X0, params, t_eval, method, solver):
    try:
        if sys.isdtime(strict=True):
            return simulate(sys, t_eval, X0, U, params=params), None
        return run_continuous(job, T, U, X0, t_eval=t_eval, method=method, **solver), None
    except (ArithmeticError, RuntimeError, ValueError, UnsupportedSystem) as error:
        return None, error


def _discrete(sys, jobs, params, T, U, X0s, t_eval, method, solver):
    job = jobs[0]
    N = T.size
    Ps = np.ascontiguousarray(np.stack([j.P for j in jobs]))
    Ys = np.zeros((len(jobs), sys.noutputs, N))
    Xs = np.zeros((len(jobs), sys.nstates, N))
    statuses = np.full((len(jobs), 3), -1, dtype=np.int64)
    U = np.require(U, dtype=float, requirements=["C", "W"])
    loader.driver().run_discrete_many(np.ascontiguousarray(T, dtype=float),
                                      np.ascontiguousarray(X0s), U, Ps, Ys, Xs, statuses,
                                      job.generic_plan())
    done = []
    for r, j in enumerate(jobs):
        if statuses[r, 0] >= 0 or not np.isfinite(Xs[r]).all():
            # run it alone: its failure in its own words
            done.append(_one(sys, j, T, U, X0s[r], params[r], t_eval, method, solver))
            continue
        done.append((base_response(sys, T, Ys[r], Xs[r], U), None))
    return done


def _continuous(sys, jobs, params, T, U, X0s, t_eval, method, solver):
    job = jobs[0]
    rtol, atol, max_step, first_step = _solver_options(job.plan.continuous.size, **solver)
    instants, h = _instants(sys, T[0], T[-1])
    eval_instant = _eval_instants(t_eval, instants, h)
    runs, m = len(jobs), t_eval.size
    Ys = np.zeros((runs, sys.noutputs, m))
    Xs = np.zeros((runs, sys.nstates, m))
    Uos = np.zeros((runs, sys.ninputs, m))
    statuses = np.full((runs, 4), -1, dtype=np.int64)
    Ps = np.ascontiguousarray(np.stack([j.P for j in jobs]))
    loader.driver().run_continuous_many(
        rk.machine_function(), instants, float(T[-1]), np.ascontiguousarray(T, dtype=float),
        np.require(U, dtype=float, requirements=["C", "W"]), t_eval, eval_instant, Ys, Xs, Uos,
        np.ascontiguousarray(X0s), Ps, rk.METHOD_INDEX[method], rtol, atol, max_step,
        first_step, statuses, job.generic_plan())
    done = []
    for r, j in enumerate(jobs):
        status = statuses[r]
        try:
            if status[1] == INTEGRATOR_FAILED:
                raise _integrator_error(j, status, t_eval, method, Xs[r][:, -1])
            if status[1] >= 0:
                explain_nan(sys, j.blocks, t_eval[min(status[0], m - 1)], int(status[1]))
        except (ArithmeticError, RuntimeError) as error:
            done.append((None, error))
            continue
        done.append((base_response(sys, t_eval, Ys[r], Xs[r], Uos[r]), None))
    return done
