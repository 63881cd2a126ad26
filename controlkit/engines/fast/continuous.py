"""Diagrams with continuous states (and of several rates) on the fast engine.

:func:`run_continuous` runs the instants' loop of :mod:`.loops` through the diagram's
module (as Python or compiled, :mod:`.run`), integrating between the discrete instants by
the Runge-Kutta methods of :mod:`.rk` (``RK45``, ``RK23``, ``DOP853``: scipy's steps) or by
scipy's stiff solvers (``LSODA``, ``BDF``, ``Radau``: :func:`.loops.scipy_interval`, as
Python). A run goes in pieces of about a tenth of a second, an interval paused inside if
need be: progress, Ctrl-C and the choice of compiling act between pieces.
"""

from __future__ import annotations

import control as ct
import numpy as np

from ... import _jit
from ..._checks import Diverged, warn_caller
from ...sampled_data import sample_times
from ..contract import UnsupportedSystem, read_only, recorded_indices
from ..contract import response as base_response
from . import loops, rk, store
from .diagnose import explain_failure
from .loops import (
    AGAIN_AS_PYTHON,
    BUDGET,
    INSTANT,
    INTEGRATOR_FAILED,
    NEXT_TIME,
    SERVES,
    UNDER_WAY,
    WATCH_STAGES,
)
from .pieces import Pieces, interrupted, now, quiet_numbers, where_they_part
from .run import Runner

