"""Diagrams with continuous states on the fast engine, and the drop-in's entry point.

:func:`response` is what :func:`controlkit.input_output_response` calls: a discrete
diagram runs step by step (:func:`.run.simulate`), any other through
:func:`run_continuous`, which integrates the continuous states with the compiled
Runge-Kutta methods of :mod:`.rk` (``RK45``, python-control's default, ``RK23`` and
``DOP853``: scipy's steps, so python-control's numbers) between the instants of the
discrete blocks, or with scipy's stiff solvers (``LSODA``, ``BDF``, ``Radau``) called
with the diagram's compiled right-hand side.
"""

from __future__ import annotations

import control as ct
import numpy as np

from ..contract import (
    UnsupportedSystem,
)
from ..contract import response as base_response
from . import loader, rk
from .diagnose import explain_nan
from .instants import _eval_instants, _instants
from .loops import INTEGRATOR_FAILED
from .switching import DriverThenModule

#: The methods integrated by compiled code; the stiff ones go to scipy.
EXPLICIT_METHODS = ("RK23", "RK45", "DOP853")
STIFF_METHODS = ("LSODA", "BDF", "Radau")
#: The ``solve_ivp`` options the engine takes; any other sends the run to python-control.
SOLVER_OPTIONS = ("rtol", "atol", "max_step", "first_step")



class StiffProblem(RuntimeError):
    """An explicit method (``RK45``, ``DOP853``) makes too little progress on a stiff diagram.

    Raised when Hairer's stiffness test (:data:`.rk.STIFF`) finds the steps held down
    by stability and the run, at that pace, would need more than
    :data:`.rk.STIFF_STEP_BUDGET` steps; the message names the diagram, the time, its
    continuous blocks and the remedy (``solve_ivp_method="BDF"``).

    Examples
    --------
    A 1 us lag tracking a sine for 10^4 s would take RK45 some 3e8 steps:

    >>> import controlkit
    >>> lag = ct.tf([1.0], [1e-6, 1.0], inputs="u", outputs="y", name="lag")
    >>> T = np.linspace(0.0, 1e4, 101)
    >>> try:
    ...     controlkit.input_output_response(lag, T, np.sin(T))
    ... except StiffProblem as error:
    ...     print(str(error).split("Use ")[-1])
    an implicit method: solve_ivp_method='BDF' (or 'LSODA', 'Radau')
    """


def _solver_options(n, rtol=1e-3, atol=1e-6, max_step=np.inf, first_step=None, **other):
    if other:
        raise UnsupportedSystem(f"solve_ivp options {sorted(other)} (the fast engine takes "
                                f"{list(SOLVER_OPTIONS)})")
    atol = np.asarray(atol, dtype=float)
    atol = np.full(n, float(atol)) if atol.ndim == 0 else atol.reshape(-1)
    if atol.size != n:
        raise ValueError(f"atol must be a number or have {n} values (one per continuous "
                         f"state), got {atol.size}")
    return (float(rtol), np.ascontiguousarray(atol), float(max_step),
            0.0 if first_step is None else float(first_step))


