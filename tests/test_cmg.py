"""CMG: plant invariants, reduced model, references, the thesis case and its errors."""

import control as ct
import numpy as np
import pytest

from controlkit.blocks import cmg
from controlkit.blocks.sampling import sample_nlsys
from controlkit.studies.cmg import scenario as scenario
from controlkit.studies.cmg.diagrams import cmg_loop
from controlkit.studies.cmg.outputs import metrics, table

RNG = np.random.default_rng(11)
J = cmg.Inertias()


def random_state():
    return np.array([RNG.uniform(-3, 3), RNG.uniform(0.1, 1.4), RNG.uniform(-3, 3),
                     RNG.normal(0, 20), RNG.normal(0, 2), RNG.normal(0, 2)])


def test_axis4_momentum_is_constant_without_axis4_friction():
    friction = cmg.Friction(b1=2e-4, b2=5e-3, c1=0.03, c2=0.02)  # none on axis 4
    plant = cmg.cmg_plant(delta_IG4x=0.005, friction=friction)
    # the smooth Coulomb terms are stiff where a rate crosses zero: 10 RK4 steps per ms
    sampled = sample_nlsys(plant, 0.001, substeps=10)
    T = np.arange(10001) * 0.001
    U = np.vstack([0.5 * np.sin(3 * T) + 0.2 * np.sign(np.sin(7 * T)), 2.0 * np.cos(2 * T)])
    x0 = [0.0, 0.6, 0.0, 30.0, 0.0, 0.1]
    resp = ct.input_output_response(sampled, T, U, x0)
    p4 = np.array([cmg.axis4_momentum(x, J, 0.005) for x in resp.states.T])
    assert np.abs(p4 - p4[0]).max() <= 1e-9 * abs(p4[0])


def test_plant_satisfies_printed_equations_1_to_3():
    friction = cmg.Friction(b1=2e-4, b2=5e-3, b4=1e-3, c1=0.03, c2=0.02, c4=0.01)
    plant = cmg.cmg_plant(delta_IG4x=0.005, friction=friction)
    I1, I2 = J.I1, J.I2 + 0.005
    for _ in range(20):
        x, T = random_state(), RNG.normal(0, 1, size=2)
        _, q2, _, w1, w2, w4 = x
        dw1, dw2, dw4 = plant.dynamics(0.0, x, T)[3:]
        F1, F2, F4 = friction.torques([w1, w2, w4])
        s, c = np.sin(q2), np.cos(q2)
        eq1 = J.IR1y * dw1 + J.IR1y * s * dw4 + J.IR1y * w2 * w4 * c - (T[0] + F1)
        eq2 = (J.IG2x + J.IR1x) * dw2 - J.IR1y * w1 * w4 * c - I1 * w4**2 * s * c - (T[1] + F2)
        eq3 = (J.IR1y * s * dw1 + (I2 + I1 * s**2) * dw4 + I1 * w2 * w4 * np.sin(2 * q2)
               + J.IR1y * w1 * w2 * c - F4)
        np.testing.assert_allclose([eq1, eq2, eq3], 0.0, atol=1e-12)


def test_reduced_model_agrees_with_plant_without_friction_and_inertia_change():
    plant = cmg.cmg_plant()
    for _ in range(20):
        x, T = random_state(), RNG.normal(0, 1, size=2)
        _, q2, _, w1, w2, w4 = x
        s, c = np.sin(q2), np.cos(q2)
        D = J.I2 + (J.I1 - J.IR1y) * s**2
        f2 = (J.IR1y * w1 * w4 * c + J.I1 * w4**2 * s * c) / J.J2
        f4 = (J.IR1y * w2 * w4 * s * c - J.I1 * w2 * w4 * np.sin(2 * q2)
              - J.IR1y * w1 * w2 * c) / D
        dw2, dw4 = plant.dynamics(0.0, x, T)[[4, 5]]
        assert dw2 == pytest.approx(f2 + T[1] / J.J2, rel=1e-12, abs=1e-12)
        assert dw4 == pytest.approx(f4 - s / D * T[0], rel=1e-12, abs=1e-12)