#: The methods integrated by the engine's own code; the stiff ones go to scipy.
EXPLICIT_METHODS = tuple(rk.METHODS)
STIFF_METHODS = ("LSODA", "BDF", "Radau")
#: The ``solve_ivp`` options the engine takes; any other sends the run to python-control.
SOLVER_OPTIONS = ("rtol", "atol", "max_step", "first_step")
#: Evaluations of the right-hand side in the piece a newly compiled module is checked on
#: (run both ways): a short one, so that a run that fits in one piece does not run twice.
CHECK_EVALUATIONS = 32


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
    >>> lag = ct.ss([[-1e6]], [[1e6]], [[1.0]], [[0.0]], inputs="u", outputs="y", name="lag")
    >>> T = np.linspace(0.0, 1e4, 101)
    >>> try:
    ...     controlkit.input_output_response(lag, T, np.sin(T), compile=False)
    ... except StiffProblem as error:
    ...     print(str(error).split("Use ")[-1])
    an implicit method: solve_ivp_method='BDF' (or 'LSODA', 'Radau')
    """


def solver_options(n, span, rtol=1e-3, atol=1e-6, max_step=np.inf, first_step=None, **other):
    """``(rtol, atol per state, max_step, first_step)`` as the integrator takes them, for
    a run over ``span`` seconds, checked as ``scipy.integrate.solve_ivp`` checks them.

    Raises
    ------
    ValueError
        With scipy's message where python-control's run would raise scipy's:
        ``max_step`` or ``first_step`` not positive, ``first_step`` beyond the span,
        ``atol`` negative; ``atol`` neither a number nor one value per state.

    Warns
    -----
    UserWarning
        ``rtol`` below ``100 eps``, which is raised to it (scipy's warning).

    Examples
    --------
    >>> rtol, atol, max_step, first_step = solver_options(2, 10.0, rtol=1e-6)
    >>> rtol, atol.tolist(), first_step
    (1e-06, [1e-06, 1e-06], 0.0)
    """
    if other:
        raise UnsupportedSystem(f"solve_ivp options {sorted(other)} (the fast engine takes "
                                f"{list(SOLVER_OPTIONS)})")
    if np.ndim(rtol) > 0:  # scipy takes one per state; the integrator takes one number
        raise UnsupportedSystem("an rtol per state (the fast engine takes one number)")
    if max_step <= 0:
        raise ValueError("`max_step` must be positive.")
    if first_step is not None and first_step <= 0:
        raise ValueError("`first_step` must be positive.")
    if first_step is not None and first_step > abs(span):
        raise ValueError("`first_step` exceeds bounds.")
    if rtol < rk.RTOL_FLOOR:
        warn_caller("At least one element of `rtol` is too small. Setting "
                    f"`rtol = np.maximum(rtol, {rk.RTOL_FLOOR})`.")
    atol = np.asarray(atol, dtype=float)
    atol = np.full(n, float(atol)) if atol.ndim == 0 else atol.reshape(-1)
    if atol.size != n:
        raise ValueError(f"atol must be a number or have {n} values (one per continuous "
                         f"state), got {atol.size}")
    if np.any(atol < 0):
        raise ValueError("`atol` must be positive.")
    return (float(rtol), np.ascontiguousarray(atol), float(max_step),
            0.0 if first_step is None else float(first_step))


class _Run:
    """The arrays of one run, which its pieces fill (see :func:`run_continuous`)."""

    def __init__(self, sys, plan, T, U, X0, t_eval, method, solver):
        self.sys, self.T, self.U, self.times = sys, T, U, t_eval
        self.instants = sample_times(getattr(sys, "base_period", 0.0), T[0], T[-1])
        h = float(getattr(sys, "base_period", 0.0) or 0.0)
        self.eval_instant = loops.instant_of(t_eval, self.instants, h)
        if not h:
            # scipy serves the first time too, as in python-control's call, from the first
            # step's interpolant: a -0.0 there is 0.0, LSODA's value a last bit off the
            # initial state, and an RK step's times are evaluated together with it
            self.eval_instant[:] = -1
        m, nc = t_eval.size, plan.continuous.size
        self.Y = np.zeros((sys.noutputs, m))
        self.X = np.zeros((sys.nstates, m))
        self.Uo = np.zeros((sys.ninputs, m))
        self.x, self.held = np.array(X0, dtype=float), np.zeros(plan.ny)
        self.ctrl = np.zeros(SERVES + 1, dtype=np.int64)
        self.users = plan.calls_users  # (whose compiled stages are watched)
        self.status = np.full(4, -1, dtype=np.int64)
        self.work = rk.make_workspace(nc, 0, m)
        self.y_eval, self.yc = np.zeros((m, nc)), np.zeros(nc)
        rk.set_horizon(self.work, self.instants[0], T[-1])
        nx, widest = sys.nstates, max([1, *(row.NX for row in plan.rows)])
        ys, ui, ubuf = np.zeros(plan.ny), np.zeros(plan.nu), np.empty((U.shape[0], 1))
        xt, dx, cidx = np.empty(nx), np.zeros(nx + 1), plan.continuous
        self.rhs_args = (self.x, xt, cidx, T, U, ubuf, None, ys, ui, self.held, dx)
        self.buffers = (ys, ui, np.empty(nx), np.empty(5 * widest), xt, cidx, self.yc,
                        self.y_eval, ubuf, self.work)
        self.method = method
        # (scipy checks first_step on each interval it is given: between the instants)
        spans = np.diff(np.append(self.instants, T[-1]))
        self.solver = solver_options(nc, spans[spans > 0].min(initial=T[-1] - T[0]),
                                     **solver)

    def loop_arguments(self, P, method):
        """What the instants' loops take after the evaluator's four functions and the step
        machine (:func:`.loops.instants_loop`, :func:`.loops.scipy_loop`), for parameters
        ``P`` and ``method`` (the integrator's index of it, or scipy's name)."""
        return ((*self.rhs_args[:6], P, *self.rhs_args[7:]),
                (self.instants, float(self.T[-1]), self.T, self.U, self.times,
                 self.eval_instant), (self.Y, self.X, self.Uo), (self.x, P, self.held),
                self.buffers, (method, *self.solver), self.ctrl, self.status)

    def arrays(self):
        """The run's state between pieces (results are written by index: a piece run again
        writes the same columns again)."""
        return (self.x, self.held, self.ctrl, self.status, *self.work, self.yc)

    def snapshot(self):
        return [a.copy() for a in self.arrays()]

    def restore(self, saved):
        for array, kept in zip(self.arrays(), saved, strict=True):
            array[...] = kept

    @property
    def position(self) -> int:
        """The outputs written so far."""
        return int(self.ctrl[NEXT_TIME])

    def served_so_far(self, job) -> int:
        """The outputs written so far, and those of the states a paused interval served,
        made now as Python (its own are made at its end; a continuous run's one interval
        spans the whole run): a run stopped by Ctrl-C keeps what it computed."""
        n = self.position  # (the integrator's first time not served, in the interval)
        served = max(n, int(self.work.ints[rk.NEXT_EVAL]))
        f, (ys, ui, _, _, xt, cidx, _, _, ubuf, _) = job.functions(), self.buffers
        for j in range(n, served):
            try:
                with quiet_numbers():
                    if loops.record_served(f.evaluate, f.outputs, j, self.x, xt, cidx,
                                           self.y_eval, self.times, self.T, self.U, ubuf,
                                           job.P, ys, ui, self.held, self.Y, self.X,
                                           self.Uo) != -1:
                        return j
            except Exception:  # noqa: BLE001 - an output that fails ends what was computed
                return j
        return served

    def stopped(self) -> bool:
        return self.status[1] != -1

    def handed_back(self) -> bool:
        return self.status[1] == AGAIN_AS_PYTHON  # (a user's function compiled went on)

    def written(self, n0, n1):
        """Results ``n0:n1``, and the integrator's states served past them (not written as
        outputs yet: a piece from the same start writes over them)."""
        return [a[:, n0:n1].copy() for a in (self.Y, self.X, self.Uo)] + [self.y_eval[n0:].copy()]

    def put_back(self, written, n0, n1):
        self.Y[:, n0:n1], self.X[:, n0:n1], self.Uo[:, n0:n1], self.y_eval[n0:] = written

    def where(self, job, n0, n1, mine, theirs) -> str:
        """(A piece ends inside an interval: the blocks named by the states it served.)"""
        served = [np.zeros((self.x.size, len(y))) for y in (mine[3], theirs[3])]
        for states, y in zip(served, (mine[3], theirs[3]), strict=True):
            states[job.plan.continuous] = y.T
        return f"after t = {self.times[max(n0 - 1, 0)]:g} s" + where_they_part(
            job.blocks, self.times[n0:], *served)

    def done(self) -> bool:
        return (self.status[1] != -1 or self.ctrl[INSTANT] >= self.instants.size
                and self.ctrl[UNDER_WAY] == 0)

    def fraction(self) -> float:
        """How much of the run's span is done."""
        span = self.T[-1] - self.T[0]
        if self.done() or span <= 0:
            return 1.0
        k = min(int(self.ctrl[INSTANT]), self.instants.size - 1)
        t = self.work.floats[rk.TIME_REACHED] if self.ctrl[UNDER_WAY] else self.instants[k]
        return float(np.clip((t - self.T[0]) / span, 0.0, 1.0))

    def piece(self, job, budget):
        """One piece of the run on ``job`` (at most ``budget`` evaluations in an interval)."""
        self.ctrl[BUDGET] = budget
        stiff = self.method in STIFF_METHODS
        self.ctrl[WATCH_STAGES] = int(job.compiled and self.users)
        args = self.loop_arguments(job.P, self.method if stiff else
                                   rk.METHOD_INDEX[self.method])
        try:
            if job.compiled and not stiff:
                _run_compiled(job, args)
            else:
                f = job.functions()
                with quiet_numbers():
                    (loops.scipy_loop if stiff else loops.instants_loop)(
                        f.evaluate, f.update, f.outputs, f.derivatives, None, *args)
        finally:
            self.ctrl[WATCH_STAGES] = 0  # (a compiled piece's state is compared with Python's)


