"""Many runs of one diagram in one call, compiled once, over all cores.

A sweep over a diagram's parameters or initial states runs the same module with other
numbers: :func:`run_many` packs each run's parameters (users' functions are compiled for
the types of their parameters, so the runs share their module), and runs the compiled
entry points on threads (the compiled loops release Python's lock, so the runs share
the cores). The first run goes alone, as Python, unless the module is compiled already:
its time says whether compiling pays for the others (:mod:`.run`'s rule). A run whose
parameters would change the module (a value of another type or shape), or a diagram
that cannot be compiled, runs one run after the other on its own.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace

import numpy as np

from ..contract import UnsupportedSystem
from ..contract import response as base_response
from .continuous import STIFF_METHODS, _failed, _Run, run_continuous
from .discrete import simulate
from .loops import AGAIN_AS_PYTHON
from .pieces import checked_as, now
from .response import read_inputs
from .run import CHECKED, PAYS, compiled_cost, compiled_job
from .tiers import _local_params


def run_many(sys, T, U, X0s, params_list, *, t_eval=None, method="RK45", compile=None, **solver):
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
        ``solve_ivp`` method for continuous states.
    compile : bool or None
        As for :func:`controlkit.input_output_response` (None: compiled when the first
        run's time says it pays for the others).
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
    discrete = sys.isdtime(strict=True)
    if discrete:  # python-control's discrete run reads U at its evaluation times
        U = read_inputs(T, U, t_eval)
    responses, errors = [None] * runs, [None] * runs

    def alone(r, compiled):
        try:
            if discrete:
                responses[r] = simulate(sys, t_eval, X0s[r], U, params=params_list[r],
                                        compile=compiled)
            else:
                responses[r] = run_continuous(sys, T, U, X0s[r], params=params_list[r],
                                              t_eval=t_eval, method=method,
                                              compile=compiled, **solver)
        except (ArithmeticError, RuntimeError, ValueError, UnsupportedSystem) as error:
            errors[r] = error

    job = None if compile is False or method in STIFF_METHODS else compiled_job(
        sys, params_list[0])
    if isinstance(job, str) or job is None:
        for r in range(runs):  # (compile=True: each run says why it runs as Python)
            alone(r, compile is True)
        return responses, errors
    todo = list(range(runs))
    if compile is None and not job.is_compiled():
        began = now()
        alone(0, False)
        todo = todo[1:]
        python = (now() - began) * len(todo)
        if python <= PAYS * compiled_cost(job):
            for r in todo:
                alone(r, False)
            return responses, errors
    jobs = {r: _repacked(sys, job, params_list[r]) for r in todo}
    for r in [r for r in todo if jobs[r] is None]:
        alone(r, True)
    todo = [r for r in todo if jobs[r] is not None]

    def one(r):
        if discrete:
            N = t_eval.size
            Y, X = np.zeros((sys.noutputs, N)), np.zeros((sys.nstates, N))
            status = np.full(2, -1, dtype=np.int64)
            args = (t_eval, X0s[r], np.require(U, dtype=float, requirements=["C", "W"]),
                    jobs[r].P, Y, X, status, 0, N)
            x = jobs[r].entry("run_discrete", args)(*args)
            return (Y, X) if status[0] < 0 and np.isfinite(x).all() else None
        run = _Run(sys, jobs[r].plan, T, U, X0s[r], t_eval, method, solver)
        run.piece(jobs[r], 0)
        return run

    for r in list(todo):  # a run of values of a class not checked yet (the first, say)
        if checked_as(jobs[r], params_list[r]) in CHECKED:  # alone: compiled, compared with
            continue                                         # Python on its first piece
        alone(r, True)
        todo.remove(r)
        if checked_as(jobs[r], params_list[r]) not in CHECKED:  # they differed (it said
            for rest in todo:                                     # so): the others as Python
                alone(rest, False)
            return responses, errors
    if todo:  # then the others on every core
        one(todo[0])  # (compiled before the threads start)
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            done = list(pool.map(one, todo))
        for r, result in zip(todo, done, strict=True):
            if result is None or not discrete and result.status[1] == AGAIN_AS_PYTHON:
                alone(r, True)  # stopped: alone, to fail in its own words or go on as Python
            elif discrete:
                responses[r] = base_response(sys, t_eval, *result, U)
            else:
                try:
                    _failed(jobs[r], result)
                    responses[r] = base_response(sys, t_eval, result.Y, result.X, result.Uo)
                except (ArithmeticError, RuntimeError, ValueError) as error:
                    errors[r] = error
            if responses[r] is not None:
                responses[r].engine_mode = "compiled"
    return responses, errors


def _repacked(sys, job, params):
    """``job`` with the parameters of ``params`` packed, or None where they would change
    its module (a value of another type or shape)."""
    parts = []
    for b in job.blocks:
        if b.kernel.repack is None:
            parts.append(b.kernel.params)
            continue
        p = b.kernel.repack(_local_params(sys, b.system, params))
        if p is None or p.shape != b.kernel.params.shape:
            return None
        parts.append(p)
    return replace(job, P=np.concatenate(parts + [np.zeros(0)]))
