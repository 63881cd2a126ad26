"""MEC and on-line FRIT tuning (eq. 13-30): RLS, FRIT identity, compensation, errors."""

import control as ct
import numpy as np
import pytest
import scipy.optimize

from controlkit.blocks import frit, mec
from controlkit.blocks import spacecraft as sc
from controlkit.kernels.mec import TUNER_STATE
from controlkit.outputs.common import signal
from controlkit.simulation import initial_state, simulate
from controlkit.studies.spacecraft import scenario as scenario
from controlkit.studies.spacecraft.diagrams import mec_loop, output_zeroing_loop
from controlkit.studies.spacecraft.outputs import metrics

RNG = np.random.default_rng(3)
F, TS = sc.F_PAPER, sc.TS_PAPER
K_TRUE = np.array([[0.3, -0.1], [0.05, 0.2]])


def synthetic(n, noise):
    xi = RNG.normal(size=(n, 2))  # persistently exciting
    eta = xi @ K_TRUE.T + noise * RNG.normal(size=(n, 2))
    return xi, eta


def run_rls(xi, eta, lambda_, gamma):
    Khat, P1, P2 = np.zeros((2, 2)), gamma * np.eye(2), gamma * np.eye(2)
    for x, y in zip(xi, eta, strict=True):
        Khat, P1, P2 = frit.rls_step(Khat, P1, P2, x, y, lambda_)
    return Khat


def test_rls_with_forgetting_converges_to_true_gain():
    xi, eta = synthetic(3000, noise=1e-3)
    Khat = run_rls(xi, eta, lambda_=0.995, gamma=100.0)
    assert np.abs(Khat - K_TRUE).max() < 5e-4  # noise 1e-3, ~200 effective samples


def test_rls_without_forgetting_is_batch_least_squares():
    xi, eta = synthetic(500, noise=0.05)
    gamma = 100.0
    Khat = run_rls(xi, eta, lambda_=1.0, gamma=gamma)
    # RLS from P(0) = gamma I, Khat(0) = 0 solves the least squares with prior 1/gamma |K_j|^2
    batch = np.linalg.solve(xi.T @ xi + np.eye(2) / gamma, xi.T @ eta).T
    np.testing.assert_allclose(Khat, batch, rtol=0, atol=1e-9)
    # a weak prior (gamma = 1e6) is ordinary least squares up to a bias of ~|K| / (gamma n)
    plain = np.linalg.lstsq(xi, eta, rcond=None)[0].T
    np.testing.assert_allclose(run_rls(xi, eta, 1.0, 1e6), plain, rtol=0, atol=1e-8)


def drive_tuner(tuner, inputs):
    """Step the tuner block alone through a sequence of input vectors; return its states."""
    x = tuner.x0.copy()
    states = [x]
    for k, u in enumerate(inputs):
        x = tuner.dynamics(k * TS, x, u)
        states.append(x)
    return np.array(states)


def tuner_inputs(n, error_scale):
    t = np.arange(n) * TS
    h = np.vstack([1e-3 * np.cos(0.01 * t), 1e-3 * np.sin(0.013 * t)]).T
    e = error_scale * np.vstack([np.sin(0.05 * t), np.cos(0.031 * t)]).T
    mu = -F * h + 0.2 * e + 1e-6 * RNG.normal(size=(n, 2))
    return np.hstack([mu, h, h + e])


def test_threshold_freezes_updates_exactly_while_error_is_small():
    tuner = frit.frit_tuner(psi=1e-4, output_scale=1.0)  # psi in units of h
    inputs = tuner_inputs(1000, error_scale=5e-4)
    states = drive_tuner(tuner, inputs)
    e = inputs[:, 4:6] - inputs[:, 2:4]
    S = TUNER_STATE
    rows = [(slice(S.Khat, S.Khat + 2), S.slice("P1"), slice(S.K, S.K + 2)),
            (slice(S.Khat + 2, S.Khat + 4), S.slice("P2"), slice(S.K + 2, S.K + 4))]
    for j, (khat, p, k) in enumerate(rows):
        frozen = np.abs(e[:, j]) < 1e-4
        assert frozen.any() and (~frozen).any()
        for cols in (khat, p, k):
            changed = np.any(states[1:, cols] != states[:-1, cols], axis=1)
            np.testing.assert_array_equal(changed[frozen], False)
        assert np.any(states[1:, khat][~frozen] != states[:-1, khat][~frozen])


def test_low_pass_law_eq30_holds_step_by_step():
    kappa = 0.3
    tuner = frit.frit_tuner(kappa=kappa, psi=0.0)
    states = drive_tuner(tuner, tuner_inputs(300, error_scale=5e-4))
    Khat, K = states[:, TUNER_STATE.slice("Khat")], states[:, TUNER_STATE.slice("K")]
    np.testing.assert_allclose(K[1:], (1 - kappa) * K[:-1] + kappa * Khat[1:], rtol=0, atol=1e-15)