def run_continuous(sys, T, U, X0, *, params=None, t_eval=None, method="RK45",
                   compile=None, progress=None, record_every=1, on_chunk=None,
                   **solver) -> ct.TimeResponseData:
    """Run a diagram with continuous states (or of several rates): the whole horizon.

    Parameters
    ----------
    sys : control.InterconnectedSystem
        The diagram (a :class:`controlkit.sampled_data.SampledDataSystem` included).
    T : numpy.ndarray
        Time points of ``U`` (python-control's ``timepts``).
    U : numpy.ndarray
        Inputs, ``(ninputs, len(T))``, interpolated linearly in between.
    X0 : numpy.ndarray
        Initial state.
    params : dict, optional
        As for :func:`control.input_output_response`.
    t_eval : numpy.ndarray, optional
        Where the response is reported (default ``T``).
    method : str
        ``RK45``, ``RK23``, ``DOP853`` (the engine's), or ``LSODA``, ``BDF``, ``Radau``.
    compile : bool or None
        As for :func:`controlkit.input_output_response`.
    progress, record_every, on_chunk
        As for :func:`controlkit.simulation.simulate` (the run is held in memory).
    **solver
        ``rtol``, ``atol``, ``max_step``, ``first_step``, as for ``solve_ivp``.

    Returns
    -------
    control.TimeResponseData

    Raises
    ------
    KeyboardInterrupt
        On Ctrl-C, with the response so far on its ``response`` attribute.

    Examples
    --------
    >>> plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="p", inputs="u",
    ...               outputs="y")
    >>> loop = ct.interconnect([plant], inputs="u", outputs="y")
    >>> T = np.linspace(0.0, 1.0, 3)
    >>> run_continuous(loop, T, np.ones((1, 3)), np.zeros(1)).outputs.round(5)
    array([0.     , 0.39349, 0.63211])
    """
    # arrays of one type whatever the caller's (a read-only one copied): the compiled
    # loop takes one type of each
    T = np.require(T, dtype=float, requirements=["C", "W"])
    U = np.require(U, dtype=float, requirements=["C", "W"])
    t_eval = T if t_eval is None else np.require(t_eval, dtype=float, requirements=["C", "W"])
    if t_eval.size and (t_eval[0] < T[0] or t_eval[-1] > T[-1]):
        raise ValueError("Values in `t_eval` are not within `t_span`.")
    if np.any(np.diff(t_eval) <= 0):
        raise ValueError("Values in `t_eval` are not properly sorted.")
    if method not in EXPLICIT_METHODS + STIFF_METHODS:
        raise UnsupportedSystem(f"solve_ivp method {method!r}")
    if compile and method in STIFF_METHODS:  # (asked for: said, as a block's reason is)
        warn_caller(f"running {sys.name!r} as Python: {method} is scipy's own solver, which "
                    f"calls the diagram's Python functions (RK45, RK23 and DOP853 compile)")
    runner = Runner(sys, params, False if method in STIFF_METHODS else compile, T.size)
    run = _Run(sys, runner.python.plan, T, U, X0, t_eval, method, solver)
    pieces, start = Pieces(first=256), now()
    while not run.done():
        began, n0, checking = now(), run.position, runner.to_check
        try:
            runner.piece(run, pieces.next(), CHECK_EVALUATIONS)
        except KeyboardInterrupt as stop:
            n = n0 if checking else run.served_so_far(runner.python)
            kept = recorded_indices(n, record_every)  # (as the whole run would keep)
            raise interrupted(stop, base_response(sys, t_eval[kept], run.Y[:, kept],
                                                  run.X[:, kept], run.Uo[:, kept])) from None
        if not checking:  # (a check runs its piece twice: not the pace of pieces)
            pieces.took(pieces.next(), now() - began)
        if not runner.decided:  # (a compiled job chosen: checked on the next piece)
            runner.decide(now() - start, run.fraction())
        if progress is not None:
            progress(run.fraction())
    _failed(runner.job, run)
    runner.finished(now() - start)
    resp = base_response(sys, t_eval, run.Y, run.X, run.Uo)
    resp.engine_mode = runner.mode
    if record_every != 1 or on_chunk is not None:
        if on_chunk is not None:
            on_chunk(*read_only(t_eval, run.Y, run.X))
        kept = recorded_indices(t_eval.size, record_every)
        resp = base_response(sys, t_eval[kept], run.Y[:, kept], run.X[:, kept], run.Uo[:, kept])
        resp.engine_mode = runner.mode
    return resp


