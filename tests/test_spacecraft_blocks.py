"""Spacecraft blocks: invariants of eq. (1)-(11) and every error a user can trigger."""

import numpy as np
import pytest

from controlkit.blocks import spacecraft as sc
from controlkit.simulation import initial_state, simulate
from controlkit.studies.spacecraft import scenario as scenario
from controlkit.studies.spacecraft.diagrams import output_zeroing_loop

RNG = np.random.default_rng(7)


def random_quaternion():
    q = RNG.normal(size=4)
    return q / np.linalg.norm(q)


def test_rotation_matrix_is_orthonormal_and_matches_kinematics():
    q = random_quaternion()
    R = sc.rotation_matrix(q)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-14)
    # eq. (4) belongs to R: d/dt R = R [w]x for q' = Q(q) w
    w, dt = RNG.normal(size=3), 1e-6
    q_plus = q + dt * sc.quaternion_rate_matrix(q) @ w
    q_minus = q - dt * sc.quaternion_rate_matrix(q) @ w
    dR = (sc.rotation_matrix(q_plus) - sc.rotation_matrix(q_minus)) / (2 * dt)
    wx = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    np.testing.assert_allclose(dR, R @ wx, atol=1e-8)


def test_momentum_invariant_and_unit_norm_along_closed_loop_run():
    plant = scenario.true_plant(model_error=True)
    loop = output_zeroing_loop(plant)
    T = np.arange(5001) * 0.1
    resp = simulate(loop, T, X0=initial_state(loop, plant=scenario.initial_attitude()))
    labels = list(resp.output_labels)
    q = resp.outputs[[labels.index(f"q[{i}]") for i in range(4)]]
    u = resp.outputs[[labels.index("u[0]"), labels.index("u[1]")]]
    np.testing.assert_allclose(np.linalg.norm(q, axis=0), 1.0, rtol=0, atol=1e-12)
    J_b, J_w1, J_w2 = sc.J_BN + sc.DELTA_J, sc.J_W1, sc.J_W2
    for k in range(0, len(T), 250):
        qk, uk, t = q[:, k], u[:, k], T[k]
        # recover w_b from the block's own q' (Q^T Q = I/4 for a unit q), then eq. (1)
        w_b = 4 * sc.quaternion_rate_matrix(qk).T @ plant.dynamics(t, qk, uk)
        H = sc.total_momentum(qk, w_b, uk, J_b, J_w1, J_w2, sc.V1, sc.V2)
        H0 = sc.paper_momentum(t)
        assert np.linalg.norm(H - H0) <= 1e-9 * np.linalg.norm(H0)


def test_linearizer_makes_h_dot_equal_mu_with_exact_model():
    plant = sc.spacecraft_plant(H0=[0.01, -0.02, 0.03])
    lin = sc.io_linearizer(H0n=[0.01, -0.02, 0.03])
    for _ in range(20):
        q, mu = random_quaternion(), RNG.normal(size=2) * 1e-3
        u = lin.output(0.0, [], np.concatenate([mu, q]))
        q_dot = plant.dynamics(0.0, q, u)
        np.testing.assert_allclose(q_dot[1:3], mu, rtol=1e-10, atol=1e-15)


def test_linearizer_alpha_vanishes_for_zero_nominal_momentum():
    lin = sc.io_linearizer()
    q = random_quaternion()
    np.testing.assert_array_equal(lin.output(0.0, [], np.concatenate([[0, 0], q])), [0, 0])


def test_zero_trial_input_does_not_trip_the_singularity_check():
    lin = sc.io_linearizer()
    np.testing.assert_array_equal(lin.output(0.0, [], np.zeros(6)), [0.0, 0.0])


@pytest.mark.parametrize("q", [[0.0, 1.0, 0.0, 0.0], [1e-9, 0.6, 0.8, 0.0]])
def test_singular_decoupling_matrix_names_the_attitude(q):
    with pytest.raises(sc.SingularDecouplingError, match=r"undefined at attitude q = \[") as e:
        sc.io_linearizer().output(0.0, [], np.concatenate([[1e-3, 0], q]))
    assert isinstance(e.value, ValueError)
    assert "180 deg rotation about an axis in the body x-y plane" in str(e.value)


@pytest.mark.parametrize("u, seen", [
    ([np.nan, 0.0, 1.0, 0.0, 0.0, 0.0],
     r"the linearizer received non-finite inputs \(mu = \[nan, 0.0\]"),
    ([1e-3, 0.0, 0.0, 1e92, 0.0, 0.0], r"the plant's quaternion norm is 1e\+92"),
])
def test_diverged_loop_is_not_reported_as_a_singular_attitude(u, seen):
    with pytest.raises(FloatingPointError, match=r"the loop diverged at t = 4 s: " + seen):
        sc.io_linearizer().output(4.0, [], u)


@pytest.mark.parametrize("engine", ["fast", "python-control"])
def test_unstable_gain_is_reported_as_divergence_on_both_engines(engine):
    # F Ts = 5: the sampled outer loop multiplies h by 1 - F Ts = -4 each step
    with pytest.raises(FloatingPointError, match=r"the loop diverged at t = 1 s: the plant's "
                                                 r"quaternion norm is .*likely a gain too high"):
        scenario.run("ideal", horizon=5.0, F=50.0, engine=engine)