def ideal_filter(v, a, start):
    """M_j under ZOH: m[i+1] = a m[i] + (1 - a) v[i], output m[i]."""
    m = np.empty_like(v)
    m[0] = start
    for i in range(len(v) - 1):
        m[i + 1] = a * m[i] + (1 - a) * v[i]
    return m


def test_rls_target_minimises_the_frit_criterion():
    # record a closed loop with model error and a fixed compensator
    resp = scenario.run("mec_fixed", horizon=3000.0, K=[[0.08, 0.02], [-0.01, 0.12]])
    h = np.vstack([signal(resp, "h[0]"), signal(resp, "h[1]")])
    hn = np.vstack([signal(resp, "hn[0]"), signal(resp, "hn[1]")])
    mu = np.vstack([signal(resp, "mu[0]"), signal(resp, "mu[1]")])
    e = hn - h
    a = np.exp(-F * TS)
    # batch least squares of eq. (21) on the tuner's own regressors
    tuner = frit.frit_tuner(h0=h[:, 0], psi=0.0, lambda_=1.0, gamma=1e6, output_scale=1.0)
    states = drive_tuner(tuner, np.vstack([mu, h, hn]).T[:-1])
    pairs = [frit.frit_regressors(x, h[:, i], tuner.F) for i, x in enumerate(states)]
    xi = np.array([p[0][0] for p in pairs])  # F1 = F2: both rows share one regressor
    eta = np.array([p[1] for p in pairs])
    K_ls = np.linalg.lstsq(xi, eta, rcond=None)[0].T

    # direct minimisation of J(K) = sum (h - M r~(K))^2, eq. (16)-(18), with M filters
    # started as the tuner's (M r~ at rest at h(0))
    def residual(k):
        K = k.reshape(2, 2)
        r_tilde = (mu - K @ e) / F + h
        return np.concatenate([h[j] - ideal_filter(r_tilde[j], a, h[j, 0]) for j in range(2)])

    K_direct = scipy.optimize.least_squares(residual, np.zeros(4), xtol=1e-15, ftol=1e-15,
                                            gtol=1e-15, x_scale=0.1).x.reshape(2, 2)
    np.testing.assert_allclose(K_ls, K_direct, rtol=1e-6, atol=1e-12)  # optimizer tolerance
    # the on-line tuner (lambda = 1) is that least squares with its prior 1/gamma |K_j|^2
    used = slice(0, -1)  # the last state has not been through an update yet
    K_prior = np.linalg.solve(xi[used].T @ xi[used] + np.eye(2) / tuner.gamma,
                              xi[used].T @ eta[used]).T
    Khat = states[-1, TUNER_STATE.slice("Khat")].reshape(2, 2)
    np.testing.assert_allclose(Khat, K_prior, rtol=1e-6)


def test_mec_with_exact_model_changes_almost_nothing():
    q0 = scenario.initial_attitude()
    T = np.arange(30001) * TS
    plain = output_zeroing_loop(scenario.true_plant(False))
    with_mec = mec_loop(scenario.true_plant(False), K=0.1)
    # the MEC's effect, not the engine's (tests/test_engine.py compares the two): the fast
    # engine, about 14x the python-control path on these blocks
    a = simulate(plain, T, X0=initial_state(plain, plant=q0), engine="fast")
    b = simulate(with_mec, T, X0=initial_state(with_mec, plant=q0, nominal=q0[1:3]),
                 engine="fast")
    gap = max(np.abs(signal(a, s) - signal(b, s)).max() for s in ("h[0]", "h[1]"))
    assert gap < 1e-6


def test_fixed_mec_brings_the_loop_back_to_the_ideal_one():
    ideal = scenario.run("ideal", horizon=3000.0)
    without = scenario.run("without_mec", horizon=3000.0)
    fixed = scenario.run("mec_fixed", horizon=3000.0)
    gap = {name: np.abs(signal(r, "h[0]") - signal(ideal, "h[0]")).max()
           for name, r in (("without", without), ("fixed", fixed))}
    assert gap["fixed"] < 0.01 * gap["without"]


def test_frit_tuner_moves_K_away_from_zero_under_model_error():
    resp = scenario.run("proposed", horizon=3000.0)
    K = np.vstack([signal(resp, f"K[{i}]") for i in range(4)])
    assert np.all(np.isfinite(K))
    assert np.abs(K[:, -1]).max() > 1e-3


