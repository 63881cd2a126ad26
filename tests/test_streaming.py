"""Streamed long runs: decimated recording equals the full run's samples, and every
sample reaches on_chunk exactly once, in order, on both engines."""

import warnings

import numpy as np
import pytest

from controlkit.engines.contract import recorded_indices
from controlkit.engines.fast import discrete
from controlkit.studies.spacecraft import scenario as spacecraft


@pytest.mark.parametrize("engine_name", ["fast", "python-control"])
def test_decimated_run_keeps_exactly_the_full_runs_samples(engine_name):
    horizon = 50.0 if engine_name == "fast" else 5.0
    full = spacecraft.run("proposed", horizon=horizon, engine=engine_name)
    seen = []
    kept = spacecraft.run("proposed", horizon=horizon, engine=engine_name, record_every=7,
                          on_chunk=lambda t, y, x: seen.append((t.copy(), y.copy(), x.copy())))
    index = recorded_indices(full.time.size, 7)
    assert index[-1] == full.time.size - 1
    np.testing.assert_array_equal(kept.time, full.time[index])
    np.testing.assert_array_equal(kept.outputs, full.outputs[:, index])
    np.testing.assert_array_equal(kept.states, full.states[:, index])
    np.testing.assert_array_equal(np.concatenate([t for t, _, _ in seen]), full.time)
    np.testing.assert_array_equal(np.hstack([y for _, y, _ in seen]), full.outputs)
    np.testing.assert_array_equal(np.hstack([x for _, _, x in seen]), full.states)


def test_streaming_crosses_chunk_boundaries(monkeypatch):
    monkeypatch.setattr(discrete, "STREAM_CHUNK_STEPS", 64)  # many chunks on a short run
    full = spacecraft.run("without_mec", horizon=100.0)
    chunks = []
    kept = spacecraft.run("without_mec", horizon=100.0, record_every=10,
                          on_chunk=lambda t, y, x: chunks.append(t.size))
    assert sum(chunks) == full.time.size and max(chunks) == 64 and len(chunks) == 16
    np.testing.assert_array_equal(kept.outputs, full.outputs[:, ::10])


def test_a_diverging_streamed_run_names_the_divergence():
    # a SamplingError is a FloatingPointError: the plant names the sample where it blew up
    with pytest.raises(FloatingPointError, match="block 'plant' blows up inside a sample at t = "):
        spacecraft.run("without_mec", horizon=50.0, F=50.0, record_every=5)


@pytest.mark.parametrize("bad", [0, -3, 2.5, True])
def test_record_every_must_be_a_positive_integer(bad):
    with pytest.raises(ValueError, match="record_every must be an integer >= 1"):
        spacecraft.run("ideal", horizon=1.0, record_every=bad)


