"""Six diagrams a python-control user would build: python-control primitives and user functions
only (no controlkit block). Shared by tests/test_user_diagrams.py and
benchmarks/bench_user_diagrams.py. Each builder returns ``(loop, T, X0, U, params)``."""

import control as ct
import numpy as np

TS = 0.05


def lti_loop(steps=400):
    """All LTI: sampled plant and PI transfer functions, summing junctions, disturbance input.

    ::

        r -->o-- e --> [PI] -- v -->o-- u --> [plant] --+--> y
             ^-                     ^ d                 |
             +-------------------------------------------+
    """
    plant = ct.sample_system(ct.tf([2.0], [1.0, 1.5, 1.0]), TS, name="plant",
                             inputs="u", outputs="y")
    pi = ct.sample_system(ct.tf([1.2, 0.8], [1.0, 0.0]), TS, name="pi", inputs="e", outputs="v")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    disturbance = ct.summing_junction(["v", "d"], "u", name="disturbance")
    loop = ct.interconnect([plant, pi, error, disturbance], inputs=["r", "d"],
                           outputs=["y", "u"], name="lti_loop")
    T = np.arange(steps) * TS
    U = np.vstack([np.ones_like(T), 0.5 * (T > 5.0)])
    return loop, T, np.zeros(loop.nstates), U, None


def pendulum_under_pi(steps=400):
    """A continuous nonlinear pendulum (user nlsys, params) sampled by sample_nlsys, under a
    sampled PI transfer function."""
    from controlkit.blocks.sampling import sample_nlsys

    def pendulum(t, x, u, params):
        g, length = params.get("g", 9.81), params["length"]
        return np.array([x[1], -g / length * np.sin(x[0]) - params["damping"] * x[1] + u[0]])

    plant = ct.nlsys(pendulum, lambda t, x, u, params: x[0], inputs="tau", outputs="theta",
                     states=["theta", "omega"], params={"length": 0.5, "damping": 0.2},
                     name="pendulum")
    sampled = sample_nlsys(plant, TS, substeps=4)
    pi = ct.sample_system(ct.tf([8.0, 4.0], [1.0, 0.0]), TS, name="pi",
                          inputs="e", outputs="tau")
    error = ct.summing_junction(["ref", "-theta"], "e", name="error")
    loop = ct.interconnect([sampled, pi, error], inputs="ref", outputs=["theta", "tau"],
                           name="pendulum_loop")
    T = np.arange(steps) * TS
    X0 = np.zeros(loop.nstates)
    X0[:2] = [0.3, 0.0]
    return loop, T, X0, 0.8 * np.ones_like(T), None


def tank_with_params(steps=400):
    """A discrete user tank (params dict with .get defaults) under a proportional valve,
    simulated with a parameter changed for the run."""

    def tank(t, x, u, params):
        area = params["area"]
        leak = params.get("leak", 0.1)
        inflow = min(max(u[0], 0.0), params.get("max_flow", 2.0))
        return x + TS * (inflow - leak * np.sqrt(abs(x[0]))) / area

    plant = ct.nlsys(tank, lambda t, x, u, params: x, inputs="q", outputs="level",
                     states="level", dt=TS, params={"area": 1.5}, name="tank")
    valve = ct.nlsys(None, lambda t, x, u, params: params.get("kp", 3.0) * (u[0] - u[1]),
                     inputs=["level_ref", "level"], outputs="q", dt=None, name="valve")
    loop = ct.interconnect([plant, valve], inputs="level_ref", outputs=["level", "q"],
                           name="tank_loop")
    T = np.arange(steps) * TS
    return loop, T, [0.2], 1.0 + 0.5 * np.sin(0.3 * T), {"leak": 0.3}


def adaptive_loop(steps=400):
    """An adaptive controller with states (MIT-rule gains) around an unknown first-order plant,
    closures over numpy arrays for the adaptation gains."""
    gamma = np.array([0.8, 0.6])
    a_m, b_m = 0.9, 0.1

    def plant_update(t, x, u, params):
        return np.array([params["a"] * x[0] + params["b"] * u[0]])

    plant = ct.nlsys(plant_update, None, inputs="u", outputs="y", states="y", dt=TS,
                     params={"a": 0.95, "b": 0.2}, name="plant")
    model = ct.ss([[a_m]], [[b_m]], [[1.0]], [[0.0]], dt=TS, name="model",
                  inputs="r", outputs="ym", states="ym")

    def adapt(t, x, u, params):  # u = r, y, ym ; x = theta_r, theta_y
        e = u[1] - u[2]
        return x - TS * gamma * e * np.array([u[0], -u[1]])

    def control_law(t, x, u, params):
        return x[0] * u[0] - x[1] * u[1]

    controller = ct.nlsys(adapt, control_law, inputs=["r", "y", "ym"], outputs="u",
                          states=["theta_r", "theta_y"], dt=TS, name="adaptive")
    loop = ct.interconnect([plant, model, controller], inputs="r",
                           outputs=["y", "ym", "u"], name="adaptive_loop")
    T = np.arange(steps) * TS
    X0 = np.zeros(loop.nstates)
    return loop, T, X0, np.sign(np.sin(0.2 * T)), None


def gain_scheduled(steps=400):
    """A static gain-scheduled controller (np.interp over a schedule held in closures) on a
    user plant whose gain varies with its speed."""
    speeds = np.array([0.0, 1.0, 2.0, 4.0])
    gains = np.array([2.0, 1.5, 1.0, 0.6])

    def cart(t, x, u, params):
        return np.array([x[0] + TS * (-0.4 * x[0] + (1.0 + 0.5 * x[0]) * u[0])])

    plant = ct.nlsys(cart, None, inputs="f", outputs="v", states="v", dt=TS, name="cart")

    def scheduled(t, x, u, params):
        k = np.interp(u[1], speeds, gains)
        return k * (u[0] - u[1])

    controller = ct.nlsys(None, scheduled, inputs=["v_ref", "v"], outputs="f", dt=None,
                          name="scheduler")
    loop = ct.interconnect([plant, controller], inputs="v_ref", outputs=["v", "f"],
                           name="scheduled_loop")
    T = np.arange(steps) * TS
    return loop, T, [0.0], np.minimum(T, 3.5), None


def sampled_lti_plant(steps=400):
    """A continuous LTI plant (mass-spring-damper) sampled by sample_nlsys under a static
    state feedback with reference gain (an LTI static block) and an output summing junction."""
    from controlkit.blocks.sampling import sample_nlsys

    msd = ct.ss([[0.0, 1.0], [-4.0, -0.4]], [[0.0], [1.0]], np.eye(2), np.zeros((2, 1)),
                name="msd", inputs="F", outputs=["p", "v"], states=["p", "v"])
    plant = sample_nlsys(msd, TS)
    feedback = ct.ss(np.zeros((0, 0)), np.zeros((0, 3)), np.zeros((1, 0)),
                     [[5.0, -3.0, -1.2]], dt=None, name="feedback",
                     inputs=["p_ref", "p", "v"], outputs="F")
    loop = ct.interconnect([plant, feedback], inputs="p_ref", outputs=["p", "v", "F"],
                           name="msd_loop")
    T = np.arange(steps) * TS
    return loop, T, [0.1, 0.0], np.ones_like(T), None


DIAGRAMS = {
    "all-LTI loop": lti_loop,
    "pendulum under sampled PI": pendulum_under_pi,
    "user nlsys with params": tank_with_params,
    "adaptive controller": adaptive_loop,
    "gain-scheduled controller": gain_scheduled,
    "sampled LTI plant": sampled_lti_plant,
}
