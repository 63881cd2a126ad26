"""The Runge-Kutta integrator (controlkit.engines.fast.rk) against scipy's ``solve_ivp``,
step for step: run as Python (:func:`rk_problems.solve_ivp`, a Python call of the loop) and
compiled (the step machine kept in the store, called by a compiled caller).

Equality means: ``max |ours - scipy| <= 1e-12 * max(1, |scipy|)`` per component, the
same number of right-hand-side evaluations and the same accepted step times. With the
integrator's arithmetic (numpy's BLAS calls) the results are in fact identical to the
last bit, which :func:`test_exact_arithmetic_is_bitwise` checks separately (it depends
on numba's BLAS and numpy's BLAS picking the same kernel, true of the wheels installed
here).

The default run keeps each method on a few problems with the options that matter,
exactness, interval restarts, failures, invalid arguments and the plain-Python mode; the
rest of the sweep is marked slow (``pytest -m slow tests/test_rk.py``).
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import warnings

import control as ct
import numpy as np
import pytest
import rk_problems as P
import scipy.integrate

import controlkit
from controlkit import _jit
from controlkit.engines.fast import rk, store

METHODS = ["RK23", "RK45", "DOP853"]
PROBLEMS = P.make_problems()

OPTIONS = {
    "default": {},
    "tight": {"rtol": 1e-7, "atol": 1e-9},
    "max_step": {"max_step_fraction": 1 / 97},
    "first_step": {"first_step": 1e-3},
    "vector_atol": {"rtol": 1e-5, "vector_atol": True},
}

RELATIVE = 1e-12

#: The (problem, option) pairs :func:`test_matches_scipy` checks in the default run, for
#: every method: every option on van der Pol; one state (numpy's vector-vector paths),
#: ten states, repeated rejections, tabulated inputs and a chaotic system with one or two
#: options each. The other pairs are marked slow.
DEFAULT_CASES = {("van_der_pol", option) for option in OPTIONS} | {
    ("decay", "default"),
    ("decay", "vector_atol"),
    ("chain10", "default"),
    ("chain10", "tight"),
    ("stiffish", "default"),
    ("mass_spring_input", "max_step"),
    ("lag_square_input", "first_step"),
    ("lorenz", "tight"),
}


def slow_unless(default, *values, ids=None):
    """``pytest.param`` for each of ``values``, marked slow unless ``default(value)``."""
    return [
        pytest.param(*(value if isinstance(value, tuple) else (value,)),
                     marks=() if default(value) else pytest.mark.slow,
                     id=None if ids is None else ids(value))
        for value in values
    ]


def resolve_options(problem, name):
    """Keyword arguments shared by scipy and :func:`rk_problems.solve_ivp` for option ``name``."""
    options = dict(OPTIONS[name])
    if options.pop("max_step_fraction", None):
        t0, t1 = problem.t_span
        options["max_step"] = abs(t1 - t0) / 97
    if options.pop("vector_atol", None):
        n = problem.y0.shape[0]
        options["atol"] = np.array([1e-8, 1e-5, 1e-3])[np.arange(n) % 3]
    return options


def scipy_solve(problem, method, t_eval, t_span=None, y0=None, **options):
    """scipy's ``solve_ivp`` on the same Python right-hand side."""
    return scipy.integrate.solve_ivp(
        problem.scipy_fun(),
        problem.t_span if t_span is None else t_span,
        problem.y0 if y0 is None else y0,
        method=method,
        t_eval=t_eval,
        **options,
    )


def our_solve(problem, method, t_eval, t_span=None, y0=None, log_steps=200_000, **options):
    """:func:`rk_problems.solve_ivp` on the same right-hand side (a Python call: the loop run as
    Python)."""
    return P.solve_ivp(
        problem.rhs,
        problem.t_span if t_span is None else t_span,
        problem.y0 if y0 is None else y0,
        method=method,
        t_eval=t_eval,
        args=problem.args,
        log_steps=log_steps,
        **options,
    )


def assert_equal_to_scipy(ours, theirs, what="y"):
    """``|ours - theirs| <= 1e-12 max(1, |theirs|)`` everywhere (shapes equal)."""
    ours = np.asarray(ours)
    theirs = np.asarray(theirs)
    assert ours.shape == theirs.shape, (what, ours.shape, theirs.shape)
    bound = RELATIVE * np.maximum(1.0, np.abs(theirs))
    excess = np.abs(ours - theirs) - bound
    worst = np.unravel_index(np.argmax(excess), excess.shape) if excess.size else None
    assert not excess.size or excess[worst] <= 0, (
        f"{what}: |diff| {np.abs(ours - theirs)[worst]:.3e} at {worst} "
        f"exceeds {bound[worst]:.3e}"
    )