@pytest.mark.parametrize("kwargs, message", [
    ({"lambda_": 0.0}, r"lambda_ must lie in \(0, 1\]"),
    ({"lambda_": 1.01}, r"lambda_ must lie in \(0, 1\]"),
    ({"kappa": 0.0}, r"kappa must lie in \(0, 1\]"),
    ({"kappa": 1.5}, r"kappa must lie in \(0, 1\]"),
    ({"psi": -1e-4}, r"psi must be >= 0"),
    ({"psi": [1e-4, -1e-4]}, r"psi must be >= 0"),
    ({"gamma": 0.0}, r"gamma must be finite and > 0"),
    ({"gamma": -100.0}, r"gamma must be finite and > 0"),
    ({"K0": [1.0, 2.0, 3.0]}, r"K0 must be a scalar or a 2x2 matrix"),
    ({"F": 0.0}, r"F must be > 0 for the FRIT tuner"),
    ({"Ts": 0.0}, r"Ts must be finite and > 0"),
])
def test_tuner_rejects_bad_settings(kwargs, message):
    with pytest.raises(ValueError, match=message):
        frit.frit_tuner(**kwargs)


@pytest.mark.parametrize("K", [[1.0, 2.0, 3.0], np.ones((3, 3)), [[np.nan, 0], [0, 1]]])
def test_constant_gain_rejects_wrong_shape(K):
    with pytest.raises(ValueError, match=r"K must be"):
        mec.constant_gain(K)


def test_tuner_period_must_match_the_loop():
    with pytest.raises(ValueError, match=r"block 'tuner' runs at dt = 0.2 s but mec_loop runs "
                                         r"at Ts = 0.1 s"):
        mec_loop(K=frit.frit_tuner(Ts=0.2), Ts=0.1)


def test_gain_source_must_output_K():
    wrong = ct.nlsys(None, lambda t, x, u, p: [0, 0], inputs=0, outputs=2, dt=None, name="g")
    with pytest.raises(ValueError, match=r"the gain source must output"):
        mec_loop(K=wrong)


def test_unknown_gain_keyword():
    with pytest.raises(ValueError, match=r'K must be a gain, "frit" or a gain-source block'):
        mec_loop(K="rls")


def test_removing_fixing_and_tuning_are_one_argument_each():
    names = {k: [s.name for s in mec_loop(K=k).syslist] for k in (0.1, "frit")}
    assert "gain" in names[0.1] and "tuner" in names["frit"]
    assert [s.name for s in output_zeroing_loop().syslist] == [
        "plant", "output", "controller", "linearizer"]


def test_fixed_mec_meets_requirement_over_last_half():
    m = metrics(scenario.run("mec_fixed"))
    assert m["requirement_met_last_half"]


def test_paper_claim_proposed_meets_requirement_without_mec_does_not():
    proposed = metrics(scenario.run("proposed"))
    without = metrics(scenario.run("without_mec"))
    assert proposed["max_pointing_error_last_half_deg"] < sc.POINTING_REQUIREMENT_DEG
    assert without["max_pointing_error_last_half_deg"] > sc.POINTING_REQUIREMENT_DEG
    # the gain changes gently (paper, after eq. 30) and the wheels stay slow
    assert proposed["peak_abs_u1_rad_s"] < 2.0 and max(abs(k) for k in proposed["final_K"]) < 5.0


def test_literal_reading_of_table3_lets_the_gain_burst():
    # decision D1: P(0) = 100 I and psi = 0.00012 in units of q (not degrees) wind the RLS
    # covariance up; measured max |K| 417 and a last-half worst error of 0.37 deg
    resp = scenario.run("proposed_literal")
    K = np.array([signal(resp, f"K[{i}]") for i in range(4)])
    assert np.abs(K).max() > 100.0
    assert metrics(resp)["max_pointing_error_last_half_deg"] > sc.POINTING_REQUIREMENT_DEG


def test_output_scale_is_the_tuner_seeing_scaled_data():
    s = frit.DEGREES_PER_QUATERNION_UNIT
    inputs = tuner_inputs(600, error_scale=5e-4)
    h0 = inputs[0, 2:4]
    scaled = drive_tuner(frit.frit_tuner(output_scale=s, h0=h0), inputs)
    plain = drive_tuner(frit.frit_tuner(h0=s * h0, output_scale=1.0), s * inputs)
    K = TUNER_STATE.slice("K")
    np.testing.assert_allclose(scaled[:, K], plain[:, K], rtol=1e-9, atol=1e-12)
    assert np.abs(scaled[-1, K]).max() > 1e-3  # the gain did move


def test_output_scale_must_be_positive():
    with pytest.raises(ValueError, match=r"output_scale must be finite and > 0"):
        frit.frit_tuner(output_scale=0.0)


# --- the readings the paper leaves open (filter, start, freeze, units) -------------------

