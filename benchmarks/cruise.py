"""python-control's cruise-control PI loop, as its example writes it, for the benchmarks.

The vehicle and the anti-windup PI controller of python-control's
``examples/cruise-control.py`` (Astrom & Murray, *Feedback Systems*, section 4.1): functions
``f(t, x, u, params)`` reading a ``params`` dict with ``params.get``, a helper handed
``params``, ``np.clip`` on scalars. :func:`loop` builds the loop continuous, or discrete at
``dt`` (the vehicle sampled under zero-order hold, the PI discrete), and optionally rewired
with a low-pass filter on the measured speed. The continuous loop imports python-control
only (a script timing python-control alone can build it).
"""

from math import copysign, sin

import control as ct
import numpy as np


def motor_torque(omega, params={}):  # noqa: B006 - the example's own signature
    Tm = params.get("Tm", 190.0)
    omega_m = params.get("omega_m", 420.0)
    beta = params.get("beta", 0.4)
    return np.clip(Tm * (1 - beta * (omega / omega_m - 1) ** 2), 0, None)


def vehicle_update(t, x, u, params={}):  # noqa: B006
    m = params.get("m", 1600.0)
    g = params.get("g", 9.8)
    Cr = params.get("Cr", 0.01)
    Cd = params.get("Cd", 0.32)
    rho = params.get("rho", 1.3)
    A = params.get("A", 2.4)
    alpha = params.get("alpha", [40, 25, 16, 12, 10])
    v = x[0]
    throttle = np.clip(u[0], 0, 1)
    gear = u[1]
    theta = u[2]
    omega = alpha[int(gear) - 1] * v
    F = alpha[int(gear) - 1] * motor_torque(omega, params) * throttle
    Fg = m * g * sin(theta)
    Fr = m * g * Cr * copysign(1, v)
    Fa = 1 / 2 * rho * Cd * A * abs(v) * v
    return (F - (Fg + Fr + Fa)) / m


def pi_output(t, x, u, params={}):  # noqa: B006
    kp = params.get("kp", 0.5)
    ki = params.get("ki", 0.1)
    return kp * (u[1] - u[0]) + ki * x[0]


def pi_rate(t, x, u, params={}):  # noqa: B006
    ki = params.get("ki", 0.1)
    kaw = params.get("kaw", 2.0)
    u_a = pi_output(t, x, u, params)
    u_aw = kaw / ki * (np.clip(u_a, 0, 1) - u_a) if ki != 0 else 0
    return (u[1] - u[0]) + u_aw


def pi_update(t, x, u, params={}):  # noqa: B006
    return [x[0] + params.get("dt", 0.1) * pi_rate(t, x, u, params)]


def filter_rate(t, x, u, params={}):  # noqa: B006
    return (u[0] - x[0]) / params.get("tau", 0.5)


def filter_update(t, x, u, params={}):  # noqa: B006
    a = np.exp(-params.get("dt", 0.1) / params.get("tau", 0.5))
    return [a * x[0] + (1 - a) * u[0]]


def loop(dt=None, filtered=False, points=20_000, horizon=None):
    """The loop: continuous (``dt=None``) or discrete at ``dt``; with a speed filter.

    Returns ``(loop, T, X0, U)`` for ``points`` time points, ``dt`` apart (0.01 s for the
    continuous loop), or spread evenly over ``horizon`` seconds when it is given
    (python-control's example: 301 points over 30 s). The road climbs a 4 degree hill
    from t = 10 s.
    """
    vehicle = ct.nlsys(vehicle_update, None, inputs=["u", "gear", "theta"], outputs="v",
                       states="v", name="vehicle")
    measured = "vf" if filtered else "v"
    if dt is None:
        pi = ct.nlsys(pi_rate, pi_output, inputs=[measured, "vref"], outputs="u",
                      states="z", name="pi")
        blocks = [vehicle, pi]
        if filtered:
            blocks.append(ct.nlsys(filter_rate, lambda t, x, u, p: x[0], inputs="v",
                                   outputs="vf", states="xf", name="filter"))
    else:
        from controlkit.blocks.sampling import sample_nlsys

        pi = ct.nlsys(pi_update, pi_output, inputs=[measured, "vref"], outputs="u",
                      states="z", dt=dt, params={"dt": dt}, name="pi")
        blocks = [sample_nlsys(vehicle, dt), pi]
        if filtered:
            blocks.append(ct.nlsys(filter_update, lambda t, x, u, p: x[0], inputs="v",
                                   outputs="vf", states="xf", dt=dt, params={"dt": dt},
                                   name="filter"))
    sys = ct.interconnect(blocks, inputs=["vref", "gear", "theta"], outputs=["v", "u"],
                          name="cruise_filtered" if filtered else "cruise")
    if horizon is None:
        T = np.arange(points) * (dt or 0.01)
    else:
        T = np.linspace(0.0, horizon, points)
    theta = np.deg2rad(np.clip(4.0 * (T - 10.0), 0.0, 4.0))  # a hill from t = 10 s
    U = np.vstack([20.0 * np.ones_like(T), 4.0 * np.ones_like(T), theta])
    X0 = np.array([18.0, 0.0] + ([18.0] if filtered else []))
    return sys, T, X0, U