def run_continuous(job, T, U, X0, *, t_eval=None, method="RK45", generic=None,
                   **solver) -> ct.TimeResponseData:
    """Run a diagram with continuous states (or of several rates): the whole horizon.

    Parameters
    ----------
    job : Job
        From :func:`.run.prepare`.
    T : numpy.ndarray
        Time points of ``U`` (python-control's ``timepts``).
    U : numpy.ndarray
        Inputs, ``(ninputs, len(T))``, interpolated linearly in between.
    X0 : numpy.ndarray
        Initial state.
    t_eval : numpy.ndarray, optional
        Where the response is reported (default ``T``).
    method : str
        ``RK45``, ``RK23``, ``DOP853`` (compiled), or ``LSODA``, ``BDF``, ``Radau``.
    generic : bool, optional
        Force the generic driver (True) or the diagram's module (False); default: as
        :meth:`.run.Job.loop` decides.
    **solver
        ``rtol``, ``atol``, ``max_step``, ``first_step``, as for ``solve_ivp``.

    Returns
    -------
    control.TimeResponseData

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="p", inputs="u",
    ...               outputs="y")
    >>> loop = ct.interconnect([plant], inputs="u", outputs="y")
    >>> T = np.linspace(0.0, 1.0, 3)
    >>> run_continuous(prepare(loop), T, np.ones((1, 3)), np.zeros(1)).outputs.round(5)
    array([0.     , 0.39349, 0.63211])
    """
    sys, plan = job.sys, job.plan
    T = np.ascontiguousarray(T, dtype=float)
    U = np.require(U, dtype=float, requirements=["C", "W"])
    t_eval = T if t_eval is None else np.ascontiguousarray(t_eval, dtype=float)
    if t_eval.size and (t_eval[0] < T[0] or t_eval[-1] > T[-1]):
        raise ValueError("Values in `t_eval` are not within `t_span`.")
    if np.any(np.diff(t_eval) <= 0):
        raise ValueError("Values in `t_eval` are not properly sorted.")
    if method in STIFF_METHODS:
        from .stiff import run_stiff

        return run_stiff(job, T, U, X0, t_eval, method, solver)
    if method not in EXPLICIT_METHODS:
        raise UnsupportedSystem(f"solve_ivp method {method!r}")
    rtol, atol, max_step, first_step = _solver_options(plan.continuous.size, **solver)
    instants, h = _instants(sys, T[0], T[-1])
    eval_instant = _eval_instants(t_eval, instants, h)
    m = t_eval.size
    Y, X, Uo = (np.zeros((sys.noutputs, m)), np.zeros((sys.nstates, m)),
                np.zeros((sys.ninputs, m)))
    x, held = np.array(X0, dtype=float), np.zeros(plan.ny)
    ctrl, status = np.zeros(1, dtype=np.int64), np.full(4, -1, dtype=np.int64)
    if generic is None:
        run, use_driver = job.loop("run_continuous")
    elif generic:
        run, use_driver = loader.driver().run_continuous, True
    else:
        run, use_driver = job.loop("run_continuous", policy="now")
    rest = (float(T[-1]), T, U, t_eval, eval_instant, ctrl, Y, X, Uo, x, held, job.P,
            rk.METHOD_INDEX[method], rtol, atol, max_step, first_step, True, status)
    if job.how == "python":
        run(rk.machine_on_arrays, instants, 0, 0, instants.size, *rest)
    else:  # instant by instant, the module taking over from the driver once compiled
        loop = DriverThenModule(job, "run_continuous", run, use_driver,
                                may_switch=generic is None)
        for k0, k1 in loop.ranges(0, instants.size):
            loop(rk.machine_function(), instants, 0, k0, k1, *rest)
            if status[1] != -1:  # failed: said below
                break
    if status[1] == INTEGRATOR_FAILED:
        raise _integrator_error(job, status, t_eval, method, x)
    if status[1] >= 0:
        explain_nan(sys, job.blocks, t_eval[min(status[0], m - 1)], int(status[1]))
    if ctrl[0] < m:
        raise RuntimeError(f"the integration of {sys.name!r} stopped at t = "
                           f"{t_eval[ctrl[0]]:g} s without a reason; please report it")
    job.after_run()
    return base_response(sys, t_eval, Y, X, Uo)


def _integrator_error(job, status, t_eval, method, x):
    """The integrator stopped: say where, why, and what to do."""
    sys = job.sys
    code, served = int(status[2]), int(status[0])
    where = t_eval[served - 1] if served > 0 else t_eval[0]
    blocks = [b.system.name for b in job.blocks if b.system.nstates
              and b.system.dt == 0]
    size = float(np.max(np.abs(x[job.plan.continuous]))) if job.plan.continuous.size else 0.0
    state = f"the continuous blocks {blocks}"
    if code == rk.STEP_TOO_SMALL:
        return RuntimeError(
            f"{sys.name!r}: the step size of {method} fell below the spacing of numbers "
            f"after t = {where:g} s, with the largest state of {state} at {size:.3g}: the "
            f"loop diverges there (a state without bound), or a block is stiff or "
            f"discontinuous; for a stiff block try solve_ivp_method='BDF' (or 'LSODA', "
            f"'Radau')")
    if code == rk.STIFF:
        return StiffProblem(
            f"{sys.name!r} is stiff for {method}: after t = {where:g} s its steps are held "
            f"down by stability, not accuracy (step size times the fastest rate |h lambda| "
            f"above the method's stability bound for many steps in a row), in {state}; at "
            f"its pace the run to t = {t_eval[-1]:g} s would take about "
            f"{float(status[3]):.2g} steps. Use an implicit method: "
            f"solve_ivp_method='BDF' (or 'LSODA', 'Radau')")
    if code == rk.NON_FINITE:
        return FloatingPointError(
            f"{sys.name!r}: the state of {state} became non-finite after t = {where:g} s "
            f"(the loop diverged, or a block's equation is undefined there)")
    return RuntimeError(f"{sys.name!r}: {rk.STATUS_MESSAGES.get(code, code)}")