def _damped_loop():
    import control as ct

    plant = ct.nlsys(lambda t, x, u, p: np.array([x[1], -x[0] - 0.4 * x[1] + u[0]]),
                     lambda t, x, u, p: x[:1], inputs="u", outputs="y", states=2,
                     name="plant")
    pi = ct.ss([[0.0]], [[1.0]], [[0.8]], [[2.0]], name="pi", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    return ct.interconnect([plant, pi, error], inputs="r", outputs="y", name="damped")


def test_a_continuous_run_in_chunks_answers_alike_on_both_engines():
    # the reference restarted python-control's solver at each chunk (2.1e-3 off the fast
    # engine's run, which integrates the horizon in one): a continuous run is now one piece
    from controlkit.simulation import simulate

    T = np.linspace(0.0, 10.0, 201)
    reports = []
    runs = [simulate(_damped_loop(), T, X0=np.zeros(3), U=1.0, engine=engine, chunks=7,
                     progress=reports.append) for engine in ("python-control", "fast")]
    one = simulate(_damped_loop(), T, X0=np.zeros(3), U=1.0)
    assert np.array_equal(runs[0].outputs, one.outputs)
    assert np.array_equal(runs[1].outputs, one.outputs)
    assert reports[0] == 1.0 and all(0.0 < f <= 1.0 for f in reports)


def test_chunks_handed_to_on_chunk_stay_as_they_were_and_cannot_be_written(monkeypatch):
    # the fast engine's buffers were handed on and written again by the next chunk
    from controlkit.simulation import simulate

    monkeypatch.setattr(discrete, "STREAM_CHUNK_STEPS", 64)
    loop = spacecraft.build_loop("without_mec")
    full = spacecraft.run("without_mec", horizon=20.0)
    kept = []
    spacecraft.run("without_mec", horizon=20.0, record_every=10,
                   on_chunk=lambda t, y, x: kept.append(y))
    assert len(kept) > 2 and not kept[0].flags.writeable
    np.testing.assert_array_equal(np.hstack(kept), full.outputs)
    with pytest.raises(ValueError, match="read-only"):
        simulate(loop, full.time[:5], X0=full.states[:, 0],
                 on_chunk=lambda t, y, x: y.__imul__(0.0))


def test_simulate_answers_as_a_return_x_response_and_checks_its_arguments_first():
    from controlkit.simulation import simulate

    T = np.linspace(0.0, 1.0, 11)
    resp = simulate(_damped_loop(), T, X0=np.zeros(3), U=1.0, params={})
    t, y, x = resp  # (python-control's response with return_x=True)
    assert x.shape == (3, 11) and resp.params == {}
    with pytest.raises(ValueError, match="compile must be True, False or None"):
        simulate(_damped_loop(), T, X0=np.zeros(3), compile="yes")
    with pytest.raises(TypeError, match="progress must be a function or None, got 5"):
        simulate(_damped_loop(), T, X0=np.zeros(3), engine="fast", progress=5)
    with pytest.raises(ValueError, match="record_every must be an integer >= 1"):
        simulate(_damped_loop(), T, X0=np.zeros(3), engine="fast", record_every=True)


def test_a_sampled_data_diagram_runs_on_the_reference_engine_too():
    import control as ct

    import controlkit
    from controlkit.simulation import simulate

    plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi", inputs="e",
                          outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    mixed = controlkit.interconnect([plant, pi, error], inputs="r", outputs="y")
    T = np.arange(31) * 0.1
    reference = simulate(mixed, T, X0=np.zeros(2), U=1.0, engine="python-control")
    fast = simulate(mixed, T, X0=np.zeros(2), U=1.0, engine="fast")
    assert np.array_equal(reference.outputs, fast.outputs)


def test_a_run_whose_state_turns_nan_stops_on_both_engines():
    # the reference answered 13 NaN states silently where the fast engine stops
    import control as ct

    from controlkit._checks import Diverged
    from controlkit.simulation import simulate

    shrink = ct.nlsys(lambda t, x, u, p: np.array([x[0] - 0.1, np.log(x[0])]),
                      lambda t, x, u, p: x[:1], inputs=1, outputs=1, states=2, dt=0.1,
                      name="shrink")
    loop = ct.interconnect([shrink], inputs="u[0]", outputs="y[0]", name="nan_loop")
    for engine in ("python-control", "fast"):
        with pytest.raises(Diverged, match=r"at t = 0\.[67] s"):
            simulate(loop, np.arange(20) * 0.1, X0=[0.5, 0.0], U=1.0, engine=engine)
    # a system alone answers python-control's numbers on both engines, NaN by design too
    sinc = ct.nlsys(None, lambda t, x, u, p: np.array([np.sin(t) / t]), inputs=0,
                    outputs=1, name="sinc")
    T = np.linspace(0.0, 1.0, 5)
    with np.errstate(invalid="ignore"):
        expected = ct.input_output_response(sinc, T).outputs
        for engine in ("python-control", "fast"):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")  # (a single block: python-control runs it)
                ours = simulate(sinc, T, X0=[], engine=engine).outputs
            assert np.array_equal(ours, expected, equal_nan=True)
