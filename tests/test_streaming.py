"""Streamed long runs: decimated recording equals the full run's samples, and every
sample reaches on_chunk exactly once, in order, on both engines."""

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