def _run_compiled(job, args):
    """A piece of ``job``'s run compiled: its module's four functions compiled for the
    instants' loop (:meth:`.run.Job.compiled_once`), handed to the loop compiled once for
    every diagram (:func:`.store.instants_loop`); ``args`` as :meth:`_Run.piece` makes them."""
    with store.LOCK:  # (threads running the same job share what it keeps)
        if job.continuous is None:
            job.continuous = [store.import_module(store.module_file(job.source, "diagram"),
                                                  job.kernels()), None]
    kept = job.continuous
    module = kept[0]
    if kept[1] is None:  # (a run's arrays are of the same types every run)
        numba = _jit.numba_module()
        rhs_args, _, results, state, buffers, _, _, _ = args
        signatures, types = loops.evaluator_signatures(numba, rhs_args, results, state,
                                                       buffers)
        functions = job.compiled_once(signatures, lambda path: store.compile_functions(
            (module.evaluate_caught, module.update_caught, module.outputs,
             module.derivatives_caught), signatures, path, blocks=len(job.blocks)))
        types = (*types, *(numba.typeof(a) for a in (store.step_machine(), *args)))
        kept[1] = (store.instants_loop(types), functions)
    compiled_loop, functions = kept[1]
    compiled_loop(*functions, store.step_machine(), *args)