# ------------------------------------------------------------------------------------------
# One interval, many problems and options
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("method", "name", "option"),
    slow_unless(lambda case: case[1:] in DEFAULT_CASES,
                *[(method, name, option) for method in METHODS for name in PROBLEMS
                  for option in OPTIONS],
                ids="-".join),
)
def test_matches_scipy(method, name, option):
    problem = PROBLEMS[name]
    options = resolve_options(problem, option)
    t_eval = np.linspace(*problem.t_span, 201)
    theirs = scipy_solve(problem, method, t_eval, **options)
    steps = scipy_solve(problem, method, None, **options)
    ours = our_solve(problem, method, t_eval, **options)
    assert theirs.status == 0 and ours["status"] == rk.SUCCESS
    assert_equal_to_scipy(ours["t"], theirs.t, "t")
    assert_equal_to_scipy(ours["y"], theirs.y)
    assert ours["nfev"] == theirs.nfev
    assert ours["n_accepted"] == steps.t.size - 1
    assert_equal_to_scipy(ours["step_times"], steps.t[1:], "step times")
    assert_equal_to_scipy(ours["y_end"], steps.y[:, -1], "final state")


@pytest.mark.parametrize("method", METHODS)
def test_step_times_as_evaluation_times(method):
    """Evaluation times equal to step ends are read from the step that ends there."""
    problem = PROBLEMS["van_der_pol"]
    step_ends = scipy_solve(problem, method, None).t
    mixed = np.sort(np.r_[step_ends[1:-1:2], step_ends[2:-1:5] - 1e-3])
    for t_eval in (step_ends, step_ends[::3], mixed):
        theirs = scipy_solve(problem, method, t_eval)
        ours = our_solve(problem, method, t_eval)
        assert_equal_to_scipy(ours["y"], theirs.y)
        assert ours["nfev"] == theirs.nfev
    # t0 comes out as y0 exactly; at the other step ends the value is the step's
    # interpolant at x = 1, which may differ from the step's state in the last bits.
    ours = our_solve(problem, method, step_ends)
    assert np.array_equal(ours["y"][:, 0], problem.y0)
    assert_equal_to_scipy(ours["y"][:, -1], ours["y_end"], "interpolant at the end")


@pytest.mark.parametrize("points", slow_unless(lambda points: points in (1, 10_001),
                                                1, 2, 3, 10_001))
@pytest.mark.parametrize("method", METHODS)
def test_number_of_evaluation_times(method, points):
    problem = PROBLEMS["pendulum"]
    t0, t1 = problem.t_span
    t_eval = np.array([t1]) if points == 1 else np.linspace(t0, t1, points)
    theirs = scipy_solve(problem, method, t_eval)
    ours = our_solve(problem, method, t_eval)
    assert ours["y"].shape == (2, points)
    assert_equal_to_scipy(ours["y"], theirs.y)
    assert ours["nfev"] == theirs.nfev


@pytest.mark.parametrize("method", METHODS)
def test_empty_interval(method):
    problem = PROBLEMS["linear3"]
    theirs = scipy_solve(problem, method, [1.0], t_span=(1.0, 1.0))
    ours = our_solve(problem, method, np.array([1.0]), t_span=(1.0, 1.0))
    assert len(theirs.t) == 0 and ours["t"].size == 0  # scipy serves nothing here
    assert ours["nfev"] == theirs.nfev == 1
    assert ours["n_accepted"] == 0
    assert np.array_equal(ours["y_end"], problem.y0)


@pytest.mark.parametrize("method", METHODS)
def test_rtol_below_floor(method):
    """``rtol`` below ``100 eps`` is raised to it, as scipy does."""
    problem = PROBLEMS["decay"]
    t_eval = np.linspace(0.0, 0.2, 5)
    ours = our_solve(problem, method, t_eval, t_span=(0.0, 0.2), rtol=1e-18, atol=1e-12)
    with pytest.warns(UserWarning, match="is too small"):
        theirs = scipy_solve(problem, method, t_eval, t_span=(0.0, 0.2), rtol=1e-18,
                             atol=1e-12)
    assert_equal_to_scipy(ours["y"], theirs.y)
    assert ours["nfev"] == theirs.nfev


BAD_OPTIONS = {
    "max_step": ({"max_step": 0.0}, "`max_step` must be positive."),
    "first_step_sign": ({"first_step": -1.0}, "`first_step` must be positive."),
    "first_step_size": ({"first_step": 20.0}, "`first_step` exceeds bounds."),
    "atol_sign": ({"atol": -1e-6}, "`atol` must be positive."),
}


