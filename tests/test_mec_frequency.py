"""What the MEC does to the spacecraft's loop, as numbers: the inertia errors each loop
tolerates (eigenvalues of its linearization at the target, confirmed by simulations of
the nonlinear loop), its margins at the plant input, and the band where the MEC lowers
the input sensitivity; and the files ``controlkit reproduce`` writes with them."""

from __future__ import annotations

import dataclasses
import io
import json

import numpy as np
import pytest

from controlkit.studies import STUDIES
from controlkit.studies.reproduce import reproduce
from controlkit.studies.spacecraft import frequency as fq

T, F = 0.1, 0.0009
#: A gain of the kind the paper's FRIT reading ends with (far from diagonal, eigenvalues
#: 0.18 +- 0.48j): the proposed case's final K over 20 000 s.
K_FRIT = np.array([[-2.25732835, 2.9160642], [-2.12180953, 2.62554211]])


@pytest.mark.parametrize("direction", ["x", "y"])
def test_the_fixed_gains_bound_is_the_sampled_error_loops(direction):
    """Per axis the loop is h[k+1] = h[k] + Ts g mu[k] with g = J_m / J_t: with
    mu = -F h + K (hn - h) it loses stability at z = -1, for g = 4 / (2 Ts (F + K) - Ts^2 K F).
    """
    K = 0.1
    bounds = fq.tolerated(K, direction)
    assert bounds["low_ratio"] == pytest.approx((2 * T * (F + K) - T**2 * K * F) / 4, rel=1e-4)
    assert bounds["high"] is None and bounds["stable_at_table2"]


def test_without_mec_every_physical_inertia_is_tolerated():
    """Its limit, J_t / J_m = Ts F / 2 = 4.5e-5, needs a body lighter than its wheels."""
    for direction in ("delta_J", "x", "y", "z"):
        bounds = fq.tolerated(None, direction, points=6)
        assert bounds["low"] is None and bounds["high"] is None
    assert fq.spectral_radius(None, fq.physical_limit("x") + 0.01, "x") < 1.0


def test_the_z_axis_inertia_does_not_enter_the_loop_at_the_target():
    radii = {fq.spectral_radius(K_FRIT, s, "z") for s in (-150.0, 1.0, 500.0)}
    assert len(radii) == 1
    assert fq.tolerated(K_FRIT, "z", points=6)["low"] is None


def test_a_frit_gain_bounds_the_y_axis_on_both_sides_as_its_margin_says():
    bounds = fq.tolerated(K_FRIT, "y")
    assert bounds["low_ratio"] == pytest.approx(0.1175, abs=1e-3)
    assert bounds["high_ratio"] == pytest.approx(1.1573, abs=1e-3)
    # the same limit read off python-control's gain margin of the loop cut at u[1]
    margin = fq.margins(fq.transfers(K_FRIT, at="u[1]").L)["gain_margin"]
    assert bounds["high_ratio"] == pytest.approx(fq._ratio(1.0, "y") / margin, rel=1e-4)


@pytest.mark.parametrize("K, direction", [(0.1, "x"), (K_FRIT, "y")])
def test_each_bound_is_confirmed_by_simulations_inside_and_outside(K, direction):
    bounds = fq.tolerated(K, direction)
    confirmed = fq.confirmations(K, bounds, direction)
    sides = [side for side in ("low", "high") if bounds[f"{side}_ratio"] is not None]
    assert sides and set(confirmed) == set(sides)
    for side in sides:
        inside, outside = confirmed[side]["inside"], confirmed[side]["outside"]
        assert inside["stable"] and inside["predicted_stable"] and inside["growth"] < 1.0
        assert not outside["stable"] and not outside["predicted_stable"]
        assert outside["diverged"] or outside["growth"] > 1.0


def test_the_family_shortcut_is_the_full_linearization():
    family = fq.LoopFamily(K_FRIT, "y")
    for scale in (-100.0, 1.0, 40.0):
        assert family.radius(scale) == pytest.approx(fq.spectral_radius(K_FRIT, scale, "y"),
                                                     abs=1e-13)


def test_the_mec_lowers_the_input_sensitivity_below_cos_w_ts_1_minus_k_ts_g_over_2():
    g = 1.0 / fq._ratio(1.0, "delta_J")  # Table 2's error
    (low, high), = fq.sensitivity_band(0.1)
    assert low == 0.0
    assert high == pytest.approx(np.arccos(1 - 0.1 * T * g / 2) / T, rel=2e-3)
    (low, high), = fq.sensitivity_band(K_FRIT)
    assert low == 0.0 and high < 0.1  # the FRIT gain lowers it far less widely


def test_the_gain_margins_at_the_plant_input_include_the_crossing_at_the_nyquist_frequency():
    margins = fq.margins(fq.transfers(None, at="u[0]").L)
    g = 1.0 / fq._ratio(1.0, "delta_J")
    assert margins["gain_margin"] == pytest.approx(2 / (T * F * g), rel=1e-6)
    assert margins["phase_crossover_rad_s"] == pytest.approx(np.pi / T)
    assert margins["phase_margin_deg"] == pytest.approx(90.0, abs=0.01)


@pytest.fixture
def without_papers_figures(monkeypatch):
    """The spacecraft study without its Fig. 5-10 (other tests' business): these tests
    wait for their own files only."""
    study = dataclasses.replace(STUDIES["spacecraft"], figure_stems=(), stems_for=None,
                                figures=lambda tables, folder: [])
    monkeypatch.setitem(STUDIES, "spacecraft", study)


@pytest.mark.usefixtures("without_papers_figures")
def test_reproduce_writes_the_bounds_and_the_frequency_figures(tmp_path):
    reproduce("spacecraft", out=tmp_path, cases=["proposed"], horizon=20.0,
              log=io.StringIO(), workers=0)
    folder = tmp_path / "spacecraft"
    manifest = json.loads((folder / "run.json").read_text())
    report = json.loads((folder / "mec_frequency.json").read_text())
    assert manifest["complete"]
    expected = {"mec_frequency.json"} | {f"{stem}.{ext}" for stem, _ in fq_outputs_figures()
                                        for ext in ("png", "svg")}
    assert expected <= set(manifest["files"])
    assert all((folder / name).is_file() for name in expected)
    assert set(report["loops"]) == {"without MEC", "MEC, K = 0.1 I", "MEC, K from FRIT"}
    fixed = report["loops"]["MEC, K = 0.1 I"]
    assert fixed["tolerated"]["delta_J"]["low"] == pytest.approx(-198.994, abs=0.01)
    assert fixed["confirmed"]["delta_J"]["low"]["outside"]["stable"] is False


@pytest.mark.usefixtures("without_papers_figures")
def test_reproduce_without_the_proposed_case_writes_no_frequency_files(tmp_path):
    reproduce("spacecraft", out=tmp_path, cases=["ideal"], horizon=1.0, log=io.StringIO(),
              workers=0)
    assert not (tmp_path / "spacecraft" / "mec_frequency.json").exists()


def fq_outputs_figures():
    from controlkit.studies.spacecraft.frequency_outputs import FIGURES

    return FIGURES