def compile_integrator() -> str:
    """Compile (or load) the step machine and the instants' loop by running a lag compiled,
    for ``controlkit warmup``; returns ``"compiled"``, or ``"python"`` where nothing compiles.

    Examples
    --------
    >>> compile_integrator() in ("compiled", "python")
    True
    """
    lag = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="lag", inputs="u", outputs="y")
    loop = ct.interconnect([lag], inputs="u", outputs="y", name="controlkit_warmup")
    T = np.linspace(0.0, 1.0, 3)
    return run_continuous(loop, T, np.ones((1, 3)), np.zeros(1), compile=True).engine_mode


def _failed(job, run):
    """Raise what stopped the run, if something did."""
    status, t_eval = run.status, run.times
    if status[1] == INTEGRATOR_FAILED:
        raise _integrator_error(job, run)
    if status[1] >= 0:
        j = min(int(status[0]), t_eval.size - 1)
        u = loops.interpolate(run.T, run.U, t_eval[j], np.zeros((run.U.shape[0], 1)))[:, 0]
        explain_failure(job, t_eval[j], run.x, u, status[1], -1)
    if run.ctrl[NEXT_TIME] < t_eval.size:
        raise RuntimeError(f"the integration of {job.sys.name!r} stopped at t = "
                           f"{t_eval[run.ctrl[NEXT_TIME]]:g} s without a reason; please report it")


def _integrator_error(job, run):
    """The integrator stopped: say where, why, and what to do."""
    sys, status, t_eval, method, x = job.sys, run.status, run.times, run.method, run.x
    code, served = int(status[2]), int(status[0])
    where = t_eval[served - 1] if served > 0 else t_eval[0]
    blocks = [b.system.name for b in job.blocks if b.system.nstates and b.system.dt == 0]
    size = float(np.max(np.abs(x[job.plan.continuous]))) if job.plan.continuous.size else 0.0
    state = f"the continuous blocks {blocks}"
    if code == rk.STEP_TOO_SMALL:
        return RuntimeError(
            f"{sys.name!r}: the step size of {method} fell below the spacing of numbers "
            f"after t = {where:g} s, with the largest state of {state} at {size:.3g}: the "
            f"loop diverges there (a state without bound), or a block is stiff or "
            f"discontinuous; for a stiff block try solve_ivp_method='BDF' (or 'LSODA', 'Radau')")
    if code == rk.STEP_NOT_A_NUMBER:  # (python-control's solver would never end)
        return RuntimeError(
            f"{sys.name!r}: the step size of {method} is not a number after t = {where:g} "
            f"s: solve_ivp's error scale atol + rtol |x| is 0 for a state at 0 with atol=0 "
            f"(scipy's solver never ends there); give solve_ivp_kwargs an atol > 0")
    if code == rk.STIFF:
        return StiffProblem(
            f"{sys.name!r} is stiff for {method}: after t = {where:g} s its steps are held "
            f"down by stability, not accuracy (step size times the fastest rate |h lambda| "
            f"above the method's stability bound for many steps in a row), in {state}; at "
            f"its pace the run to t = {t_eval[-1]:g} s would take about "
            f"{float(status[3]):.2g} steps. Use an implicit method: "
            f"solve_ivp_method='BDF' (or 'LSODA', 'Radau')")
    if code == rk.NON_FINITE:
        return Diverged(
            f"{sys.name!r}: the state of {state} became non-finite after t = {where:g} s "
            f"(the loop diverged, or a block's equation is undefined there)")
    return RuntimeError(f"{sys.name!r}: {rk.STATUS_MESSAGES.get(code, code)}")