@pytest.mark.parametrize("call, message", [
    (lambda: sc.io_linearizer().output(0, [], [1e-3, 0, 1]),
     r"block 'linearizer': the input u must have 6 values \(mu\[0\], mu\[1\], q\[0\]"),
    (lambda: sc.spacecraft_plant().dynamics(0, [1, 0, 0, 0], [1.0]),
     r"block 'plant': the input u must have 2 values \(u\[0\], u\[1\]\), got shape \(1,\)"),
    (lambda: sc.spacecraft_plant().dynamics(0, [1, 0, 0], [1.0, 0.0]),
     r"block 'plant': the state x must have 4 values"),
    (lambda: sc.outer_controller().output(0, [], [0, 0, 1]),
     r"block 'controller': the input u must have 4 values \(r\[0\], r\[1\], h\[0\], h\[1\]\)"),
    (lambda: sc.quaternion_from_axis_angle([0, 0, 1], np.nan), r"angle_deg must be finite"),
    (lambda: sc.rotation_matrix([1, 0, 0]), r"q must be a vector of length 4"),
    (lambda: sc.body_rate([1, 0, 0, 0], [0.0], np.zeros(3), np.eye(3), sc.V1, sc.V2),
     r"u must be a vector of length 2"),
])
def test_wrong_sizes_and_values_are_refused_at_the_block_boundary(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_body_rate_attribute_is_the_integrated_equation():
    plant = sc.spacecraft_plant(H0=sc.paper_momentum)
    q, u, t = random_quaternion(), np.array([3.0, -2.0]), 1234.5
    w = plant.body_rate(t, q, u)
    # oracle: eq. (2) written out with numpy
    b1, b2 = sc.J_W1 @ sc.V1, sc.J_W2 @ sc.V2
    expected = np.linalg.solve(sc.J_M, sc.rotation_matrix(q).T @ sc.paper_momentum(t)
                               - b1 * u[0] - b2 * u[1])
    np.testing.assert_allclose(w, expected, rtol=1e-12)
    np.testing.assert_allclose(plant.dynamics(t, q, u), sc.quaternion_rate_matrix(q) @ w,
                               rtol=1e-12, atol=1e-18)


def test_singular_attitude_stops_simulation_with_clear_error():
    with pytest.raises(ValueError, match=r"decoupling matrix dh/dq g\(q\) is singular"):
        scenario.run("ideal", horizon=1.0, q_initial=[0.0, 0.6, 0.8, 0.0])


def test_pointing_error_of_table2_attitude():
    # h = [q1, q2] = sin(15 deg) [1, 2] / sqrt(14): arccos(1 - 2 |h|^2)
    q = scenario.initial_attitude()
    expected = np.rad2deg(np.arccos(1 - 2 * np.sin(np.deg2rad(15)) ** 2 * 5 / 14))
    assert sc.pointing_error_deg(q) == pytest.approx(expected, rel=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"J_b": [4000, -1, 6000]}, r"J_b must be positive definite"),
        ({"J_b": [[1, 2, 0], [0, 1, 0], [0, 0, 1]]}, r"J_b must be symmetric"),
        ({"J_w1": [[1, 0], [0, 1]]}, r"J_w1 must be a 3x3 inertia matrix"),
        ({"v1": [0, 0, 0]}, r"wheel axis v1 must be a non-zero 3-vector"),
        ({"v2": [2, 0, 0]}, r"wheel axes v1 and v2 must not be parallel"),
        ({"H0": lambda t: [0, 0]}, r"H0 must return a finite 3-vector"),
        ({"H0": [0, 0, np.nan]}, r"H0 must be finite"),
    ],
)
def test_plant_rejects_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message):
        sc.spacecraft_plant(**kwargs)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"J_m": np.diag([1.0, 0.0, 1.0])}, r"J_m must be positive definite"),
        ({"v1": [0, 1, 0]}, r"must not be parallel"),
        ({"singular_tol": 0}, r"singular_tol must be finite and > 0"),
    ],
)
def test_linearizer_rejects_bad_parameters(kwargs, message):
    with pytest.raises(ValueError, match=message):
        sc.io_linearizer(**kwargs)


@pytest.mark.parametrize("F", [-0.0009, [0.0009, -1.0], np.nan])
def test_outer_controller_rejects_negative_gain(F):
    with pytest.raises(ValueError, match=r"F must be finite and >= 0"):
        sc.outer_controller(F)


def test_outer_controller_rejects_non_diagonal_gain():
    with pytest.raises(ValueError, match=r"F must be diagonal"):
        sc.outer_controller([[1, 0.1], [0, 1]])


@pytest.mark.parametrize("q", [[1, 0.1, 0, 0], [2, 0, 0, 0], [0, 0, 0, 0]])
def test_non_unit_initial_quaternion_is_refused(q):
    with pytest.raises(ValueError, match=r"q_initial must be a unit quaternion"):
        scenario.run("ideal", horizon=1.0, q_initial=q)


def test_unknown_case_is_refused():
    allowed = (r"\['ideal', 'mec_fixed', 'proposed', 'proposed_literal', 'safeguarded', "
               r"'without_mec'\]")
    with pytest.raises(ValueError, match=r"case must be one of " + allowed):
        scenario.build_loop("with_mec_typo")


def test_pointing_error_keeps_precision_for_tiny_angles():
    angle = 1e-9  # rad about x
    q = [np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0]
    assert sc.pointing_error_deg(q) == pytest.approx(np.rad2deg(angle), rel=1e-12)
