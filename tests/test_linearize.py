"""controlkit.linearize and find_eqpt: python-control's results on its own examples, the
exact discretisation of sampled-data diagrams, exact Jacobians of the papers' blocks, and
loops cut open at a signal."""

from __future__ import annotations

from math import cos, sin

import control as ct
import numpy as np
import pytest

import controlkit
from controlkit.analysis import find_eqpt, linearize, loop_transfers, reduced
from controlkit.analysis.jacobians import _differences, block_jacobians
from controlkit.blocks import common, mec
from controlkit.blocks import spacecraft as sc
from controlkit.blocks.cmg import torque_saturation
from controlkit.blocks.sampling import sample_nlsys
from controlkit.studies._period import zero_order_hold
from controlkit.studies.spacecraft import diagrams

# --- python-control's examples (control/tests/iosys_test.py, examples/) -------------------


def kincar():
    """The kinematic car of python-control's tests, written as they write it."""
    def kincar_update(t, x, u, params):
        return np.array([np.cos(x[2]) * u[0], np.sin(x[2]) * u[0], u[1]])

    def kincar_output(t, x, u, params):
        return np.array([x[0], x[1]])

    return ct.NonlinearIOSystem(kincar_update, kincar_output, inputs=["v", "phi"],
                                outputs=["x", "y"], states=["x", "y", "theta"], name="car")


def pvtol():
    """python-control's reduced PVTOL (control/tests/iosys_test.py), its parameters read
    from the dict as python-control's tests read them."""
    def pvtol_update(t, x, u, params={}):  # noqa: B006 (python-control's own idiom)
        m, J = params.get("m", 4.0), params.get("J", 0.0475)
        r, g, c = params.get("r", 0.25), params.get("g", 9.8), params.get("c", 0.05)
        return np.array([
            x[3],
            -c / m * x[1] + 1 / m * cos(x[0]) * u[0] - 1 / m * sin(x[0]) * u[1],
            -g - c / m * x[2] + 1 / m * sin(x[0]) * u[0] + 1 / m * cos(x[0]) * u[1],
            -0.1 / J * sin(x[0]) + r / J * u[0]])

    return ct.nlsys(pvtol_update, lambda t, x, u, params: x[0:2], states=4, inputs=2,
                    outputs=2, params={"m": 4.0, "c": 0.05}, name="pvtol")


def steering_loop():
    """The vehicle of python-control's steering example under a static state feedback."""
    def vehicle_update(t, x, u, params):
        a, b = params.get("refoffset", 1.5), params.get("wheelbase", 3.0)
        delta = np.clip(u[1], -params.get("maxsteer", 0.5), params.get("maxsteer", 0.5))
        alpha = np.arctan2(a * np.tan(delta), b)
        return np.array([u[0] * np.cos(x[2] + alpha), u[0] * np.sin(x[2] + alpha),
                         (u[0] / a) * np.sin(alpha)])

    vehicle = ct.nlsys(vehicle_update, None, inputs=("v", "delta"), outputs=("x", "y", "theta"),
                       states=3, name="vehicle", params={"wheelbase": 3.0, "maxsteer": 0.5})
    feedback = ct.nlsys(None, lambda t, x, u, params: [u[0], -params["k"] * u[2] - u[3]],
                        inputs=("vd", "x", "y", "theta"), outputs=("v", "delta"),
                        params={"k": 0.4}, name="control")
    return ct.interconnect([vehicle, feedback], inputs="vd", outputs=["x", "y", "theta"],
                           name="steering")


def eqpt_rhs(t, x, u, params):
    return np.array([x[0] / 2 + u[0], x[0] - x[1] ** 2 + u[1], x[1] - x[2]])


def eqpt_out(t, x, u, params):
    return np.array([x[0], x[1] + u[1]])