@pytest.mark.parametrize("case", list(BAD_OPTIONS))
def test_bad_solver_options_raise_as_python_control_s_run(case):
    """A diagram's run given options scipy refuses raises scipy's ``ValueError``, as
    python-control's run does (not the integrator's status)."""
    import control as ct

    import controlkit

    lag = ct.nlsys(lambda t, x, u, params: -x + u, lambda t, x, u, params: x, states=1,
                   inputs=1, outputs=1, name="lag")
    options, message = BAD_OPTIONS[case]
    T = np.linspace(0.0, 10.0, 11)
    with pytest.raises(ValueError, match=re.escape(message)):
        ct.input_output_response(lag, T, 1.0, solve_ivp_kwargs=options)
    with pytest.raises(ValueError, match=re.escape(message)):
        controlkit.input_output_response(lag, T, 1.0, solve_ivp_kwargs=options, compile=False)


def test_a_first_step_longer_than_a_sampled_data_interval_raises_scipy_s_error():
    """scipy checks ``first_step`` on each interval it integrates, between the sample
    instants: the fast engine checked it on the whole run and its integrator refused the
    interval (a RuntimeError) where the reference raises scipy's ``ValueError``."""
    import control as ct

    from controlkit import input_output_response
    from controlkit.sampled_data import interconnect

    plant = ct.ss(-1.0, 1, 1, 0, name="plant", inputs="u", outputs="y")
    gain = ct.ss([], [], [], [[-0.5]], dt=0.1, name="gain", inputs="y", outputs="u")
    loop = interconnect([plant, gain], outputs="y")
    for engine in ("fast", "python-control"):
        with pytest.raises(ValueError, match="`first_step` exceeds bounds."):
            input_output_response(loop, np.linspace(0.0, 1.0, 11), 0.0, [1.0],
                                  solve_ivp_kwargs={"first_step": 0.2}, engine=engine)


def test_an_rtol_per_state_is_left_to_python_control():
    """scipy takes an ``rtol`` per state, the integrator one number: such a run is
    python-control's own, said in a warning, with its numbers."""
    import control as ct

    import controlkit

    pair = ct.nlsys(lambda t, x, u, params: -x + u, lambda t, x, u, params: x, states=2,
                    inputs=1, outputs=2, name="pair")
    T = np.linspace(0.0, 1.0, 11)
    options = {"rtol": np.array([1e-3, 1e-4])}
    theirs = ct.input_output_response(pair, T, 1.0, solve_ivp_kwargs=options)
    with pytest.warns(UserWarning, match="an rtol per state"):
        ours = controlkit.input_output_response(pair, T, 1.0, solve_ivp_kwargs=options,
                                                compile=False)
    assert ours.engine_mode == "python-control"
    assert np.array_equal(ours.outputs, theirs.outputs)


def test_rtol_below_floor_warns_as_python_control_s_run():
    import control as ct

    import controlkit

    lag = ct.nlsys(lambda t, x, u, params: -x + u, lambda t, x, u, params: x, states=1,
                   inputs=1, outputs=1, name="lag")
    T = np.linspace(0.0, 1.0, 11)
    with pytest.warns(UserWarning, match="is too small") as theirs_warning:
        theirs = ct.input_output_response(lag, T, 1.0, solve_ivp_kwargs={"rtol": 1e-18})
    with pytest.warns(UserWarning, match="is too small") as ours_warning:
        ours = controlkit.input_output_response(lag, T, 1.0, solve_ivp_kwargs={"rtol": 1e-18},
                                                compile=False)
    assert str(ours_warning[0].message) == str(theirs_warning[0].message)
    assert np.array_equal(ours.outputs, theirs.outputs)


@pytest.mark.parametrize("method", METHODS)
def test_exact_arithmetic_is_bitwise(method):
    for name in ("decay", "van_der_pol", "chain10", "lorenz", "lag_square_input"):
        problem = PROBLEMS[name]
        t_eval = np.linspace(*problem.t_span, 101)
        theirs = scipy_solve(problem, method, t_eval)
        ours = our_solve(problem, method, t_eval)
        assert np.array_equal(ours["y"], theirs.y), name


# ------------------------------------------------------------------------------------------
# Intervals, restarted as a sampled-data loop does
# ------------------------------------------------------------------------------------------


