"""The Fig. 2 loop: exact linearization, and what model error does to it."""

import control as ct
import numpy as np

from controlkit.blocks import spacecraft as sc
from controlkit.blocks.common import lowpass_filter
from controlkit.blocks.sampling import sample_nlsys
from controlkit.outputs.common import signal
from controlkit.simulation import initial_state, simulate
from controlkit.studies.spacecraft import scenario as scenario
from controlkit.studies.spacecraft.diagrams import linearized_plant, output_zeroing_loop
from controlkit.studies.spacecraft.outputs import metrics

F, TS = sc.F_PAPER, sc.TS_PAPER


def check_exact_linearization(resp):
    h = np.vstack([signal(resp, "h[0]"), signal(resp, "h[1]")])
    h0 = scenario.initial_attitude()[1:3]
    k = np.arange(h.shape[1])
    discrete_ideal = np.outer(h0, (1 - F * TS) ** k)
    continuous_ideal = np.outer(h0, np.exp(-F * resp.time))
    assert np.abs(h - discrete_ideal).max() < 1e-7
    assert np.abs(h - continuous_ideal).max() < 1e-5


def test_linearized_plant_is_an_integrator_per_sample():
    sys = linearized_plant()
    q0 = scenario.initial_attitude()
    mu = np.array([[2e-5], [-1e-5]]) * np.ones((1, 11))
    resp = ct.input_output_response(sys, np.arange(11) * TS, mu,
                                    initial_state(sys, plant=q0))
    h = resp.outputs[:2]
    np.testing.assert_allclose(h[:, -1] - h[:, 0], 10 * TS * mu[:, 0], rtol=1e-6)


def test_ideal_loop_follows_exact_linear_model_over_2000_s():
    check_exact_linearization(scenario.run("ideal", horizon=2000.0))


def test_chunked_run_equals_single_run_bit_for_bit():
    loop = output_zeroing_loop(scenario.true_plant(True))
    T = np.arange(301) * TS
    X0 = initial_state(loop, plant=scenario.initial_attitude())
    whole = simulate(loop, T, X0=X0)
    chunked = simulate(loop, T, X0=X0, chunks=7)
    np.testing.assert_array_equal(whole.outputs, chunked.outputs)
    np.testing.assert_array_equal(whole.states, chunked.states)
    assert list(chunked.output_labels) == list(loop.output_labels)


def test_model_error_spoils_the_linearization_early():
    ideal = scenario.run("ideal", horizon=500.0)
    error = scenario.run("without_mec", horizon=500.0)
    gap = np.abs(signal(error, "h[0]") - signal(ideal, "h[0]")).max()
    assert gap > 1e-4


def test_ideal_full_horizon_meets_linear_model_and_points_exactly():
    resp = scenario.run("ideal")
    check_exact_linearization(resp)
    assert metrics(resp)["final_pointing_error_deg"] < 1e-3


def test_without_mec_oscillates_and_misses_requirement():
    m = metrics(scenario.run("without_mec"))
    assert 0.4 < m["final_pointing_error_deg"] < 0.7
    assert not m["requirement_met_last_half"]


def test_lowpass_filter_in_the_fig2_loop_runs_the_same_on_both_engines():
    # controller -> v -> low-pass -> mu -> linearizer: the block of docs/writing-a-block.md
    tau = 50.0
    plant = sample_nlsys(sc.spacecraft_plant(), TS)
    controller = sc.outer_controller(F, output="v")
    lowpass = lowpass_filter(tau, TS, input="v", output="mu")
    loop = ct.interconnect(
        [plant, sc.attitude_output(), controller, lowpass, sc.io_linearizer()],
        inputs=["r[0]", "r[1]"], outputs=["h[0]", "h[1]", "v[0]", "v[1]", "mu[0]", "mu[1]"])
    T = np.arange(2001) * TS
    X0 = initial_state(loop, plant=scenario.initial_attitude())
    ref = simulate(loop, T, X0=X0, engine="python-control")
    fast = simulate(loop, T, X0=X0, engine="fast")
    np.testing.assert_array_equal(fast.outputs, ref.outputs)
    np.testing.assert_array_equal(fast.states, ref.states)
    # the filter's recursion, step by step (oracle written out here)
    v, mu = fast.outputs[2:4], fast.outputs[4:6]
    a = np.exp(-TS / tau)
    np.testing.assert_allclose(mu[:, 1:], a * mu[:, :-1] + (1 - a) * v[:, :-1], rtol=1e-12,
                               atol=1e-18)
    # the lag slows the loop but, with tau F << 1, it still zeroes h
    h = fast.outputs[:2]
    assert np.abs(h[:, -1]).max() < 0.9 * np.abs(h[:, 0]).max()
    assert np.abs(h[:, -1] - np.exp(-F * T[-1]) * h[:, 0]).max() > 1e-3  # but lags Fig. 2
