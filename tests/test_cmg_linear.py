"""The CMG loop linearized at rest: no linearization with sgn, one with a boundary layer,
and the thinnest layer whose sampled loop is stable (the onset of chattering)."""

from __future__ import annotations

import pytest

from controlkit.blocks.cmg import GAINS_THESIS, TS_CMG
from controlkit.studies.cmg import linear


def test_the_thinnest_stable_boundary_layer_is_eta_ts_over_2_minus_c_ts():
    """Inside the layer s[k+1] = (1 - Ts (C + eta / phi)) s[k]: stable while
    Ts (C + eta / phi) < 2."""
    eta, C = GAINS_THESIS["eta1"], GAINS_THESIS["C2"]
    phi = linear.critical_boundary_layer(rtol=1e-4)
    assert phi == pytest.approx(eta * TS_CMG / (2 - C * TS_CMG), rel=5e-3)
    assert linear.closed_loop_radius(1.05 * phi) < 1.0 < linear.closed_loop_radius(0.95 * phi)


def test_with_sgn_the_difference_quotient_grows_as_one_over_the_step():
    radii = [linear.closed_loop_radius(0.0, eps=h) for h in (1e-4, 1e-6, 1e-8)]
    assert 1.0 < radii[0] and radii[1] > 50 * radii[0]
    assert radii[2] / radii[1] == pytest.approx(100.0, rel=0.01)  # ~ eta / h: no derivative