def run_sampled_loop_ours(method, samples, t_out, closed_everywhere, gains, **options):
    """A discrete PD controller holding a torque on the pendulum, integrated interval by
    interval with :func:`rk.solve_interval` (one workspace, no allocation per interval)."""
    p = np.array([9.81, 0.05, 0.0])
    args = (p, *P.no_table())
    rhs = P.pendulum_held_torque
    y = np.array([2.5, 0.0])
    n = y.shape[0]
    y_eval = np.full((t_out.shape[0], n), np.nan)
    work = rk.make_workspace(n, 0, t_out.shape[0])
    atol = np.full(n, options.get("atol", 1e-6))
    i_eval = 0
    states = []
    for k in range(samples.shape[0] - 1):
        p[2] = -(gains[0] * y[0] + gains[1] * y[1])
        last = k == samples.shape[0] - 2
        status, i_eval = rk.solve_interval(
            None, rhs, args, rk.METHOD_INDEX[method], samples[k],
            samples[k + 1], y,
            options.get("rtol", 1e-3), atol, options.get("max_step", np.inf),
            options.get("first_step", 0.0), t_out, i_eval, closed_everywhere or last,
            y_eval, y, work, 0, False,
        )
        assert status == rk.SUCCESS
        states.append(y.copy())
    assert i_eval == t_out.shape[0]
    return y_eval.T, np.array(states)


def run_sampled_loop_scipy(method, samples, t_out, closed_everywhere, gains, **options):
    """The reference: one fresh ``solve_ivp`` per sample interval (dense output for the
    output times inside it, the solver's last state for the next interval)."""
    p = np.array([9.81, 0.05, 0.0])
    problem = P.Problem("held", P.pendulum_held_torque, np.array([2.5, 0.0]), (0, 1), p)
    fun = problem.scipy_fun()
    y = problem.y0.copy()
    outputs = []
    states = []
    served = np.zeros(t_out.shape[0], dtype=bool)
    for k in range(samples.shape[0] - 1):
        p[2] = -(gains[0] * y[0] + gains[1] * y[1])
        t_k, t_next = samples[k], samples[k + 1]
        last = k == samples.shape[0] - 2
        inside = (t_out >= t_k) & ((t_out <= t_next) if (closed_everywhere or last)
                                   else (t_out < t_next)) & ~served
        solution = scipy.integrate.solve_ivp(fun, (t_k, t_next), y, method=method,
                                             dense_output=True, **options)
        assert solution.status == 0
        if inside.any():
            outputs.append(solution.sol(t_out[inside]))
        served |= inside
        y = solution.y[:, -1].copy()
        states.append(y.copy())
    return np.hstack(outputs), np.array(states)


@pytest.mark.parametrize(
    ("method", "option", "closed_everywhere"),
    slow_unless(lambda case: case[1:] in {("default", False), ("tight", True),
                                          ("first_step", False)},
                *[(method, option, closed) for method in METHODS
                  for option in ("default", "tight", "first_step") for closed in (False, True)],
                ids=lambda case: "-".join(map(str, case))),
)
def test_sample_intervals(method, option, closed_everywhere):
    """Half-open ``[t_k, t_k+1)`` (the next interval serves ``t_k+1``, at its start) or
    closed intervals (the interval ending at ``t_k+1`` serves it): both as scipy would."""
    options = {"default": {}, "tight": {"rtol": 1e-8, "atol": 1e-10},
               "first_step": {"first_step": 1e-2}}[option]
    samples = np.linspace(0.0, 4.0, 41)  # Ts = 0.1
    t_out = np.linspace(0.0, 4.0, 161)  # every 4th output time is a sample instant
    gains = (8.0, 1.5)
    ours, our_states = run_sampled_loop_ours(method, samples, t_out, closed_everywhere,
                                             gains, **options)
    theirs, their_states = run_sampled_loop_scipy(method, samples, t_out,
                                                  closed_everywhere, gains, **options)
    assert_equal_to_scipy(our_states, their_states, "states at the sample instants")
    assert_equal_to_scipy(ours, theirs)
    # Half-open: an output at a sample instant is the state the interval starts from.
    if not closed_everywhere:
        at_samples = ours[:, 4:-1:4].T
        assert np.array_equal(at_samples, our_states[:-1])


# ------------------------------------------------------------------------------------------
# python-control's own call
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", slow_unless(lambda method: method == "RK45", *METHODS))
def test_python_control_input_output_response(method):
    """``control.input_output_response`` with a square wave sampled on ``T`` (interpolated
    linearly between samples) gives what :func:`rk_problems.solve_ivp` gives."""
    control = pytest.importorskip("control")
    problem = PROBLEMS["lag_square_input"]
    tau = problem.p[0]

    def updfcn(t, x, u, params):
        return np.array([(u[0] - x[0]) / tau])

    system = control.nlsys(updfcn, None, inputs=1, states=1)
    response = control.input_output_response(
        system, problem.T, problem.U[0], problem.y0, solve_ivp_method=method
    )
    ours = our_solve(problem, method, problem.T)
    assert_equal_to_scipy(ours["y"], response.states)


