"""sample_nlsys: exact ZOH on linear systems, accurate on nonlinear ones."""

import control as ct
import numpy as np
import pytest
import scipy.integrate

from controlkit.blocks.sampling import sample_nlsys, time_grid

A = np.array([[0.0, 1.0], [-2.0, -3.0]])
B = np.array([[0.0], [1.0]])
C = np.array([[1.0, 0.0]])


@pytest.mark.parametrize("method, options", [("rk4", {"substeps": 10}), ("solve_ivp", {})])
def test_linear_system_matches_control_sample_system(method, options):
    Ts = 0.1
    exact = ct.sample_system(ct.ss(A, B, C, 0), Ts, method="zoh")
    sampled = sample_nlsys(ct.ss(A, B, C, 0), Ts, method=method, **options)
    assert sampled.dt == Ts
    T = np.arange(51) * Ts
    U = np.sin(0.7 * T) + 0.3 * np.cos(3.1 * T)
    x0 = [0.5, -0.2]
    ours = ct.input_output_response(sampled, T, U, x0, return_x=True)
    ref = ct.input_output_response(exact, T, U, x0, return_x=True)
    np.testing.assert_allclose(ours.states, ref.states, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.outputs, ref.outputs, rtol=0, atol=1e-9)


def test_nonlinear_system_matches_solve_ivp_under_zoh():
    def rhs(t, x, u, params):  # forced Van der Pol with a time-varying term
        return [x[1], params["m"] * (1 - x[0] ** 2) * x[1] - x[0] + u[0] + 0.1 * np.sin(t)]

    vdp = ct.nlsys(rhs, None, inputs=1, states=2, outputs=2, params={"m": 1.5}, name="vdp")
    Ts = 0.05
    sampled = sample_nlsys(vdp, Ts, substeps=40)
    T = np.arange(101) * Ts
    U = np.cos(2 * T)
    resp = ct.input_output_response(sampled, T, U, [1.0, 0.0], return_x=True)
    x = np.array([1.0, 0.0])
    for k, t in enumerate(T[:-1]):
        np.testing.assert_allclose(resp.states[:, k], x, rtol=0, atol=1e-9)
        sol = scipy.integrate.solve_ivp(lambda tau, xi, uk=U[k]: rhs(tau, xi, [uk], {"m": 1.5}),
                                        (t, t + Ts), x, method="DOP853", rtol=1e-13, atol=1e-14)
        x = sol.y[:, -1]


def test_parameters_pass_through():
    sys = ct.nlsys(lambda t, x, u, p: -p["a"] * x, None, inputs=0, states=1, outputs=1,
                   params={"a": 1.0})
    sampled = sample_nlsys(sys, 0.1, substeps=20)
    assert sampled.dynamics(0.0, [1.0], [], params={"a": 2.0})[0] == pytest.approx(
        np.exp(-0.2), abs=1e-10)


@pytest.mark.parametrize("Ts", [0, -0.1, np.inf])
def test_non_positive_sampling_period_is_refused(Ts):
    with pytest.raises(ValueError, match=r"Ts must be finite and > 0"):
        sample_nlsys(ct.ss(A, B, C, 0), Ts)


def test_discrete_system_is_refused():
    with pytest.raises(ValueError, match=r"sys must be continuous time"):
        sample_nlsys(ct.ss(A, B, C, 0, 0.1), 0.1)


@pytest.mark.parametrize("kwargs, message", [
    ({"method": "euler"}, r"method must be one of \('rk4', 'solve_ivp'\)"),
    ({"substeps": 0}, r"substeps must be an integer >= 1"),
])
def test_bad_options_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        sample_nlsys(ct.ss(A, B, C, 0), 0.1, **kwargs)


def test_time_grid_refuses_horizon_not_multiple_of_Ts():
    with pytest.raises(ValueError, match=r"horizon must be a positive multiple of Ts"):
        time_grid(1.05, 0.1)
