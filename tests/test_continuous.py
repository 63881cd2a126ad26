"""Continuous and sampled-data diagrams on the fast engine against their references.

Continuous diagrams are compared with ``control.input_output_response`` (RK45, RK23,
DOP853 and the stiff methods), sampled-data diagrams with a plain reference written
here from the semantics alone (solve_ivp between sample instants, discrete outputs
held), at tight tolerances.
"""

import math
import re
import warnings

import control as ct
import numpy as np
import pytest
import scipy.integrate
from continuous_diagrams import CONTINUOUS, MIXED, dc_motor, observer, servo_pi_discrete
from idiom_diagrams import expected_tier

import controlkit
from controlkit.engines.fast import StiffProblem, explain
from controlkit.engines.fast.continuous import run_continuous

TIGHT = {"rtol": 1e-10, "atol": 1e-12}


def scaled_error(ours, ref):
    """The largest difference relative to each output's size (at least 1)."""
    scale = np.maximum(1.0, np.abs(ref).max(axis=-1, keepdims=True))
    return float(np.abs((ours - ref) / scale).max())


def fast(loop, T, U, X0=0, compile=False, **kwargs):
    """The engine's response (as Python unless ``compile`` says otherwise: the rule leaves
    a new diagram's short run to python-control)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no fallback to python-control allowed
        return controlkit.input_output_response(loop, T, U, X0, compile=compile, **kwargs)


@pytest.mark.parametrize("method", ["RK45", "RK23", "DOP853"])
@pytest.mark.parametrize("name", sorted(CONTINUOUS))
def test_continuous_diagram_equals_python_control(name, method):
    loop, T, X0, U = CONTINUOUS[name]()
    assert [row.tier for row in explain(loop)] == [expected_tier(name, row.name)
                                                   for row in explain(loop)]
    ref = ct.input_output_response(loop, T, U, X0, solve_ivp_method=method)
    ours = fast(loop, T, U, X0, solve_ivp_method=method)
    assert ours.outputs.shape == ref.outputs.shape and ours.states.shape == ref.states.shape
    assert scaled_error(ours.y, ref.y) <= 1e-9
    assert scaled_error(ours.x, ref.x) <= 1e-9
    np.testing.assert_array_equal(ours.time, ref.time)


def test_lti_kernels_make_python_control_s_products_to_the_bit():
    # python-control's LTI block computes A @ x + B @ u with numpy, whose BLAS sums a
    # row in its own order with fused multiply-adds: a plain loop differs in the last
    # bits for dense rows (2 of 3 random 3-state blocks did), and a loose-tolerance
    # integration carries that to 1e-9 (the fuzzer's seed 882)
    from controlkit import _jit
    from controlkit.kernels import lti

    update, output = (_jit.python_function(k) for k in (lti.lti_update, lti.lti_output))
    rng = np.random.default_rng(7)
    for n, m, q in ((1, 1, 1), (2, 1, 1), (3, 1, 2), (4, 2, 1), (6, 3, 3), (0, 2, 1)):
        for _ in range(50):
            block = ct.ss(*(rng.normal(size=shape) for shape in ((n, n), (n, m), (q, n),
                                                                   (q, m))))
            x, u = rng.normal(size=n), rng.normal(size=m)
            p = lti.pack(block.A, block.B, block.C, block.D)
            if n:
                assert update(0.0, x, u, p, np.empty(n)).tobytes() == \
                    block.updfcn(0.0, x, u, {}).tobytes()
            assert output(0.0, x, u, p, np.empty(q)).tobytes() == \
                block.outfcn(0.0, x, u, {}).tobytes()


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_a_dense_lti_plant_gives_python_control_s_numbers_to_the_bit(method):
    # the fuzzer's seed 882: a PI with anti-windup, a dense 3-state plant, a gain; as
    # Python and compiled, equal to python-control's to the last bit (1e-9 apart before)
    def pi_rate(t, x, u, params):
        command = 1.3 * u[0] + 0.7 * x[0]
        return [u[0] + np.clip(command, -2.0, 2.0) - command]

    controller = ct.nlsys(pi_rate, lambda t, x, u, params: np.clip(
        1.3 * u[0] + 0.7 * x[0], -2.0, 2.0), inputs="e", outputs="c", states=1, name="pi")
    plant = ct.ss([[-2.17, 0.79, -0.17], [0.0, -1.77, 0.9], [0.0, 0.0, -2.04]],
                  [[1.39], [0.3], [0.89]], [[-0.36, 0.43, 0.84]], [[0.0]], name="plant",
                  inputs="c", outputs="y")
    gain = ct.ss([], [], [], [[2.78]], name="gain", inputs="y", outputs="z")
    loop = ct.interconnect([controller, plant, gain], inputs="e", outputs="z")
    T = np.linspace(0.0, 6.26, 39)
    U = np.sin(T)
    X0 = [-0.408, 0.137, 0.139, 0.316]
    ref = ct.input_output_response(loop, T, U, X0, solve_ivp_method=method)
    for compile in (False, True):
        ours = fast(loop, T, U, X0, solve_ivp_method=method, compile=compile)
        assert ours.y.tobytes() == ref.y.tobytes() and ours.x.tobytes() == ref.x.tobytes()


def test_sums_of_three_signals_give_python_control_s_numbers_to_the_bit():
    # python-control makes every block input as connect_map @ outputs + input_map @ u and
    # the outputs as output_map @ [outputs, inputs]: numpy's BLAS sums a row of three
    # terms in an order that depends on the whole matrix (1.4e-14 apart before)
    rng = np.random.default_rng(9)
    lags = [ct.ss([[-1.0 - k]], [[1.0]], [[rng.normal()]], [[0.0]], name=name, inputs="u",
                  outputs="y") for k, name in enumerate("abc")]
    plant = ct.nlsys(lambda t, x, u, params: -0.5 * x + u, lambda t, x, u, params: x,
                     states=1, name="p", inputs="u", outputs="y")
    loop = ct.interconnect([*lags, plant], inplist=[["a.u", "b.u", "c.u"]], inputs="r",
                           outlist=[["a.y", "b.y", "-c.y"], "p.y"], outputs=["s", "y"],
                           connections=[["p.u", "a.y", "b.y", "-c.y"]])
    T = np.linspace(0.0, 5.0, 51)
    X0 = rng.normal(size=4)
    ref = ct.input_output_response(loop, T, np.sin(T), X0)
    for compile in (False, True):
        ours = fast(loop, T, np.sin(T), X0, compile=compile)
        assert ours.y.tobytes() == ref.y.tobytes() and ours.x.tobytes() == ref.x.tobytes()


@pytest.mark.parametrize("compile", [False, True])
def test_an_infinite_connection_gain_is_written_as_a_number(compile):
    # a gain's repr is written into the module's text; an infinity's ("inf") named
    # nothing, and the run died of a NameError instead of saying the loop diverged
    lag = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="a", inputs="u", outputs="y")
    plant = ct.nlsys(lambda t, x, u, params: -x + u, lambda t, x, u, params: x, states=1,
                     name="q", inputs="u", outputs="y")
    loop = ct.interconnect([lag, plant], connections=[["q.u", ("a", "y", float("inf"))]],
                           inplist=["a.u"], outlist=["q.y"], inputs="r", outputs="y")
    T = np.linspace(0.0, 3.0, 31)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (q's lambda runs as Python when compile=True)
        with pytest.raises(FloatingPointError, match=r"\['a', 'q'\] became non-finite"):
            controlkit.input_output_response(loop, T, np.ones(31), compile=compile)


def test_compile_true_runs_a_short_continuous_diagram_compiled():
    loop, T, X0, U = CONTINUOUS["car_pi"]()
    U = np.broadcast_to(U, (loop.ninputs, T.size))
    modes = [run_continuous(loop, T, U, X0, compile=True).engine_mode for _ in range(2)]
    assert modes == ["compiled", "compiled"]


@pytest.fixture
def differing_compiled(monkeypatch):
    """The compiled continuous module made to differ from Python (its integrator's stages
    and served states scaled by 1 + 1e-6 after each compiled piece), in a process that
    has checked and refused no module yet."""
    from controlkit.engines.fast import continuous, run

    def differing(job, args):
        compiled(job, args)
        buffers = args[4]  # (ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work)
        buffers[9].stages[...] *= 1.0 + 1e-6
        buffers[7][...] *= 1.0 + 1e-6  # the states served at the output times

    compiled = continuous._run_compiled
    monkeypatch.setattr(continuous, "_run_compiled", differing)
    monkeypatch.setattr(run, "DIFFERS", {})
    checked = set(run.CHECKED)
    run.CHECKED.clear()
    yield
    run.CHECKED.update(checked)


def test_a_compiled_module_that_differs_inside_its_first_step_is_left_for_python(
        differing_compiled):
    # the check piece is short (32 evaluations): for a continuous loop it may end inside
    # the integrator's first step, writing no output and no state. A compiled module whose
    # right-hand side differs from Python's is then seen in the integrator's stages, which
    # are compared too (they once were not, and such a module went on compiled)
    loop, T, X0, U = CONTINUOUS["mrac"]()
    U = np.broadcast_to(U, (loop.ninputs, T.size))
    ref = ct.input_output_response(loop, T, U, X0)
    with pytest.warns(UserWarning, match="its compiled numbers differ from Python's") as said:
        ours = controlkit.input_output_response(loop, T, U, X0, compile=True)
    assert ours.engine_mode == "python"
    assert scaled_error(ours.y, ref.y) <= 1e-9
    assert said[0].filename == __file__  # the line that called, not one of the engine's


def test_a_rejected_compiled_piece_leaves_none_of_its_states_behind(differing_compiled):
    # the integrator serves states at the output times as it steps and writes them as
    # outputs when its interval ends; a compiled piece rejected by the check had served
    # some over Python's (from the same start), and one of them once stayed in the result
    loop, _, X0, _ = CONTINUOUS["pi_first_order"]()
    T = np.linspace(0.0, 10.0, 2001)
    U = np.ones((loop.ninputs, T.size))
    ref = ct.input_output_response(loop, T, U, X0)
    with pytest.warns(UserWarning, match=r"its compiled numbers differ from Python's after "
                                         r"t = 0 s; first at t = [\d.e-]+ s, in the state "
                                         r"of '\w+'"):  # (the served states say which)
        ours = controlkit.input_output_response(loop, T, U, X0, compile=True)
    assert ours.engine_mode == "python"
    assert scaled_error(ours.y, ref.y) <= 1e-9


def test_many_runs_go_on_as_python_when_the_first_run_s_check_rejects_the_module(
        differing_compiled):
    # the first of many runs is compiled and checked alone; rejected, the others once went
    # on compiled all the same (with the numbers the check had refused)
    loop, T, X0, U = CONTINUOUS["mrac"]()
    U = np.broadcast_to(U, (loop.ninputs, T.size))
    X0s = np.array([X0, 0.5 * np.asarray(X0, dtype=float) + 0.1])
    with pytest.warns(UserWarning, match="its compiled numbers differ from Python's"):
        ours = controlkit.input_output_response(loop, T, U, X0s, compile=True)
    for resp, x0 in zip(ours, X0s, strict=True):
        assert resp.engine_mode == "python"
        assert scaled_error(resp.y, ct.input_output_response(loop, T, U, x0).y) <= 1e-9


@pytest.mark.parametrize("method", ["LSODA", "BDF", "Radau"])
def test_stiff_methods_run_scipy_on_the_diagrams_right_hand_side(method):
    loop, T, X0, U = dc_motor()  # a 1 ms electrical pole under a 100 ms mechanical one
    ref = ct.input_output_response(loop, T, U, X0, solve_ivp_method=method)
    ours = fast(loop, T, U, X0, solve_ivp_method=method)
    assert scaled_error(ours.y, ref.y) <= 1e-9
    with pytest.warns(UserWarning, match=rf"running '.*' as Python: {method} is scipy's"):
        asked = controlkit.input_output_response(loop, T, U, X0, solve_ivp_method=method,
                                                 compile=True)  # (asked for: said why not)
    assert asked.engine_mode == "python"
    with pytest.warns(UserWarning, match=rf"running '.*' as Python: {method} is scipy's"):
        batch = controlkit.input_output_response(loop, T, U, [X0, X0], solve_ivp_method=method,
                                                 compile=True)  # (many runs: the same)
    assert [resp.engine_mode for resp in batch] == ["python", "python"]


def test_python_control_options_and_result_flags_are_kept():
    loop, T, X0, U = CONTINUOUS["pendulum"]()
    t_eval = np.linspace(0.2, 4.0, 7)
    options = dict(evaluation_times=t_eval, solve_ivp_kwargs={"rtol": 1e-6, "max_step": 0.1},
                   return_states=True, transpose=True, params={"kp": 15.0})
    ref = ct.input_output_response(loop, T, U, X0, **options)
    ours = fast(loop, T, U, X0, **options)
    t, y, x = ours
    assert scaled_error(y.T, ref.y) <= 1e-9 and x.shape == ref.x.T.shape
    np.testing.assert_array_equal(t, t_eval)


@pytest.mark.parametrize("Ts", [0.0, 0.05])
def test_a_block_that_cannot_compile_runs_as_python_inside_the_loop(Ts):
    # a damper written where its source cannot be read (exec, as some tools generate code):
    # it runs as Python inside the compiled loop, with python-control's numbers
    scope = {"np": np}
    exec("def damper(t, x, u, params):\n    return -params['c'] * np.tanh(u[0])\n", scope)
    damper = ct.nlsys(None, scope["damper"], inputs="w", outputs="f_d", params={"c": 0.5},
                      name="damper")
    mass = ct.ss([[0.0, 1.0], [-4.0, 0.0]], [[0.0], [1.0]], np.eye(2), 0.0,
                 inputs="f", outputs=["q", "w"], name="mass")
    push = ct.summing_junction(["u", "f_d"], "f", name="push")
    blocks = [mass, damper, push]
    if Ts:  # the damper's force as a sampled controller would apply it
        blocks[1] = ct.nlsys(None, scope["damper"], inputs="w", outputs="f_d",
                             params={"c": 0.5}, name="damper", dt=Ts)
    loop = controlkit.interconnect(blocks, inputs="u", outputs=["q", "w"])
    assert {row.name: row.tier for row in explain(loop)}["damper"] == "python"
    T = np.linspace(0.0, 5.0, 101)
    if Ts == 0:
        ours = fast(loop, T, 1.0, [1.0, 0.0])
        ref = ct.input_output_response(loop, T, 1.0, [1.0, 0.0])
        assert scaled_error(ours.y, ref.y) <= 1e-9
    else:
        ours = fast(loop, T, 1.0, [1.0, 0.0], solve_ivp_kwargs=TIGHT)
        Y, X = reference(loop, T, [1.0, 0.0], np.ones((1, T.size)))
        assert scaled_error(ours.y, Y) <= 1e-8 and scaled_error(ours.x, X) <= 1e-8


def test_a_list_of_systems_gives_a_list_of_responses():
    systems = [CONTINUOUS["pi_first_order"]()[0], CONTINUOUS["two_tanks"]()[0]]
    T = np.linspace(0.0, 5.0, 11)
    responses = fast(systems, T, 1.0, 0.0)
    assert len(responses) == 2
    for sys, resp in zip(systems, responses, strict=True):
        ref = ct.input_output_response(sys, T, 1.0, 0.0)
        assert scaled_error(resp.y, ref.y) <= 1e-9


# ---------------------------------------------------------------- sampled-data diagrams

def reference(sys, T, X0, U, rtol=1e-10, atol=1e-12):
    """The sampled-data semantics in plain Python, from python-control's own functions.

    At each instant k h: every block's output (a discrete block that fires computes it,
    the others give the output they hold), then the firing blocks' state updates, then
    solve_ivp over the continuous states to the next instant with the outputs held.
    States at an instant are reported before the update.
    """
    h = min(s.dt for s in sys.syslist if s.dt not in (None, 0, True))
    n = int(np.floor((T[-1] - T[0]) / h * (1 + 1e-12))) + 1
    instants = T[0] + np.arange(n) * h
    offsets = np.cumsum([0] + [s.nstates for s in sys.syslist])
    inputs = np.cumsum([0] + [s.ninputs for s in sys.syslist])
    outs = np.cumsum([0] + [s.noutputs for s in sys.syslist])
    discrete = [s.dt not in (None, 0) for s in sys.syslist]
    every = [round(s.dt / h) if d else 0 for s, d in zip(sys.syslist, discrete, strict=True)]
    held = [None] * len(sys.syslist)

    def u_at(t):
        return np.array([np.interp(t, T, row) for row in U]) if len(U) else np.zeros(0)

    def sweep(t, x, firing):
        u = u_at(t)
        ulist = sys.input_map @ u
        ylist = np.zeros(sys.connect_map.shape[1])
        for _ in range(len(sys.syslist) + 1):
            for i, s in enumerate(sys.syslist):
                if discrete[i] and i not in firing:
                    y = held[i]
                else:
                    y = s._out(t, x[offsets[i]:offsets[i + 1]], ulist[inputs[i]:inputs[i + 1]])
                ylist[outs[i]:outs[i + 1]] = y
            ulist = sys.connect_map @ ylist + sys.input_map @ u
        return u, ulist, ylist

    def outputs_at(t, x, firing):
        u, ulist, ylist = sweep(t, x, firing)
        return sys.output_map @ np.concatenate([ylist, ulist])

    cont = [i for i, s in enumerate(sys.syslist) if s.dt == 0 and s.nstates]
    index = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in cont])
    x = np.array(X0, dtype=float)
    Y, X = np.zeros((sys.noutputs, T.size)), np.zeros((sys.nstates, T.size))
    for k, t in enumerate(instants):
        firing = {i for i in range(len(sys.syslist)) if discrete[i] and k % every[i] == 0}
        _, ulist, ylist = sweep(t, x, firing)
        for i in firing:
            held[i] = ylist[outs[i]:outs[i + 1]].copy()
        for j in np.nonzero(np.isclose(T, t, rtol=0, atol=1e-9 * h))[0]:
            Y[:, j], X[:, j] = outputs_at(t, x, firing), x
        for i in firing:
            if sys.syslist[i].nstates:
                x[offsets[i]:offsets[i + 1]] = sys.syslist[i]._rhs(
                    t, x[offsets[i]:offsets[i + 1]], ulist[inputs[i]:inputs[i + 1]])
        t1 = instants[k + 1] if k + 1 < n else T[-1]
        if t1 <= t:
            continue

        def rhs(tau, xc):
            xt = x.copy()
            xt[index] = xc
            _, ulist, _ = sweep(tau, xt, set())
            dx = np.zeros(sys.nstates)
            for i in cont:
                dx[offsets[i]:offsets[i + 1]] = sys.syslist[i]._rhs(
                    tau, xt[offsets[i]:offsets[i + 1]], ulist[inputs[i]:inputs[i + 1]])
            return dx[index]

        sol = scipy.integrate.solve_ivp(rhs, (t, t1), x[index], rtol=rtol, atol=atol,
                                        dense_output=True)
        inside = (T > t + 1e-9 * h) & (T < t1 - 1e-9 * h) | ((k + 1 == n) & (T > t) & (
            T <= t1))
        for j in np.nonzero(inside)[0]:
            xt = x.copy()
            xt[index] = sol.sol(T[j])
            Y[:, j], X[:, j] = outputs_at(T[j], xt, set()), xt
        x[index] = sol.y[:, -1]
    return Y, X


@pytest.mark.parametrize("name", sorted(MIXED))
def test_sampled_data_diagram_equals_the_reference(name):
    loop, T, X0, U = MIXED[name]()
    T, U = T[: T.size // 4 + 1], U[..., : T.size // 4 + 1]  # a quarter: the reference is slow
    assert type(loop).__name__ == "SampledDataSystem"
    assert {row.tier for row in explain(loop)} == {"compiled"}
    ours = fast(loop, T, U, X0, solve_ivp_kwargs=TIGHT)
    Y, X = reference(loop, T, X0, np.atleast_2d(U) if np.ndim(U) else np.zeros((0, T.size)))
    assert scaled_error(ours.y, Y) <= 1e-8
    assert scaled_error(ours.x, X) <= 1e-8


def test_a_sampled_data_diagram_runs_on_the_python_reference_when_asked():
    # engine="python-control" on a diagram python-control refuses: the plain-Python
    # reference, with the compiled engine's numbers (it once failed with UnboundLocalError)
    loop, T, X0, U = servo_pi_discrete()
    T, U = T[:41], U[:41]
    slow = controlkit.input_output_response(loop, T, U, X0, engine="python-control")
    quick = controlkit.input_output_response(loop, T, U, X0)
    assert slow.outputs.shape == quick.outputs.shape == (2, 41)
    assert scaled_error(slow.outputs, quick.outputs) <= 1e-6


def test_a_sampled_data_run_between_its_instants_is_the_reference_s_to_the_bit():
    # the reference read its times between instants from scipy's dense output one at a
    # time, a product of other roundings than solve_ivp's t_eval (the times at once),
    # which the engine follows: 0.11647093596930379 against ...377 at t = 0.06 s
    plant = ct.nlsys(lambda t, x, u, p: [-x[0] + u[0]], lambda t, x, u, p: [x[0]],
                     inputs="u", outputs="y", states=1, name="lag")
    gain = ct.nlsys(None, lambda t, x, u, p: [2.0 * u[0]], inputs="e", outputs="u",
                    name="gain", dt=0.1)
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = controlkit.interconnect([plant, gain, error], inputs="r", outputs="y")
    T = np.linspace(0.0, 1.0, 101)
    reference = controlkit.input_output_response(loop, T, 1.0, 0.0, engine="python-control")
    for compile in (False, True):
        ours = controlkit.input_output_response(loop, T, 1.0, 0.0, compile=compile)
        assert np.array_equal(ours.outputs, reference.outputs), compile
        assert np.array_equal(ours.states, reference.states), compile


def test_a_function_that_raises_in_a_rejected_step_raises_compiled_too():
    # a trial step too long for the slow lag takes its state to -1.03 at t = 2.00858 s, a
    # stage the integrator rejects: math.log raises there as Python (and in python-control),
    # and compiled it gave NaN, which the rejection hid, and the run answered (fuzz seed 56)
    def lag(t, x, u, params):
        return (-x + 0.177 * u) / 1.53

    upper = ct.nlsys(lag, lambda t, x, u, p: math.log(1 + x[0]), inputs="r", outputs="y1",
                     states=1, name="upper")
    lower = ct.ss([], [], [], [[1.94]], inputs="r", outputs="v2", name="lower")
    lower_plant = ct.ss([[-1.15, 0.76], [0.0, -0.576]], [[1.48], [0.66]], [[-0.5, -0.28]],
                        [[0.0]], inputs="v2", outputs="y2", name="lower_plant")
    mix = ct.nlsys(None, lambda t, x, u, p: np.array([0.694, -0.836]) @ u,
                   inputs=["y1", "y2"], outputs="y", name="mix")
    parallel = ct.interconnect([upper, lower, lower_plant, mix], inputs="r",
                               outputs=["y", "y1"])
    T = np.linspace(0.0, 3.34, 75)
    arguments = dict(inputs=np.where(np.arange(75) >= 18, 1.22, 0.0),
                     initial_state=[0.258, 0.0, 0.0], evaluation_times=np.linspace(0, 3.34, 15))
    with pytest.raises(ValueError, match="math domain error"):
        ct.input_output_response(parallel, T, **arguments)
    for compile in (False, True):
        with pytest.raises(ValueError, match="math domain error .*'upper'.* t = 2.00858 s"):
            controlkit.input_output_response(parallel, T, compile=compile, **arguments)


def test_a_single_system_s_output_function_is_not_called_at_the_integrator_s_stages():
    # python-control calls a single system's output function at the times it serves (an
    # interconnect's, at every stage): math.log met a stage's state out of its domain at
    # t = 2.43 s as controlkit's Python run, which raised where python-control answers
    # (fuzz seed 289)
    def lag(t, x, u, params):
        return (-x + 1.58 * u) / 0.642

    plant = ct.nlsys(lag, lambda t, x, u, p: math.log(1 + x[0]), inputs=1, outputs=1,
                     states=1, name="plant")
    T = np.linspace(0.0, 2.822, 37)
    U = np.where(np.arange(37) >= 9, 0.774, 0.0)
    expected = ct.input_output_response(plant, T, U, 0.0)
    for compile in (False, True):
        ours = controlkit.input_output_response(plant, T, U, 0.0, compile=compile)
        assert ours.engine_mode == ("compiled" if compile else "python")
        assert np.array_equal(ours.outputs, expected.outputs), compile
        assert np.array_equal(ours.states, expected.states), compile


def test_a_lone_system_s_outputs_are_made_as_python_control_makes_them_after_its_solver():
    # python-control calls a lone system's output function after its solver, on a column
    # of the solution's states (a strided view), where numpy's C @ x rounds otherwise than
    # on a copy: 89 of 100 random state-space systems moved in the last bit (python-control's
    # own timeresp_test.test_squeeze among them); in an interconnect it copies x, as we do
    T = np.linspace(0.0, 1.0, 8)
    U = np.ones((2, 1)) @ np.sin(T).reshape(1, -1)
    differ = 0
    for seed in range(20):  # (one output: numpy's product of a row and a column)
        rng = np.random.default_rng(seed)
        plant = ct.ss(-2.0 * np.eye(4) + 0.5 * rng.standard_normal((4, 4)),
                      *(rng.standard_normal(shape) for shape in ((4, 2), (1, 4), (1, 2))))
        expected = ct.input_output_response(plant, T, U, return_x=True)
        copied = np.array([plant.C @ expected.x[:, i].copy() + plant.D @ expected.u[:, i].copy()
                           for i in range(T.size)]).T
        differ += not np.array_equal(copied, expected.y)
        for compile in (False, True) if seed < 2 else (False,):  # (a compile: 1-2 s each)
            ours = controlkit.input_output_response(plant, T, U, compile=compile)
            assert np.array_equal(ours.states, expected.states), (seed, compile)
            assert np.array_equal(ours.outputs, expected.outputs), (seed, compile)
    assert differ > 10  # (the case the test is about: the copy's products differ: 14)
    starts = np.array([[0.1, 0.0, 0.0, 0.0], [0.2, 0.0, 0.0, 0.3]])  # and in many runs
    for start, ours in zip(starts, controlkit.input_output_response(plant, T, U, starts,
                                                                    compile=False), strict=True):
        assert np.array_equal(ours.outputs,
                              ct.input_output_response(plant, T, U, start).outputs)
    # a user's output function with the call's params over the system's own
    plant = ct.nlsys(lambda t, x, u, p: -p["a"] * x + u, lambda t, x, u, p: p["c"] * x,
                     states=1, inputs=1, outputs=1, params={"a": 1.0, "c": 2.0})
    expected = ct.input_output_response(plant, T, 1.0, params={"c": 3.0})
    ours = controlkit.input_output_response(plant, T, 1.0, params={"c": 3.0}, compile=False)
    assert np.array_equal(ours.outputs, expected.outputs)


def test_the_first_time_point_is_served_by_the_solver_s_first_step_as_scipy_serves_it():
    # scipy's solve_ivp evaluates the first step's interpolant at the first time point and
    # the step's other times together (one product for all: for one time alone it rounds
    # otherwise, a last bit at t = 0.05 here), and a -0.0 initial state comes out as 0.0
    plant = ct.nlsys(_oscillator, lambda t, x, u, p: [x[0], x[1]], inputs="u",
                     outputs=["y0", "y1"], states=2, name="oscillator")
    loop = ct.interconnect([plant], inputs="u", outputs=["y0", "y1"])
    T = np.linspace(0.0, 3.0, 61)
    for X0 in (0.1, [-0.0, 0.0]):
        expected = ct.input_output_response(loop, T, 1.0, X0)
        for compile in (False, True):
            ours = controlkit.input_output_response(loop, T, 1.0, X0, compile=compile)
            assert ours.states.tobytes() == expected.states.tobytes(), (X0, compile)
            assert ours.outputs.tobytes() == expected.outputs.tobytes(), (X0, compile)
    assert not np.signbit(expected.states[0, 0])


def _oscillator(t, x, u, params):
    return [x[1], -2.0 * x[0] - 0.3 * x[1] + u[0]]


_GAINS = (0.5, 1.0, 2.0)


def _table_update(t, x, u, params):  # a gain looked up by the state: an index out of range
    return [x[0] + 0.1 * _GAINS[int(x[0])] * u[0]]


def _guarded_rate(t, x, u, params):  # the function's own raise
    if x[0] > 0.8:
        raise ValueError(f"the lag went over its limit at t = {t}")
    return [-x[0] + u[0]]


def _guarded_output(t, x, u, params):
    if x[0] > 0.8:
        raise ValueError(f"the output went over its limit at t = {t}")
    return [x[0]]


@pytest.mark.parametrize("case", ["discrete update", "continuous rate", "output"])
def test_a_user_s_function_that_raises_in_compiled_code_raises_as_python_does(case):
    # the instants' loop calls a diagram's functions compiled as numba's C functions, which
    # cannot raise: a discrete block's table lookup out of range went on silently
    # (fuzz seed 302 answered with compile=True where Python and python-control raise)
    lag = ct.nlsys(_guarded_rate if case == "continuous rate" else lambda t, x, u, p: -x + u,
                   _guarded_output if case == "output" else None, inputs=1, outputs=1,
                   states=1, name="lag")
    blocks = [lag]
    if case == "discrete update":
        blocks.append(ct.nlsys(_table_update, None, inputs=1, outputs=1, states=1, dt=0.1,
                               name="table"))
    loop = controlkit.interconnect(blocks, inplist=[f"{b.name}.u[0]" for b in blocks],
                                   outlist=[f"{b.name}.y[0]" for b in blocks], name=case)
    T = np.linspace(0.0, 4.0, 41)
    U = 3.0 * np.ones((len(blocks), T.size))
    with pytest.raises((IndexError, ValueError)) as theirs:  # (python-control's, or Python's)
        (controlkit if len(blocks) > 1 else ct).input_output_response(loop, T, U, 0.0)
    for compile in (False, True):
        with pytest.raises(type(theirs.value)) as ours:
            controlkit.input_output_response(loop, T, U, 0.0, compile=compile)
        assert str(theirs.value).split(" at t")[0] in str(ours.value)


def _forced_by_time(t, x, u, params):
    return [-x[0] + 0.5 / t + u[0]]


def test_a_division_by_the_first_time_point_raises_as_in_python_control():
    # solve_ivp's first call is given t0 as a Python float (0.5 / 0.0 raises), its later
    # ones numpy's floats (inf, and a warning); the engine answered "diverged" instead
    plant = ct.nlsys(_forced_by_time, lambda t, x, u, p: x[:1], inputs=1, outputs=1,
                     states=1, name="plant")
    gain = ct.nlsys(None, lambda t, x, u, p: -0.2 * u, inputs=1, outputs=1, name="gain")
    loop = ct.interconnect([plant, gain], connections=[["plant.u[0]", "gain.y[0]"],
                                                       ["gain.u[0]", "plant.y[0]"]],
                           inplist=[], outlist=["plant.y[0]"], name="forced")
    T = np.linspace(0.0, 2.0, 21)
    with pytest.raises(ZeroDivisionError):
        ct.input_output_response(loop, T, X0=0.0)
    for compile in (False, True):
        with pytest.raises(ZeroDivisionError, match="at t = 0 s"):
            controlkit.input_output_response(loop, T, X0=0.0, compile=compile)
    # from t0 = 1 on, the function is defined everywhere: the same numbers
    T = np.linspace(1.0, 3.0, 21)
    expected = ct.input_output_response(loop, T, X0=0.0)
    ours = controlkit.input_output_response(loop, T, X0=0.0, compile=True)
    assert ours.outputs.tobytes() == expected.outputs.tobytes()


def test_python_control_refuses_a_sampled_data_diagram_with_the_remedy():
    loop, T, X0, U = servo_pi_discrete()
    with pytest.raises(ValueError, match=r"sampled-data diagram .* "
                                         r"controlkit.input_output_response simulates it"):
        ct.input_output_response(loop, T, U, X0)
    # nested in a larger interconnect: python-control's matching builds it, and the run
    # says the same, naming the blocks to build the larger diagram from
    sensor = ct.tf([1.0], [0.2, 1.0], name="sensor", inputs=loop.output_labels[0],
                   outputs="measured")
    outer = controlkit.interconnect([loop, sensor], inputs=loop.input_labels,
                                    outputs="measured")
    with pytest.raises(ValueError, match=r"nor an interconnect it is nested in; .*"
                                         + re.escape(f"({loop.name}.syslist)")):
        controlkit.input_output_response(outer, T, U, X0, compile=False)


@pytest.mark.parametrize("build", [dc_motor, observer, CONTINUOUS["car_pi"]],
                         ids=["continuous LTI", "sampled-data", "user functions"])
def test_the_diagrams_module_compiled_gives_its_numbers_run_as_python(build):
    # one module, two ways of running it: the integrator's step machine and the blocks
    # compiled, or all of it as Python; the same arithmetic, so the same bits (these
    # diagrams call no libm function whose last bit numba's and Python's could differ in)
    loop, T, X0, U = build()
    U = np.broadcast_to(np.atleast_2d(U) if np.ndim(U) else np.zeros((0, T.size)),
                        (loop.ninputs, T.size))
    # steps of at most 50 ms: runs of many pieces, the first one compared with Python
    run_continuous(loop, T, U, X0, compile=True, max_step=0.05)  # compiled, checked
    compiled = run_continuous(loop, T, U, X0, compile=True, max_step=0.05)  # throughout
    python = run_continuous(loop, T, U, X0, compile=False, max_step=0.05)
    assert (compiled.engine_mode, python.engine_mode) == ("compiled", "python")
    np.testing.assert_array_equal(compiled.y, python.y)
    np.testing.assert_array_equal(compiled.x, python.x)


def test_rates_that_are_not_multiples_are_refused_naming_the_blocks():
    plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    fast_pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi", inputs="e",
                               outputs="u")
    filt = ct.sample_system(ct.tf([1.0], [1.0, 1.0]), 0.25, name="filter", inputs="y",
                            outputs="yf")
    error = ct.summing_junction(["r", "-yf"], "e", name="error")
    with pytest.raises(ValueError, match=r"integer multiples of the shortest \(0.1 s of 'pi'\)"
                                         r"; got 'filter' at 0.25 s"):
        controlkit.interconnect([plant, fast_pi, filt, error], inputs="r", outputs="y")


def test_a_discrete_block_without_a_period_beside_a_continuous_one_is_refused():
    plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    gain = ct.ss([], [], [], [[2.0]], dt=True, name="k", inputs="y", outputs="u")
    with pytest.raises(ValueError, match=r"blocks \['k'\] are discrete with no sampling "
                                         r"period \(dt=True\)"):
        controlkit.interconnect([plant, gain])


def test_one_timebase_gives_python_controls_own_interconnect():
    loop, *_ = CONTINUOUS["pi_first_order"]()
    again = controlkit.interconnect(loop.syslist, inputs="r", outputs=["y", "u"])
    assert type(again) is type(loop) and again.dt == 0
    # periods python-control counts as one (np.isclose): its own diagram, not two rates
    plant = ct.ss([[0.5]], [[1.0]], [[1.0]], [[0.0]], dt=0.1000001, name="plant",
                  inputs="u", outputs="y")
    gain = ct.ss([], [], [], [[0.5]], dt=0.1, name="k", inputs="y", outputs="u")
    theirs = ct.interconnect([plant, gain], inputs="u", outputs="y")
    ours = controlkit.interconnect([plant, gain], inputs="u", outputs="y")
    assert type(ours) is type(theirs) and ours.dt == theirs.dt == 0.1000001


def test_ignore_errors_on_a_sampled_data_diagram_still_names_the_stop():
    # python-control returns a run up to its solver's stop with ignore_errors=True; a
    # sampled-data diagram has no python-control run to hand over to: the engine's error
    grow = ct.nlsys(lambda t, x, u, params: x * x + u, None, inputs="u", outputs="y",
                    states=1, name="blowup")
    hold = ct.ss([], [], [], [[0.0]], dt=0.1, name="hold", inputs="y", outputs="u")
    loop = controlkit.interconnect([grow, hold], inputs=[], outputs="y")
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # (no hand-over promised)
        with pytest.raises(RuntimeError, match=r"fell below the spacing of numbers after "
                                               r"t = 0.9 s"):
            controlkit.input_output_response(loop, np.linspace(0.0, 2.0, 21), 0.0, 1.0,
                                             ignore_errors=True)


def test_a_diverging_continuous_loop_names_the_time_and_the_blocks():
    # x' = x^2 from 1 escapes to infinity at t = 1: scipy's steps shrink to nothing there
    grow = ct.nlsys(lambda t, x, u, params: x * x, None, states=1, inputs=0, outputs=1,
                    name="blowup")
    loop = ct.interconnect([grow], outputs="y[0]")
    with pytest.raises(RuntimeError, match=r"fell below the spacing of numbers after "
                                           r"t = 0.5 s.*\['blowup'\] at .*e\+.*diverges"
                                           r".*solve_ivp_method='BDF'"):
        fast(loop, np.linspace(0.0, 2.0, 5), 0.0, 1.0)


def stiff_loop(Ts=0.0):
    """A 1 us actuator before a 10 s plant under a PI (continuous, or sampled at Ts)."""
    actuator = ct.tf([1.0], [1e-6, 1.0], name="actuator", inputs="u", outputs="f")
    plant = ct.tf([1.0], [10.0, 1.0], name="plant", inputs="f", outputs="y")
    pi = ct.tf([2.0, 0.5], [1.0, 0.0], inputs="e", outputs="u", name="pi")
    if Ts:
        pi = ct.sample_system(pi, Ts, method="tustin", name="pi")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    return controlkit.interconnect([actuator, plant, pi, error], inputs="r", outputs="y",
                                   name="stiff_loop")


@pytest.mark.parametrize("Ts", [0.0, 0.1])
def test_a_stiff_loop_stops_at_once_naming_an_implicit_method(Ts):
    # RK45 would need some 3e8 steps of 3 us for 1000 s: hours in scipy, a minute here
    loop = stiff_loop(Ts)
    T = np.linspace(0.0, 1000.0, 10001)
    blocks = "'actuator', 'plant', 'pi'" if Ts == 0 else "'actuator', 'plant'"
    with pytest.raises(StiffProblem, match=rf"'stiff_loop' is stiff for RK45: .*\[{blocks}\]"
                                           r".* to t = 1000 s would take about 3e\+08 steps"
                                           r".*solve_ivp_method='BDF'"):
        fast(loop, T, 1.0)
    # the remedy the message names works and gives python-control's numbers
    ours = fast(loop, T[:1001], 1.0, solve_ivp_method="BDF")
    assert abs(ours.outputs[-1] - 1.0) < 1e-4  # the PI has removed the error by 100 s
    if Ts == 0:
        ref = ct.input_output_response(loop, T[:1001], 1.0, solve_ivp_method="BDF")
        assert scaled_error(ours.y, ref.y) <= 1e-9


def test_a_short_stiff_run_goes_on_as_python_control():
    # 1 ms of the stiff loop: about 300 steps, under the budget; RK45's own numbers
    loop = stiff_loop()
    T = np.linspace(0.0, 1e-3, 11)
    ref = ct.input_output_response(loop, T, 1.0)
    assert scaled_error(fast(loop, T, 1.0).y, ref.y) <= 1e-9


@pytest.mark.parametrize("which", ["fig2", "fig3", "fig4", "cmg"])
def test_the_papers_loops_with_the_continuous_plant_agree_with_the_sampled_plant(which):
    from controlkit.blocks import spacecraft as sc
    from controlkit.blocks.cmg import adaptive_smc
    from controlkit.simulation import initial_state, simulate
    from controlkit.studies.cmg.diagrams import cmg_loop
    from controlkit.studies.cmg.scenario import X0_THESIS
    from controlkit.studies.spacecraft.diagrams import mec_loop, output_zeroing_loop

    q0 = sc.quaternion_from_axis_angle([1, 2, 3], 30.0)
    build, start, Ts, steps = {
        "fig2": (output_zeroing_loop, {"plant": q0}, 0.1, 1000),
        "fig3": (lambda **kw: mec_loop(K=0.1, **kw), {"plant": q0, "nominal": q0[1:3]},
                 0.1, 1000),
        "fig4": (lambda **kw: mec_loop(h0=q0[1:3], **kw), {"plant": q0, "nominal": q0[1:3]},
                 0.1, 1000),
        # 4 s: the references start moving at 2 s. With the thesis's sgn(s) the sliding
        # mode amplifies any last-bit difference (a tolerance change alone moves w1 by
        # 1e-5), so the comparison is made with a boundary layer, where the loop is smooth
        "cmg": (lambda **kw: cmg_loop(controller=adaptive_smc(boundary_layer=0.005), **kw),
                {"cmg": X0_THESIS}, 0.001, 4000),
    }[which]
    sampled, held = build(), build(continuous_plant=True)
    assert type(held).__name__ == "SampledDataSystem"
    T = np.arange(steps + 1) * Ts
    ref = simulate(sampled, T, X0=initial_state(sampled, **start), engine="fast")
    ours = fast(held, T, 0.0, initial_state(held, **start), solve_ivp_kwargs=TIGHT)
    rows = [held.output_labels.index(label) for label in sampled.output_labels]
    # RK4 over one sample (the paper's hold) against an adaptive method at tight tolerance
    assert scaled_error(ours.y[rows], ref.y) <= 1e-9
    moved = np.abs(ref.x - ref.x[:, :1]).max()  # a loop at rest would agree trivially
    assert moved > 0.005, moved


def test_a_single_block_is_explained_and_run_as_a_one_block_diagram():
    # a plant on its own, as a notebook simulates it before closing the loop
    def pendulum(t, x, u, params):
        return [x[1], -params["g"] * np.sin(x[0]) - params["c"] * x[1] + u[0]]

    plant = ct.nlsys(pendulum, None, states=["theta", "omega"], inputs="torque",
                     outputs=["theta", "omega"], params={"g": 9.81, "c": 0.2}, name="pendulum")
    assert [(row.name, row.tier) for row in explain(plant)] == [("pendulum", "compiled")]
    T = np.linspace(0.0, 5.0, 51)
    ours = fast(plant, T, 0.0, [1.0, 0.0])
    ref = ct.input_output_response(plant, T, 0.0, [1.0, 0.0])
    assert scaled_error(ours.y, ref.y) <= 1e-9
    assert ours.output_labels == ref.output_labels and ours.state_labels == ref.state_labels