# ------------------------------------------------------------------------------------------
# Failures
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_step_too_small(method):
    problem = P.Problem("blow_up", P.blow_up, np.array([1.0]), (0.0, 2.0), np.zeros(1))
    theirs = scipy_solve(problem, method, None)
    ours = our_solve(problem, method, None)
    assert theirs.status == -1 and theirs.message == rk.STATUS_MESSAGES[rk.STEP_TOO_SMALL]
    assert ours["status"] == rk.STEP_TOO_SMALL and not ours["success"]
    assert ours["message"] == theirs.message
    assert ours["t_reached"] == theirs.t[-1]
    assert ours["nfev"] == theirs.nfev
    assert_equal_to_scipy(ours["y_end"], theirs.y[:, -1])


@pytest.mark.parametrize("method", METHODS)
def test_nan_derivative_later(method):
    """scipy rejects and shrinks until the step is too small; we stop at the same time
    and evaluation count but say why: the derivative is not finite."""
    problem = P.Problem("nan_after", P.nan_after, np.array([1.0]), (0.0, 2.0),
                        np.array([0.5]))
    t_eval = np.linspace(0.0, 2.0, 21)
    theirs = scipy_solve(problem, method, t_eval)
    ours = our_solve(problem, method, t_eval)
    assert theirs.status == -1
    assert ours["status"] == rk.NON_FINITE
    assert ours["nfev"] == theirs.nfev
    assert_equal_to_scipy(ours["y"], theirs.y)  # the times served before the failure
    assert ours["t_reached"] <= 0.5 < ours["t_reached"] + 1e-12
    assert np.isfinite(ours["y_end"]).all()


@pytest.mark.parametrize("method", METHODS)
def test_nan_derivative_at_start(method):
    """scipy never returns here (its first step is NaN and NaN is never below the
    smallest step); we return at once with one evaluation."""
    problem = P.Problem("nan_always", P.nan_always, np.array([1.0]), (0.0, 1.0),
                        np.zeros(1))
    ours = our_solve(problem, method, np.array([0.0, 1.0]))
    assert ours["status"] == rk.NON_FINITE
    assert ours["nfev"] == 1 and ours["t_reached"] == 0.0
    assert ours["t"].size == 0


@pytest.mark.parametrize("method", METHODS)
def test_state_overflow(method):
    """``y' = 1e308``: the stages stay finite but their sums overflow. scipy reports
    success with ``inf``/NaN values (with RK45 every value is NaN, even at ``t = 0``: the
    interpolant's coefficients overflow); we stop at the last finite state and serve
    only finite values."""
    problem = P.Problem("huge", P.huge_constant, np.array([0.0]), (0.0, 3.0), np.zeros(1))
    t_eval = np.linspace(0.0, 3.0, 31)
    with np.errstate(over="ignore", invalid="ignore"):
        theirs = scipy_solve(problem, method, t_eval)
    ours = our_solve(problem, method, t_eval)
    if method == "DOP853":  # its first step is 0 (d1 = inf): both fail at once
        assert theirs.status == -1 and ours["status"] == rk.NON_FINITE
        assert ours["nfev"] == theirs.nfev
    else:
        assert theirs.status == 0 and not np.isfinite(theirs.y).all()
        assert ours["status"] == rk.NON_FINITE
    served = ours["t"].size
    assert served < 31 and np.isfinite(ours["y"]).all()
    assert_equal_to_scipy(ours["y"], np.reshape(theirs.y, (1, -1))[:, :served])
    assert np.isfinite(ours["y_end"]).all() and ours["t_reached"] < 3.0


if _jit.available():
    numba = _jit.numba_module()

    @numba.njit
    def _compiled_interval(machine, args, method, t0, t1, y0, rtol, atol, max_step,
                           first_step, t_eval, i_eval, closed_right, y_eval, y_end, work,
                           budget, resume):
        """Generated code as controlkit writes it: the right-hand side a global (a
        compile-time constant), the step machine compiled once and kept in the store,
        received as an argument and called through a pointer."""
        return rk.solve_interval(
            machine, P.van_der_pol, args, method, t0, t1, y0, rtol, atol, max_step,
            first_step, t_eval, i_eval, closed_right, y_eval, y_end, work, budget, resume,
        )

    @numba.njit
    def _caller_machine_linked(y0, t_eval, y_eval, work):
        """Generated code with the machine linked in: the right-hand side is a global and
        the machine's code compiled into this function."""
        p = np.array([2.0])
        args = (p, np.zeros(2), np.zeros((0, 2)))
        y_end = np.empty(2)
        return rk.solve_interval(
            rk.machine, P.van_der_pol, args, 2, 0.0, 20.0, y0, 1e-3, np.full(2, 1e-6),
            np.inf, 0.0, t_eval, 0, True, y_eval, y_end, work, 0, False,
        )