@pytest.mark.parametrize(("filter_", "ahead"), [("zoh", 0), ("feedthrough", 1)])
def test_filter_reading_sets_which_sample_the_regressors_come_from(filter_, ahead):
    # kappa = 1 and psi = 0 make each step a bare RLS step on that step's regressors
    inputs = tuner_inputs(200, error_scale=5e-4)
    tuner = frit.frit_tuner(h0=inputs[0, 2:4], psi=0.0, kappa=1.0, units="q", filter=filter_)
    states = drive_tuner(tuner, inputs)
    S = TUNER_STATE
    for k in range(0, 200, 17):
        # "zoh" reads the filters before sample k (m[k]); "feedthrough" after it (m[k+1])
        xi, eta = frit.frit_regressors(states[k + ahead], inputs[k, 2:4], tuner.F)
        np.testing.assert_array_equal(xi[0], xi[1])  # F1 = F2: one regressor for both rows
        P1, P2 = (states[k, S.slice(name)].reshape(2, 2) for name in ("P1", "P2"))
        Khat, P1n, _ = frit.rls_step(states[k, S.slice("Khat")].reshape(2, 2), P1, P2,
                                    xi[0], eta, tuner.lambda_)
        np.testing.assert_allclose(states[k + 1, S.slice("Khat")], Khat.ravel(),
                                   rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(states[k + 1, S.slice("P1")], P1n.ravel(), rtol=1e-12)


def test_filter_readings_share_the_filter_states_and_differ_in_the_gain():
    inputs = tuner_inputs(300, error_scale=5e-4)
    zoh, ft = (drive_tuner(frit.frit_tuner(h0=inputs[0, 2:4], filter=f, units="q", psi=0.0),
                           inputs) for f in ("zoh", "feedthrough"))
    filters = np.r_[TUNER_STATE.slice("Mxi1"), TUNER_STATE.slice("Mxi2"),
                    TUNER_STATE.slice("Mmu"), TUNER_STATE.slice("Mh")]
    np.testing.assert_array_equal(zoh[:, filters], ft[:, filters])
    K = TUNER_STATE.slice("K")
    assert np.abs(zoh[-1, K] - ft[-1, K]).max() > 1e-3 * np.abs(zoh[-1, K]).max() > 0


def test_start_reading_changes_only_the_initial_state_of_the_M_h_filters():
    h0 = [0.01, -0.02]
    rest, zero = frit.frit_tuner(h0=h0, start="rest"), frit.frit_tuner(h0=h0, start="zero")
    np.testing.assert_array_equal(rest.kernels.params, zero.kernels.params)
    differs = np.nonzero(rest.x0 != zero.x0)[0]
    np.testing.assert_array_equal(differs, np.arange(*TUNER_STATE.slice("Mh").indices(24)))
    np.testing.assert_array_equal(rest.x0[TUNER_STATE.slice("Mh")], h0)
    np.testing.assert_array_equal(zero.x0[TUNER_STATE.slice("Mh")], 0.0)


def test_joint_freeze_freezes_both_rows_exactly_when_the_larger_error_is_below_psi():
    psi = 3e-4
    inputs = tuner_inputs(1500, error_scale=5e-4)
    e = np.abs(inputs[:, 4:6] - inputs[:, 2:4])
    states = drive_tuner(frit.frit_tuner(psi=psi, units="q", freeze="joint",
                                        h0=inputs[0, 2:4]), inputs)
    S = TUNER_STATE
    frozen = e.max(axis=1) < psi
    assert frozen.any() and (~frozen).any()
    steps = np.diff(states[:, S.slice("Khat")], axis=0)
    P_steps = np.diff(states[:, np.r_[S.slice("P1"), S.slice("P2")]], axis=0)
    assert not np.any(steps[frozen]) and not np.any(P_steps[frozen])
    # where one error is below psi and the other is not, the row reading would freeze one
    # row; the joint reading updates both
    split = ~frozen & (e.min(axis=1) < psi)
    assert split.sum() > 10
    assert np.all(np.abs(P_steps[split]).reshape(-1, 2, 4).max(axis=2) > 0)


@pytest.mark.parametrize(("units", "scale"), [("deg", 360 / np.pi), ("q", 1.0)])
def test_units_reading_is_an_output_scale(units, scale):
    by_units = frit.frit_tuner(units=units, h0=[0.01, 0.02])
    by_scale = frit.frit_tuner(output_scale=scale, h0=[0.01, 0.02])
    np.testing.assert_array_equal(by_units.kernels.params, by_scale.kernels.params)
    np.testing.assert_array_equal(by_units.x0, by_scale.x0)
    assert by_units.readings["units"] == units


@pytest.mark.parametrize(("option", "value"), [("filter", "tustin"), ("start", "rested"),
                                               ("freeze", "both"), ("units", "rad")])
def test_unknown_reading_is_refused_with_the_allowed_ones(option, value):
    with pytest.raises(ValueError, match=rf"{option} must be one of \("):
        frit.frit_tuner(**{option: value})