@pytest.mark.parametrize("t_switch", [2.0, 8.0])
def test_references_are_continuous_with_continuous_first_derivative(t_switch):
    before, after = cmg.reference(t_switch - 1e-9), cmg.reference(t_switch + 1e-9)
    np.testing.assert_allclose(before[[0, 1, 3, 4]], after[[0, 1, 3, 4]], atol=1e-8)
    assert cmg.reference(0.0)[0] == pytest.approx(np.pi / 18)
    assert cmg.reference(12.0)[[0, 3]] == pytest.approx([np.pi / 3, 1.0])


def test_reference_derivatives_match_finite_differences():
    for t in (2.5, 4.0, 7.3):
        h = 1e-6
        r = cmg.reference(t)
        d = (cmg.reference(t + h) - cmg.reference(t - h)) / (2 * h)
        np.testing.assert_allclose(d[[0, 1, 3, 4]], r[[1, 2, 4, 5]], rtol=1e-6, atol=1e-8)


def test_thesis_case_tracks_within_bounds():
    m = metrics(scenario.run("thesis"))
    assert m["max_abs_q2_error_after_1s_rad"] < 2e-3
    assert m["max_abs_q4_error_after_1s_rad"] < 2e-3
    assert m["peak_abs_T1_applied_Nm"] <= cmg.T1_MAX
    assert m["peak_abs_T2_applied_Nm"] <= cmg.T2_MAX
    assert m["peak_abs_T2_commanded_Nm"] < cmg.T2_MAX  # gimbal 2 never needs saturation
    assert max(m["max_abs_estimates"]) < 1.0  # bounded estimates


def test_friction_beyond_eta_leaves_a_tracking_error():
    thesis = metrics(scenario.run("thesis", horizon=6.0))
    strong = metrics(scenario.run("strong_friction", horizon=6.0))
    assert strong["max_abs_q2_error_after_1s_rad"] > 3 * thesis["max_abs_q2_error_after_1s_rad"]


def test_boundary_layer_smooths_the_torque():
    def roughness(**kw):
        c = table(scenario.run("thesis", horizon=1.0, x0=[0, 0.3, 0, 0, 0, 0], **kw))
        return np.abs(np.diff(c["T2"])).mean()
    assert roughness(boundary_layer=0.05) < 0.1 * roughness()


def test_csv_columns_in_order(tmp_path):
    from controlkit.cli import main
    main(["reproduce", "cmg", "--horizon", "0.05", "--out", str(tmp_path)])
    header = (tmp_path / "cmg" / "run.csv").read_text().splitlines()[0]
    assert header == "time,q1,q2,q4,w1,w2,w4,q2d,q4d,T1,T2,a1,a2,a3,a4"
    for stem in ("fig3_q2", "fig4_q4", "fig5_T1", "fig6_T2"):
        assert (tmp_path / "cmg" / f"{stem}.png").exists()


@pytest.mark.parametrize("field", ["IR1y", "IR1x", "IG2x", "IG2y", "IG2z", "IG3x", "IG4x"])
def test_non_positive_inertia_is_refused(field):
    with pytest.raises(ValueError, match=rf"{field} must be finite and > 0"):
        cmg.Inertias(**{field: 0.0})


def test_inertia_change_must_keep_gimbal4_inertia_positive():
    with pytest.raises(ValueError, match=r"delta_IG4x must keep IG4x \+ delta_IG4x > 0"):
        cmg.cmg_plant(delta_IG4x=-0.1)


@pytest.mark.parametrize("q2", [0.0, -0.1, np.pi / 2, 2.0])
def test_initial_q2_outside_range_is_refused(q2):
    with pytest.raises(ValueError, match=r"q2 must lie in \(0, pi/2\)"):
        scenario.run(horizon=0.01, x0=[0, q2, 0, 0, 0, 0])