needs_numba = pytest.mark.skipif(not _jit.available(), reason="needs numba")
#: The two ways of running the loop around the step machine.
WAYS = ["python", pytest.param("compiled", marks=needs_numba)]


def interval_call(way, budget=0, resume=False, **changes):
    """:func:`rk.solve_interval` on van der Pol over [0, 1] with some arguments changed:
    ``(status, next_eval, y_eval, work)``."""
    problem = PROBLEMS["van_der_pol"]
    call = {
        "t0": 0.0, "t1": 1.0, "y0": problem.y0.copy(), "rtol": 1e-3, "atol": np.full(2, 1e-6),
        "max_step": np.inf, "first_step": 0.0, "t_eval": np.linspace(0.0, 1.0, 5),
        "i_eval": 0, "closed_right": True, "work": rk.make_workspace(2, 0, 5),
        "method": rk.METHOD_INDEX["RK45"],
    }
    call.update(changes)
    y_eval = changes.get("y_eval", np.zeros((call["t_eval"].shape[0], 2)))
    arguments = (problem.args, call["method"], call["t0"], call["t1"], call["y0"],
                 call["rtol"], call["atol"], call["max_step"], call["first_step"],
                 call["t_eval"], call["i_eval"], call["closed_right"], y_eval, np.zeros(2),
                 call["work"])
    if way == "compiled":
        status, next_eval = _compiled_interval(store.step_machine(), *arguments, budget,
                                               resume)
    else:
        status, next_eval = rk.solve_interval(None, P.van_der_pol, *arguments, budget, resume)
    return int(status), int(next_eval), y_eval, call["work"]


@pytest.mark.parametrize("way", WAYS)
@pytest.mark.parametrize(
    "changes",
    [
        {"max_step": 0.0},
        {"max_step": np.nan},
        {"first_step": -1.0},
        {"first_step": 2.0},
        {"atol": np.full(2, -1.0)},
        {"atol": np.ones(3)},
        {"t1": np.inf},
        {"t1": -1.0, "t_eval": np.zeros(0)},  # (forward only: the engine never goes back)
        {"rtol": np.nan},
        {"t_eval": np.array([0.0, 0.5, 0.4, 1.0])},
        {"t_eval": np.array([-0.1, 0.5])},
        {"i_eval": 7},
        {"work": rk.make_workspace(3, 0, 0)},
        {"y0": np.ones(3)},
        {"method": 3},
    ],
    ids=lambda changes: next(iter(changes)),
)
def test_bad_arguments_give_the_invalid_argument_status(changes, way):
    status, next_eval, _, _ = interval_call(way, **changes)
    assert status == rk.INVALID_ARGUMENT
    assert next_eval == changes.get("i_eval", 0)


@pytest.mark.parametrize("way", WAYS)
def test_a_zero_error_scale_stops_where_scipy_never_ends(way):
    # atol=0 and a state at 0: solve_ivp's error scale is 0, its starting step NaN, and its
    # trials go on at NaN forever; the machine stops at once, compiled code dividing by
    # the zero scale as numpy does (it raised ZeroDivisionError, which a C function prints
    # and drops, again and again)
    status, next_eval, _, _ = interval_call(way, atol=np.zeros(2), y0=np.zeros(2))
    assert (status, next_eval) == (rk.STEP_NOT_A_NUMBER, 0)


def test_a_zero_error_scale_is_said_where_python_control_would_never_end():
    lag = ct.nlsys(lambda t, x, u, p: -x + u, None, inputs=1, states=1, outputs=1, name="lag")
    with pytest.raises(RuntimeError, match=r"'lag': the step size of RK45 is not a number "
                                           r"after t = 0 s: .* give solve_ivp_kwargs an atol"):
        controlkit.input_output_response(lag, np.linspace(0.0, 1.0, 11), 1.0, [0.0],
                                         solve_ivp_kwargs={"atol": 0.0}, compile=False)


@pytest.mark.parametrize("way", WAYS)
def test_status_success_and_evaluation_index(way):
    status, next_eval, _, _ = interval_call(way)
    assert (status, next_eval) == (rk.SUCCESS, 5)
    status, next_eval, _, _ = interval_call(way, closed_right=False)
    assert (status, next_eval) == (rk.SUCCESS, 4)  # t = 1 left to the next interval


