"""Diagrams built the python-control way run compiled, with python-control's numbers."""

import numpy as np
import pytest
from user_diagrams import DIAGRAMS

from controlkit import engine
from controlkit.simulation import simulate


@pytest.mark.parametrize("name", list(DIAGRAMS))
def test_user_diagram_is_compiled_and_equals_python_control(name):
    loop, T, X0, U, params = DIAGRAMS[name]()
    tiers = engine.explain(loop, params=params)
    assert [row.tier for row in tiers] == ["compiled"] * len(loop.syslist), tiers
    ref = simulate(loop, T, X0, U, params=params)
    fast = simulate(loop, T, X0, U, params=params, engine="fast")
    assert list(fast.state_labels) == list(ref.state_labels)
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.states, ref.states, rtol=0, atol=1e-9)
    assert np.abs(ref.outputs).max() > 0.1  # the loop does something