def discrete_loop():
    """A discrete nonlinear plant under a sampled PI, wired the python-control way."""
    plant = ct.nlsys(lambda t, x, u, params: np.array([x[0] + 0.1 * (np.sin(x[0]) + u[0])]),
                     lambda t, x, u, params: x, inputs="u", outputs="y", states=1, dt=0.1,
                     name="plant")
    pi = ct.sample_system(ct.tf([2.0, 1.0], [1.0, 0.0]), 0.1, name="pi", inputs="e",
                          outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    return ct.interconnect([plant, pi, error], inputs="r", outputs="y", name="loop")


CASES = {
    "kincar at rest": (kincar, [0, 0, 0], [0, 0]),
    "kincar turning": (kincar, [1.0, 2.0, 0.7], [2.0, 0.3]),
    "pvtol": (pvtol, [0.1, 0.2, -0.3, 0.4], [1.0, 9.8]),
    "steering loop": (steering_loop, [0.0, 0.5, 0.2], [10.0]),
    "discrete eqpt system": (lambda: ct.nlsys(eqpt_rhs, eqpt_out, dt=1, states=3, inputs=2,
                                              outputs=2), [0.3, -0.5, 0.25], [0.1, -0.25]),
    "discrete loop": (discrete_loop, [0.4, -0.2], [0.5]),
}


@pytest.mark.parametrize("case", CASES)
def test_linearize_is_python_controls_on_its_examples(case):
    build, x, u = CASES[case]
    sys = build()
    ours, theirs = linearize(sys, x, u), ct.linearize(sys, x, u)
    assert ours.dt == theirs.dt
    for name in "ABCD":  # python-control's forward differences with 1e-6: ~1e-6 errors
        np.testing.assert_allclose(getattr(ours, name), getattr(theirs, name), atol=2e-5,
                                   err_msg=name)


def test_central_differences_reach_1e_9_on_the_kinematic_car():
    x, u = [1.0, 2.0, 0.7], [2.0, 0.3]
    lin = linearize(kincar(), x, u)
    exact_A = [[0, 0, -np.sin(0.7) * 2.0], [0, 0, np.cos(0.7) * 2.0], [0, 0, 0]]
    exact_B = [[np.cos(0.7), 0], [np.sin(0.7), 0], [0, 1]]
    np.testing.assert_allclose(lin.A, exact_A, atol=1e-9)
    np.testing.assert_allclose(lin.B, exact_B, atol=1e-9)
    assert lin.jacobian_methods == {"car": "central differences"}


def test_names_follow_python_control():
    car = kincar()
    for kwargs in ({}, {"copy_names": True}, {"copy_names": True, "name": "lin"},
                   {"copy_names": True, "inputs": ["v2", "phi2"]}, {"name": "other"}):
        ours, theirs = linearize(car, 0, 0, **kwargs), ct.linearize(car, 0, 0, **kwargs)
        assert (ours.input_labels, ours.output_labels, ours.state_labels) == (
            theirs.input_labels, theirs.output_labels, theirs.state_labels)
        if "name" in kwargs or kwargs.get("copy_names"):
            assert ours.name == theirs.name


def test_an_operating_point_and_vectors_are_read_as_python_control_reads_them():
    car = kincar()
    point = ct.OperatingPoint(np.array([1.0, 2.0, 0.7]), np.array([2.0, 0.3]))
    np.testing.assert_array_equal(linearize(car, point).A, linearize(car, [1, 2, 0.7],
                                                                     [2, 0.3]).A)
    np.testing.assert_array_equal(linearize(car, [0, np.array([0, 0])], [0, 0]).B,
                                  linearize(car, 0, 0).B)  # lists of arrays concatenate
    assert linearize(car, [0, 0], np.array([0])).nstates == 3  # padded with zeros
    with pytest.warns(UserWarning, match="x0 too short; padding with zeros"):
        linearize(car, [0, 1], 0)


BAD_ARGUMENTS = {
    "xeq too long": (dict(xeq=[0, 0, 0, 0]), r"xeq must have 3 values \(x, y, theta\), got 4"),
    "ueq too long": (dict(ueq=[0, 0, 1]), r"ueq must have 2 values \(v, phi\), got 3"),
    "xeq nan": (dict(xeq=[0, np.nan, 0]), r"xeq must be finite; not finite at \['y'\]"),
    "ueq text": (dict(ueq="fast"), r"ueq must be numbers, got 'fast'"),
    "t inf": (dict(t=np.inf), r"t must be a finite number, got inf"),
    "eps zero": (dict(eps=0.0), r"eps must be > 0 \(a finite-difference step\), got 0.0"),
    "params": (dict(params=[1]), r"params must be a dict of parameter values, got \[1\]"),
}


@pytest.mark.parametrize("case", BAD_ARGUMENTS)
def test_bad_arguments_are_refused_by_name(case):
    given, message = BAD_ARGUMENTS[case]
    arguments = {"xeq": 0.0, "ueq": 0.0, **given}
    with pytest.raises(ValueError, match=message):
        linearize(kincar(), **arguments)


def test_a_transfer_function_is_linearized_in_its_state_space_form():
    G = ct.tf([2.0, 1.0], [1.0, 3.0, 2.0], name="G")
    lin = linearize(G, 0.0, 0.0)
    np.testing.assert_allclose(complex(lin(1j)), complex(G(1j)), rtol=1e-12)


def test_what_is_not_a_system_or_has_no_inputs_is_refused():
    with pytest.raises(TypeError, match="Can only linearize InputOutputSystem types"):
        linearize(np.eye(2), 0)
    with pytest.raises(TypeError, match="got FrequencyResponseData"):
        linearize(ct.frd([1.0, 0.5], [1.0, 2.0]), 0)
    autonomous = ct.nlsys(lambda t, x, u, p: -x, lambda t, x, u, p: x, states=1, inputs=0,
                          outputs=1, name="decay")
    with pytest.raises(ValueError, match="'decay' has no inputs, and python-control"):
        linearize(autonomous, 1.0)


def test_a_block_without_a_derivative_is_named():
    kink = ct.nlsys(lambda t, x, u, p: np.array([np.inf if u[0] > 0 else 0.0]),
                    lambda t, x, u, p: x, states=1, inputs=1, outputs=1, name="kink")
    with pytest.raises(ValueError, match="block 'kink': its dynamics is not finite within"):
        linearize(kink, 0.0, 0.0)


# --- the papers' blocks: exact Jacobians ----------------------------------------------

MOMENTUM = sc.MomentumProfile(constant=(0.01, -0.02, 0.03), sine=(0.05, 0.0, 0.05),
                              cosine=(0.0, 0.05, 0.0), omega=2e-3)
Q = sc.quaternion_from_axis_angle([1.0, -2.0, 0.5], 40.0)
BLOCKS = {
    "plant": (lambda: sc.spacecraft_plant(J_b=sc.J_BN + sc.DELTA_J, H0=MOMENTUM), Q,
              [3.0, -1.5]),
    "linearizer": (lambda: sc.io_linearizer(H0n=MOMENTUM), [], [2e-3, -1e-3, *Q]),
    "output": (sc.attitude_output, [], Q),
    "controller": (lambda: sc.outer_controller([0.5, 0.2]), [], [0.1, 0.2, 0.3, -0.4]),
    "mec": (mec.mec_compensator, [], [0.1, -0.2, 0.3, 0.4, -0.5, 0.6, 1.0, 2.0, -3.0, 4.0]),
    "gain": (lambda: mec.constant_gain([[1.0, 2.0], [3.0, 4.0]]), [], []),
    "nominal": (lambda: mec.nominal_model(0.1), [0.2, -0.1], [0.3, 0.4]),
    "lowpass": (lambda: common.lowpass_filter(2.0, 0.1), [0.2, -0.1], [0.3, 0.4]),
    "saturation": (torque_saturation, [], [0.3, -3.0]),
    "zoh": (lambda: zero_order_hold(["u[0]", "u[1]"], 0.1), [], [0.3, -3.0]),
}


@pytest.mark.parametrize("name", BLOCKS)
def test_exact_jacobians_equal_central_differences(name):
    build, x, u = BLOCKS[name]
    block = build()
    x, u = np.asarray(x, dtype=float), np.asarray(u, dtype=float)
    A, B, C, D, how = block_jacobians(block, 123.0, x, u, {})
    assert how == "exact"
    Ad, Bd = _differences(block, "dynamics", 123.0, x, u, {}, None, block.nstates)
    Cd, Dd = _differences(block, "output", 123.0, x, u, {}, None, block.noutputs)
    for exact, estimate in ((A, Ad), (B, Bd), (C, Cd), (D, Dd)):
        scale = max(1.0, np.abs(exact).max(initial=0.0))
        np.testing.assert_allclose(exact, estimate, atol=1e-8 * scale)


@pytest.mark.parametrize("method", ["rk4", "solve_ivp"])
def test_a_sampled_block_is_differentiated_through_its_own_map(method):
    plant = sc.spacecraft_plant(J_b=sc.J_BN + sc.DELTA_J, H0=MOMENTUM)
    sampled = sample_nlsys(plant, 5.0, method=method, substeps=2)
    x, u = Q, np.array([30.0, -20.0])  # fast wheels: the map is far from linear
    A, B, _, _, how = block_jacobians(sampled, 7.0, x, u, {})
    assert how == {"rk4": "rk4 (exact)", "solve_ivp": "variational (solve_ivp)"}[method]
    Ad, Bd = _differences(sampled, "dynamics", 7.0, x, u, {}, 1e-4, 4)
    np.testing.assert_allclose(A, Ad, atol=1e-7)
    np.testing.assert_allclose(B, Bd, atol=1e-9)


# --- sampled-data diagrams: exact at the instants -------------------------------------

def _plant(name="plant", inputs="u", outputs="y"):
    return ct.ss([[0.0, 1.0], [-2.0, -0.3]], [[0.0], [1.5]], [[1.0, 0.2]], 0.0, name=name,
                 inputs=inputs, outputs=outputs)


def _pi(Ts, name="pi", inputs="e", outputs="u"):
    return ct.sample_system(ct.tf([0.8, 0.3], [1.0, 0.0]), Ts, name=name, inputs=inputs,
                            outputs=outputs)


def _simple(Ts):
    """Plant, discrete PI, summing junction."""
    parts = [_plant(), _pi(Ts), ct.summing_junction(["r", "-y"], "e", name="error")]
    hand = [ct.sample_system(parts[0], Ts, "zoh", name="plant"), *parts[1:]]
    return parts, hand


def _continuous_chain(Ts):
    """Plant -> static gain -> continuous filter, all between instants; a controller with
    feedthrough reads the filter."""
    plant, gain = _plant(outputs="y0"), ct.ss([], [], [], [[2.0]], name="gain", inputs="y0",
                                              outputs="y1")
    lag = ct.ss(-3.0, 3.0, 1.0, 0.0, name="lag", inputs="y1", outputs="y")
    ctrl = ct.ss(0.9, 0.1, -0.5, 0.7, dt=Ts, name="ctrl", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    continuous = ct.interconnect([plant, gain, lag], inputs="u", outputs="y", name="cont")
    hand = [ct.sample_system(continuous, Ts, "zoh", name="cont"), ctrl, error]
    return [plant, gain, lag, ctrl, error], hand


def _nested(Ts):
    """The plant and a sensor as a sub-diagram of their own."""
    sensor = ct.ss(-5.0, 5.0, 1.0, 0.0, name="sensor", inputs="y0", outputs="y")
    inner = ct.interconnect([_plant(outputs="y0"), sensor], inputs="u", outputs="y",
                            name="inner")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    hand = [ct.sample_system(inner, Ts, "zoh", name="inner"), _pi(Ts), error]
    return [inner, _pi(Ts), error], hand


@pytest.mark.parametrize("build", [_simple, _continuous_chain, _nested])
@pytest.mark.parametrize("Ts", [0.05, 0.4])
def test_sampled_data_equals_sample_system_composed_with_the_controller(build, Ts):
    parts, hand = build(Ts)
    loop = controlkit.interconnect(parts, inputs="r", outputs=["y", "u"])
    reference = ct.interconnect(hand, inputs="r", outputs=["y", "u"])
    lin = linearize(loop, 0.0, 0.0)
    assert type(loop).__name__ == "SampledDataSystem" and lin.dt == Ts
    for name in "ABCD":
        np.testing.assert_allclose(getattr(lin, name), getattr(reference, name), atol=1e-10,
                                   rtol=0, err_msg=name)


def test_several_rates_give_the_frame_map_the_simulation_follows():
    """Controllers at Ts and 2 Ts: the model over the frame (2 Ts) moves the state as
    the reference simulation does."""
    Ts = 0.1
    inner = _pi(Ts, name="fast", inputs="e", outputs="v")
    outer = ct.ss(0.5, 1.0, 0.3, 0.2, dt=2 * Ts, name="slow", inputs="v", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = controlkit.interconnect([_plant(), inner, outer, error], inputs="r", outputs="y")
    lin = linearize(loop, 0.0, 0.0)
    assert lin.dt == pytest.approx(2 * Ts)
    x0 = np.array([0.3, -0.2, 0.5, 0.1])
    T = np.array([0.0, 2 * Ts])
    resp = controlkit.input_output_response(loop, T, 0.0, x0,
                                            solve_ivp_kwargs={"rtol": 1e-11, "atol": 1e-13})
    np.testing.assert_allclose(lin.A @ x0, resp.states[:, -1], atol=1e-9)


def test_the_spacecraft_loop_sampled_data_equals_its_rk4_sampled_version_at_the_target():
    plant = sc.spacecraft_plant(J_b=sc.J_BN + sc.DELTA_J)
    models = []
    for continuous in (False, True):
        loop = diagrams.mec_loop(plant, K=0.1, continuous_plant=continuous)
        x = controlkit.initial_state(loop, plant=[1.0, 0, 0, 0], nominal=[0.0, 0.0])
        models.append(linearize(loop, x, 0.0))
    assert models[0].jacobian_methods["plant"] == "rk4 (exact)"
    assert models[1].jacobian_methods["plant"] == "exact"
    for name in "ABCD":  # at rest the plant is x' = B u, which RK4 integrates exactly
        np.testing.assert_allclose(getattr(models[0], name), getattr(models[1], name),
                                   atol=1e-12, err_msg=name)


def test_find_eqpt_of_a_sampled_data_loop():
    plant = ct.ss(-1, 1, 1, 0, name="plant", inputs="u", outputs="y")
    ctrl = ct.ss(1, 0.1, 0.5, 0, dt=0.1, name="ctrl", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = controlkit.interconnect([plant, ctrl, error], inputs="r", outputs="y")
    x, u, y, result = find_eqpt(loop, [0, 0], 2.0, return_outputs=True, return_result=True)
    assert result.success
    np.testing.assert_allclose([*x, *u, *y], [2.0, 4.0, 2.0, 2.0], atol=1e-9)
    point = find_eqpt(loop, [0, 0], [0.0], y0=[3.0], iu=[])  # the output fixed instead
    np.testing.assert_allclose(point.inputs, [3.0], atol=1e-9)


def test_find_eqpt_of_one_timebase_is_python_controls():
    sys = ct.nlsys(eqpt_rhs, eqpt_out, dt=0, states=3, inputs=2, outputs=2)
    ours = find_eqpt(sys, [0.9, 0.9, 0.9], [-1, 0])
    theirs = ct.find_eqpt(sys, [0.9, 0.9, 0.9], [-1, 0])
    np.testing.assert_array_equal(ours.states, theirs.states)


# --- loops cut open -------------------------------------------------------------------

def test_loop_transfers_of_an_integrator_under_unit_feedback():
    plant = ct.tf([1], [1, 0], name="plant", inputs="u", outputs="y")
    minus = ct.summing_junction(["r", "-y"], "u", name="error")
    loop = ct.interconnect([plant, minus], inputs="r", outputs="y")
    L, S, T = loop_transfers(loop, "u", 0.0)
    for w in (0.1, 1.0, 10.0):
        s = 1j * w
        assert complex(L(s)) == pytest.approx(1 / s)
        assert complex(S(s)) == pytest.approx(s / (s + 1))
        assert complex(T(s)) == pytest.approx(1 / (s + 1))


def test_the_sensitivitys_poles_are_the_closed_loops():
    loop = discrete_loop()
    lin = linearize(loop, [0.4, -0.2], 0.5)
    _, S, _ = loop_transfers(loop, "u", [0.4, -0.2], 0.5)
    np.testing.assert_allclose(np.sort_complex(S.poles()), np.sort_complex(lin.poles()),
                               atol=1e-12)


def test_a_cut_that_is_not_a_loop_is_refused():
    loop = discrete_loop()
    with pytest.raises(ValueError, match=r"no block outputs a signal 'w'; signals: \['e', "
                                         r"'u', 'y'\]"):
        loop_transfers(loop, "w", [0.4, -0.2], 0.5)
    with pytest.raises(ValueError, match=r"at must name one signal or several"):
        loop_transfers(loop, [], [0.4, -0.2], 0.5)
    twice = ct.interconnect([discrete_loop(), ct.ss([], [], [], [[1.0]], dt=0.1, name="copy",
                                                    inputs="r", outputs="y")],
                            inputs="r", outputs="y", warn_duplicate=False)
    with pytest.raises(ValueError, match=r"'y' is output by blocks \['copy', 'plant'\]"):
        loop_transfers(twice, "y", [0.4, -0.2], 0.5)
    open_chain = ct.interconnect([ct.ss(-1, 1, 1, 0, name="a", inputs="u", outputs="y")],
                                 inputs="u", outputs="y")
    with pytest.raises(ValueError, match=r"no block reads 'a.y', so there is no loop"):
        loop_transfers(open_chain, "y", 0.0, 0.0)


def test_reduced_keeps_what_connects_inputs_to_outputs():
    sys = ct.ss(np.diag([1.0, -2.0, 3.0]), [[1.0], [0.0], [1.0]], [[1.0, 1.0, 0.0]], 0.0)
    assert reduced(sys).state_labels == ["x[0]"]  # x[1] not driven, x[2] not seen
    np.testing.assert_allclose(complex(reduced(sys)(2.0)), complex(sys(2.0)))
    with pytest.raises(ValueError, match=r"outputs \['z'\] are not among \['y\[0\]'\]"):
        reduced(sys, outputs=["z"])


def _pendulum():
    return ct.nlsys(lambda t, x, u, p: np.array([x[1], -np.sin(x[0]) + u[0]]),
                    lambda t, x, u, p: x[:1] * x[1:], states=2, inputs="u", outputs="y",
                    name="pend")


def test_a_zero_d_array_is_a_vector_of_one_as_in_python_control():
    # python-control broadcasts a scalar only (np.isscalar): np.array(0.5) is padded
    with pytest.warns(UserWarning, match="x0 too short"):
        expected = ct.linearize(_pendulum(), np.array(0.5))
    with pytest.warns(UserWarning, match="x0 too short"):
        ours = linearize(_pendulum(), np.array(0.5))
    assert ours.C.tolist() == [[0.0, 0.5]]  # (at [0.5, 0]; broadcast, [0.5, 0.5])
    np.testing.assert_allclose(ours.C, expected.C, atol=1e-6)
    np.testing.assert_allclose(ours.A, expected.A, atol=1e-6)
    assert linearize(_pendulum(), 0.5).A[1, 0] == pytest.approx(-cos(0.5), abs=1e-9)


def test_a_diagram_without_inputs_linearizes_where_python_control_holds_it():
    plant = ct.nlsys(lambda t, x, u, p: np.array([x[1], -2.0 * x[0] - 0.2 * x[1] + u[0]]),
                     lambda t, x, u, p: x[:1], states=2, inputs="u", outputs="y",
                     name="plant")
    lag = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="lag", inputs="y", outputs="z")
    loop = ct.interconnect([plant, lag], inputs=[], outputs=["y", "z"], name="loop",
                           check_unused=False)
    expected, ours = ct.linearize(loop, 0), linearize(loop, 0)
    assert ours.B.shape == expected.B.shape == (3, 0)
    np.testing.assert_allclose(ours.A, expected.A, atol=1e-6)


def test_a_system_of_undeclared_sizes_is_python_control_s_to_size():
    free = ct.nlsys(lambda t, x, u, p: -x + u, None, states=1, name="free")  # (no inputs=)
    assert free.ninputs is None
    assert linearize(free, [1.0], [2.0]).A.tolist() == ct.linearize(free, [1.0],
                                                                       [2.0]).A.tolist()
    assert find_eqpt(free, [0.0], [2.0]).states.tolist() == [2.0]


def test_find_eqpt_takes_python_control_s_later_parameters_by_position():
    loop = ct.nlsys(lambda t, x, u, p: -x + u, lambda t, x, u, p: x, states=1, inputs=1,
                    outputs=1, name="lag")
    args = (loop, 0.5, 1.0, [3.0], 0, None, [], None, None, None, None, "lm")
    expected, ours = ct.find_eqpt(*args), find_eqpt(*args)
    assert np.allclose(ours.states, expected.states) and np.allclose(ours.states, [3.0])