@pytest.mark.parametrize("way", WAYS)
@pytest.mark.parametrize("budget", [1, 7, 50])
def test_an_interval_paused_and_resumed_gives_the_same_bits(way, budget):
    # a long run returns to Python every so many evaluations (progress, Ctrl-C): the
    # interval goes on from its workspace, with the steps of one call
    t_eval = np.linspace(0.0, 20.0, 41)
    whole = interval_call(way, t1=20.0, t_eval=t_eval, work=rk.make_workspace(2, 0, 41))
    work, y_eval = rk.make_workspace(2, 0, 41), np.zeros((41, 2))
    status, pauses = rk.PAUSED, -1
    while status == rk.PAUSED:
        status, next_eval, _, _ = interval_call(way, budget, pauses >= 0, t1=20.0,
                                                t_eval=t_eval, work=work, y_eval=y_eval)
        pauses += 1
    assert (status, next_eval) == (rk.SUCCESS, 41) == whole[:2]
    assert pauses == whole[3].ints[rk.NFEV] // budget
    np.testing.assert_array_equal(y_eval, whole[2])
    assert work.ints[rk.NFEV] == whole[3].ints[rk.NFEV]


@needs_numba
@pytest.mark.parametrize("caller", slow_unless(lambda caller: caller == "by_pointer",
                                               "by_pointer", "linked"))
def test_compiled_caller_with_global_rhs(caller):
    """A compiled caller holding the right-hand side as a global (the machine linked
    into it: slow to compile; or by pointer, as controlkit's modules call the step
    machine of the store) equals :func:`rk_problems.solve_ivp` run as Python."""
    problem = PROBLEMS["van_der_pol"]
    t_eval = np.linspace(0.0, 20.0, 51)
    y_eval = np.zeros((51, 2))
    work = rk.make_workspace(2, 0, 51)
    if caller == "linked":
        status, served = _caller_machine_linked(problem.y0, t_eval, y_eval, work)
    else:
        status, served = _compiled_interval(
            store.step_machine(), (np.array([2.0]), np.zeros(2), np.zeros((0, 2))), 2, 0.0,
            20.0, problem.y0, 1e-3, np.full(2, 1e-6), np.inf, 0.0, t_eval, 0, True, y_eval,
            np.empty(2), work, 0, False)
    ours = our_solve(problem, "DOP853", t_eval)
    assert (status, served) == (rk.SUCCESS, 51)
    assert np.array_equal(y_eval.T, ours["y"])
    assert work.ints[rk.NFEV] == ours["nfev"]


@needs_numba
def test_the_step_machine_is_compiled_with_a_random_id():
    """The machine is compiled under controlkit._jit's random function ids (numba issue
    10486): its C function's symbol holds a 128-bit number (``v<id>`` in numba's
    mangling), not a per-process counter."""
    name = store.step_machine().native_name
    ids = [int(found) for found in re.findall(r"v(\d+)B", name)]
    assert ids and all(i > 2**64 for i in ids), name


def test_plain_python_equals_scipy():
    """Without numba the same package runs as Python and still takes scipy's steps."""
    script = textwrap.dedent(
        """
        import numpy as np, scipy.integrate, rk_problems as P
        from controlkit.engines.fast import rk
        from controlkit import _jit
        assert not _jit.available()
        problem = P.make_problems()["mass_spring_input"]
        t_eval = np.linspace(*problem.t_span, 31)
        for method in ("RK23", "RK45", "DOP853"):
            theirs = scipy.integrate.solve_ivp(problem.scipy_fun(), problem.t_span,
                                               problem.y0, method=method, t_eval=t_eval)
            ours = P.solve_ivp(problem.rhs, problem.t_span, problem.y0, method=method,
                                t_eval=t_eval, args=problem.args)
            assert np.array_equal(ours["y"], theirs.y), method
            assert ours["nfev"] == theirs.nfev, method
        import sys
        assert "numba" not in sys.modules
        print("same")
        """
    )
    environment = dict(os.environ, CONTROLKIT_DISABLE_NUMBA="1")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            cwd=os.path.dirname(os.path.abspath(__file__)), env=environment,
                            timeout=600)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "same"