@pytest.mark.parametrize("gain", ["C1", "C4", "eta1", "eta2"])
def test_negative_gains_are_refused(gain):
    with pytest.raises(ValueError, match=rf"{gain} must be finite and >= 0"):
        cmg.adaptive_smc(**{gain: -1.0})


@pytest.mark.parametrize("gain", ["gamma1", "gamma4"])
def test_adaptation_gains_must_be_positive(gain):
    with pytest.raises(ValueError, match=rf"{gain} must be finite and > 0"):
        cmg.adaptive_smc(**{gain: 0.0})


def test_unknown_gain_is_refused():
    with pytest.raises(ValueError, match=r"unknown gain\(s\) \['C5'\]"):
        cmg.adaptive_smc(C5=1.0)


def test_controller_refuses_vanishing_sin_q2():
    with pytest.raises(ValueError, match=r"divides by sin\(q2\)"):
        cmg.smc_law([0, 1e-5, 0, 0, 0, 0], cmg.reference(0.0), np.zeros(4), J,
                    cmg.GAINS_THESIS)


def test_controller_ignores_the_all_zero_trial_sweep():
    smc = cmg.adaptive_smc()
    np.testing.assert_array_equal(smc.output(0.0, smc.x0, np.zeros(12))[:2], [0.0, 0.0])


def test_loop_refuses_mismatched_periods():
    with pytest.raises(ValueError, match=r"block 'smc' runs at dt = 0.002 s"):
        cmg_loop(controller=cmg.adaptive_smc(Ts=0.002), Ts=0.001)


@pytest.mark.parametrize("call, message", [
    (lambda: cmg.cmg_plant().dynamics(0.0, [0, 0.5, 0], [0.0, 0.0]),
     r"block 'cmg': the state x must have 6 values \(q1, q2, q4, w1, w2, w4\), got shape \(3,\)"),
    (lambda: cmg.adaptive_smc().output(0.0, np.zeros(4), np.zeros(6)),
     r"block 'smc': the input u must have 12 values \(q1, q2, \.\.\., q4d_ddot\)"),
    (lambda: cmg.accelerations([0, 0.5, 0], [0.0, 0.0], J), r"x must be a vector of length 6"),
    (lambda: cmg.accelerations([0, 0.5, 0, 0, 0, np.nan], [0.0, 0.0], J), r"x must be finite"),
    (lambda: cmg.smc_law([0, 0.5, 0], cmg.reference(0.0), np.zeros(4), J, cmg.GAINS_THESIS),
     r"x must be a vector of length 6"),
    (lambda: cmg.smc_law([0, 0.5, 0, 0, 0, 0], cmg.reference(0.0), np.zeros(3), J,
                         cmg.GAINS_THESIS), r"a_hat must be a vector of length 4"),
    (lambda: cmg.smc_law([0, 0.5, 0, 0, 0, 0], cmg.reference(0.0), np.zeros(4), J, {"C1": 1}),
     r"adaptive SMC parameters: missing \['C2'"),
    (lambda: cmg.reference(np.nan), r"t must be finite"),
    (lambda: cmg.axis4_momentum([0, 0.5, 0], J), r"x must be a vector of length 6"),
    (lambda: cmg.Friction(b1=1.0).torques([0.0, 1.0]), r"w must be a vector of length 3"),
])
def test_wrong_sizes_and_values_are_refused(call, message):
    with pytest.raises(ValueError, match=message):
        call()


@pytest.mark.parametrize("measured, seen", [
    ([0, np.nan, 0, 0, 0, 0], r"the CMG controller received non-finite signals"),
    ([0, 100 * np.pi, 0, 0, 0, 0], r"gimbal 2 is at q2 = 314 rad"),  # sin q2 ~ 1e-14
])
def test_diverged_loop_is_not_reported_as_vanishing_sin_q2(measured, seen):
    smc = cmg.adaptive_smc()
    with pytest.raises(FloatingPointError, match=r"the loop diverged at t = 2 s: " + seen):
        smc.output(2.0, smc.x0, np.concatenate([measured, cmg.reference(2.0)]))