def test_tableaux_are_scipy_s():
    """The coefficients are scipy's own (read from its method classes), laid out as the
    machine reads them: DOP853's 16 rows are the 12 stages, the weights as the step's last
    stage, and the dense output's three extra stages."""
    import scipy.integrate

    for name, ours in rk.METHODS.items():
        theirs = getattr(scipy.integrate, name)
        S = theirs.n_stages
        assert ours.n_stages == S and ours.estimator_order == theirs.error_estimator_order
        assert np.array_equal(ours.C[:S], theirs.C)
        assert np.array_equal(ours.A[:S, : theirs.A.shape[1]], theirs.A)
        assert np.array_equal(ours.B, theirs.B)
        assert not ours.A[:S].any(axis=0)[S - 1 :].any()  # strictly lower triangular
        for array in (ours.C, ours.A, ours.B, ours.E, ours.E_low, ours.dense):
            assert array.dtype == np.float64 and array.flags.c_contiguous
        if name == "DOP853":
            assert ours.n_rows == 16 and ours.A.shape == (16, 16) and ours.C[S] == 1.0
            assert np.array_equal(ours.A[S, :S], theirs.B) and not ours.A[S, S:].any()
            assert np.array_equal(ours.A[S + 1 :], theirs.A_EXTRA)
            assert np.array_equal(ours.C[S + 1 :], theirs.C_EXTRA)
            assert np.array_equal(ours.E, theirs.E5) and np.array_equal(ours.E_low, theirs.E3)
            assert np.array_equal(ours.dense, theirs.D)
        else:
            assert ours.n_rows == S + 1 and ours.A.shape == (S, S)
            assert np.array_equal(ours.E, theirs.E) and np.array_equal(ours.dense, theirs.P)
            assert ours.E_low.shape == (S + 1,) and not ours.E_low.any()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            assert ours.error_exponent == -1 / (theirs.error_estimator_order + 1)


# ------------------------------------------------------------------------------------------
# Stiffness: Hairer's test stops an explicit run that stability holds down
# ------------------------------------------------------------------------------------------

STIFF_METHODS = [m for m in METHODS if rk.TABLEAUX[rk.METHOD_INDEX[m]].stiffness_bound > 0]


def test_stiffness_test_where_the_last_stage_is_at_t_plus_h():
    assert STIFF_METHODS == ["RK45", "DOP853"]
    for method in METHODS:
        tableau = rk.TABLEAUX[rk.METHOD_INDEX[method]]
        if tableau.stiffness_bound:
            assert tableau.C[tableau.n_stages - 1] == 1.0


@pytest.mark.parametrize("method", STIFF_METHODS)
def test_stiffness_estimate_is_h_lambda(method):
    # y' = -p y: k_S - k_{S-1} = -p (y_new - y_{S-1}) exactly, so the estimate is h p
    p = 2000.0
    problem = P.Problem("decay", P.decay, np.array([1.0]), (0.0, 0.02), np.array([p]))
    ours = our_solve(problem, method, None)
    assert ours["success"]
    h_last = np.diff(ours["step_times"])[-1]
    assert ours["stiffness"] == pytest.approx(h_last * p, rel=1e-6)


@pytest.mark.parametrize("method", STIFF_METHODS)
def test_stiff_run_stops_early_with_the_projected_steps(method):
    # eigenvalue -1e6 over 100 s: about 3e7 explicit steps (hours in scipy)
    problem = P.Problem("stiff", P.stiffish, np.array([1.0, 1.0]), (0.0, 100.0),
                        np.array([1e6]))
    ours = our_solve(problem, method, None)
    assert ours["status"] == rk.STIFF and not ours["success"]
    assert ours["message"] == rk.STATUS_MESSAGES[rk.STIFF]
    assert "BDF" in ours["message"]
    assert rk.STIFF_STEPS_BEFORE_PROJECTING <= ours["n_accepted"] < 3 * \
        rk.STIFF_STEPS_BEFORE_PROJECTING
    assert ours["projected_steps"] > rk.STIFF_STEP_BUDGET
    # the projection is the pace so far carried to the end of the span
    expected = ours["n_accepted"] * 100.0 / ours["t_reached"]
    assert ours["projected_steps"] == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize("method", STIFF_METHODS)
def test_stiff_run_within_the_budget_goes_on_as_scipy(method):
    # a lag of 0.1 ms tracking sin t: stiff all along, some 10^4 steps over 1 s
    T = np.linspace(0.0, 10000.0, 10001)
    problem = P.Problem("fast_lag", P.lag_with_input, np.array([0.0]), (0.0, 1.0),
                        np.array([1e-4, 0.0]), T, np.ascontiguousarray(np.sin(T)[None, :]))
    t_eval = np.linspace(0.0, 1.0, 11)
    ours = our_solve(problem, method, t_eval)
    theirs = scipy_solve(problem, method, t_eval)
    assert ours["success"] and ours["n_accepted"] > rk.STIFF_STEPS_BEFORE_PROJECTING
    assert ours["nfev"] == theirs.nfev
    assert_equal_to_scipy(ours["y"], theirs.y)
    # the test was watching: over 10^4 s (over 10^7 steps) the same problem stops
    longer = our_solve(problem, method, None, t_span=(0.0, 10000.0))
    assert longer["status"] == rk.STIFF
    assert longer["projected_steps"] > rk.STIFF_STEP_BUDGET > 1000 * ours["n_accepted"]
