"""Continuous and sampled-data diagrams built the way python-control users build them.

Transfer functions and state-space blocks, summing junctions, and ``nlsys`` blocks whose
functions are written in python-control's idiom (``params`` dicts handed to helpers,
``map(params.get, ...)``, scalar ``np.clip``, numpy), many of them reused from
``tests/idiom_diagrams.py`` with ``dt = 0``. Each builder returns ``(loop, T, X0, U)``.

Continuous (``CONTINUOUS``): a PI around a first-order plant, a PID servo on a DC motor, a
car under a PI speed loop with anti-windup, hares and lynx under state feedback, a
pendulum under a saturated PD, a bicycle under gain-scheduled steering, an adaptive loop
by the MIT rule, a two-tank level loop, and the spacecraft paper's Fig. 2 loop of
controlkit blocks.

Sampled-data (``MIXED``): a continuous plant under a discrete PI, a continuous car
under a discrete PI with anti-windup, a two-rate servo (velocity loop at 10 ms, position
loop at 50 ms), and a continuous mass-spring-damper watched by a discrete observer.
"""

import control as ct
import numpy as np
from idiom_diagrams import (
    ARM,
    ECOSYSTEM,
    arm_dynamics,
    arm_position,
    car_dynamics,
    hares_and_lynx,
    motor_lag,
    steering_loop,
)

from controlkit import interconnect
from controlkit.blocks import spacecraft as sc


def pi_first_order():
    #  r --(+)--> e --[ PI ]--> u --[ 1/(2s+1) ]--+--> y
    #       ^-y                                   |
    plant = ct.tf([1.0], [2.0, 1.0], name="plant", inputs="u", outputs="y")
    pi = ct.tf([1.5, 0.8], [1.0, 0.0], name="pi", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = ct.interconnect([plant, pi, error], inputs="r", outputs=["y", "u"])
    T = np.linspace(0.0, 20.0, 201)
    return loop, T, np.zeros(loop.nstates), np.where(T > 1.0, 1.0, 0.0)


def dc_motor():
    # a DC motor (current, speed, angle) under a PID with a filtered derivative
    J, b, K, R, L = 0.01, 0.1, 0.01, 1.0, 0.5
    motor = ct.ss([[-R / L, 0, -K / L], [K / J, -b / J, 0], [0, 1, 0]], [[1 / L], [0], [0]],
                  [[0, 0, 1]], [[0]], name="motor", inputs="v", outputs="theta")
    pid = ct.tf([30.0, 0.0], [0.01, 1.0]) + ct.tf([100.0], [1.0]) + ct.tf([50.0], [1.0, 0.0])
    pid = ct.tf(pid, name="pid", inputs="e", outputs="v")
    error = ct.summing_junction(["r", "-theta"], "e", name="error")
    loop = ct.interconnect([motor, pid, error], inputs="r", outputs=["theta", "v"])
    T = np.linspace(0.0, 3.0, 301)
    return loop, T, np.zeros(loop.nstates), np.ones_like(T)


def car_pi(dt=0):
    # the car of idiom_diagrams, continuous, under a PI with anti-windup (continuous or,
    # with dt, discrete)
    car = ct.nlsys(car_dynamics, None, inputs=["throttle", "gear", "slope"], outputs="v",
                   states="v", name="car", params={"mass": 1600.0})

    def pi_output(t, x, u, params):
        kp, ki = map(params.get, ["kp", "ki"])
        return np.clip(kp * (u[1] - u[0]) + ki * x[0], 0.0, 1.0)

    def pi_rate(t, x, u, params):
        kp, ki, kaw = params["kp"], params["ki"], params["kaw"]
        command = kp * (u[1] - u[0]) + ki * x[0]
        rate = (u[1] - u[0]) + kaw / ki * (pi_output(t, x, u, params) - command)
        return x[0] + dt * rate if dt else rate

    pi = ct.nlsys(pi_rate, pi_output, inputs=["v", "v_ref"], outputs="throttle", states="z",
                  dt=dt, params={"kp": 0.5, "ki": 0.1, "kaw": 2.0}, name="pi")
    make = interconnect if dt else ct.interconnect
    loop = make([car, pi], inputs=["v_ref", "gear", "slope"], outputs=["v", "throttle"],
                name="cruise")
    T = np.linspace(0.0, 20.0, 201)
    slope = np.deg2rad(np.clip(4.0 * (T - 5.0), 0.0, 4.0))
    U = np.vstack([20.0 * np.ones_like(T), 4.0 * np.ones_like(T), slope])
    return loop, T, np.array([18.0, 0.0]), U


def predator_prey():
    system = ct.nlsys(hares_and_lynx, None, inputs="u", outputs=["H", "L"], states=["H", "L"],
                      params=ECOSYSTEM, name="ecosystem")
    xe, _ = ct.find_operating_point(system, [20.0, 30.0], 0.0)
    linear = system.linearize(xe, 0.0)
    K = ct.place(linear.A, linear.B, [-0.4, -0.5])
    feedback = ct.nlsys(None, lambda t, x, u, params: -K @ (u - xe), inputs=["H", "L"],
                        outputs="u", name="feedback")
    loop = ct.interconnect([system, feedback], outputs=["H", "L", "u"], name="ecosystem_loop")
    T = np.linspace(0.0, 30.0, 121)
    return loop, T, np.array([xe[0] + 5.0, xe[1] - 3.0]), np.zeros((0, T.size))


def pendulum():
    # a pendulum (params through map) under a PD whose torque is clipped by an actuator
    def dynamics(t, x, u, params):
        m, length, b, g = map(params.get, ["m", "l", "b", "g"])
        return [x[1], (u[0] - b * x[1] - m * g * length * np.sin(x[0])) / (m * length ** 2)]

    plant = ct.nlsys(dynamics, None, inputs="tau", outputs=["theta", "omega"],
                     states=["theta", "omega"], name="pendulum",
                     params={"m": 1.0, "l": 0.5, "b": 0.05, "g": 9.81})
    pd = ct.nlsys(None, lambda t, x, u, params: np.clip(
        params["kp"] * (u[0] - u[1]) - params["kd"] * u[2], -params["umax"], params["umax"]),
        inputs=["r", "theta", "omega"], outputs="tau", name="pd",
        params={"kp": 20.0, "kd": 3.0, "umax": 4.0})
    loop = ct.interconnect([plant, pd], inputs="r", outputs=["theta", "tau"])
    T = np.linspace(0.0, 5.0, 251)
    return loop, T, np.array([0.0, 0.0]), np.where(T > 0.5, 1.0, 0.2)


def steering():
    loop = steering_loop(0)
    T = np.linspace(0.0, 10.0, 201)
    U = np.vstack([8.0 * np.ones_like(T), np.where(T > 2.0, 1.0, 0.0)])
    return loop, T, np.array([0.0, -0.5, 0.0]), U


def mrac():
    # model-reference adaptive control of a first-order plant by the MIT rule
    b = 0.5
    plant = ct.ss(-1.0, b, 1.0, 0.0, inputs="u", outputs="y", states="y", name="plant")
    model = ct.ss(-2.0, 2.0, 1.0, 0.0, inputs="r", outputs="ym", states="ym", name="model")

    def adaptation(t, x, u, params):
        gamma, a_m, sign_b = params["gamma"], params["a_m"], params["sign_b"]
        r, ym, y = u
        e = ym - y
        return [a_m * x[0] + a_m * r, -gamma * x[0] * e * sign_b,
                a_m * x[2] + a_m * y, -gamma * x[2] * e * sign_b]

    controller = ct.nlsys(adaptation, lambda t, x, u, params: [x[3] * u[2] + x[1] * u[0]],
                          inputs=["r", "ym", "y"], outputs="u", states=4, name="controller",
                          params={"gamma": 1.0, "a_m": -2.0, "sign_b": np.sign(b)})
    loop = ct.interconnect([plant, model, controller], inputs="r", outputs=["y", "ym", "u"])
    T = np.linspace(0.0, 20.0, 401)
    return loop, T, np.zeros(loop.nstates), np.sign(np.sin(0.6 * T) + 1e-9)


def two_tanks():
    # levels of two tanks in series (outflow a sqrt(h), helper functions) under a PI
    def outflow(level, params):
        return params["a"] * np.sqrt(max(level, 0.0))

    def tanks(t, x, u, params):
        q_in = np.clip(u[0], 0.0, params["qmax"])
        return [(q_in - outflow(x[0], params)) / params["area"],
                (outflow(x[0], params) - outflow(x[1], params)) / params["area"]]

    plant = ct.nlsys(tanks, lambda t, x, u, params: x[1], inputs="q", outputs="h2",
                     states=["h1", "h2"], name="tanks",
                     params={"a": 0.5, "area": 2.0, "qmax": 2.0})
    pi = ct.tf([2.0, 0.4], [1.0, 0.0], name="pi", inputs="e", outputs="q")
    error = ct.summing_junction(["r", "-h2"], "e", name="error")
    loop = ct.interconnect([plant, pi, error], inputs="r", outputs=["h2", "q"])
    T = np.linspace(0.0, 60.0, 241)
    return loop, T, np.array([1.0, 1.0, 0.0]), 2.0 * np.ones_like(T)


def spacecraft_fig2(Ts=None):
    # the spacecraft paper's Fig. 2 of controlkit blocks: continuous, or the continuous
    # plant behind a zero-order hold at Ts (a discrete identity: D/A converter)
    blocks = [sc.spacecraft_plant(), sc.attitude_output(), sc.outer_controller(),
              sc.io_linearizer()]
    outputs = ["h[0]", "h[1]", "u[0]", "u[1]"]
    if Ts is None:
        loop = ct.interconnect(blocks, inputs=["r[0]", "r[1]"], outputs=outputs)
    else:
        blocks[3].set_outputs(["v[0]", "v[1]"])
        hold = ct.ss([], [], [], np.eye(2), dt=Ts, name="zoh", inputs=["v[0]", "v[1]"],
                     outputs=["u[0]", "u[1]"])
        loop = interconnect(blocks + [hold], inputs=["r[0]", "r[1]"], outputs=outputs)
    T = np.linspace(0.0, 200.0, 201)
    X0 = sc.quaternion_from_axis_angle([1, 2, 3], 30.0)
    return loop, T, X0, np.zeros((loop.ninputs, T.size))


def servo_pi_discrete(Ts=0.1):
    plant = ct.tf([1.0], [2.0, 1.0], name="plant", inputs="u", outputs="y")
    pi = ct.sample_system(ct.tf([1.5, 0.8], [1.0, 0.0]), Ts, name="pi", inputs="e",
                          outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = interconnect([plant, pi, error], inputs="r", outputs=["y", "u"])
    T = np.linspace(0.0, 20.0, 201)
    return loop, T, np.zeros(loop.nstates), np.where(T > 1.0, 1.0, 0.0)


def two_rate_servo():
    # the arm of idiom_diagrams (continuous) behind a lagging actuator; a discrete velocity
    # PI at 10 ms inside a discrete position P at 50 ms
    arm = ct.nlsys(arm_dynamics, arm_position, inputs="tau", outputs="y",
                   states=["theta", "omega"], params=ARM, name="arm")
    actuator = ct.nlsys(motor_lag, None, inputs="u", outputs="tau", states="tau",
                        params={"umax": 5, "alpha": 10}, name="actuator")
    velocity = ct.sample_system(ct.tf([40.0, 20.0], [1.0, 0.0]), 0.01, name="velocity",
                                inputs="ev", outputs="u")
    position = ct.ss([], [], [], [[3.0]], dt=0.05, name="position", inputs="ep",
                     outputs="w_ref")
    ev = ct.summing_junction(["w_ref", "-dy"], "ev", name="ev")
    ep = ct.summing_junction(["r", "-y"], "ep", name="ep")
    rate = ct.tf([1.0, 0.0], [0.05, 1.0], name="rate", inputs="y", outputs="dy")
    loop = interconnect([arm, actuator, velocity, position, ev, ep, rate], inputs="r",
                        outputs=["y", "u"])
    T = np.linspace(0.0, 10.0, 501)
    return loop, T, np.zeros(loop.nstates), np.where(T > 0.5, 1.0, 0.0)


def observer():
    # a continuous mass-spring-damper under a static gain on a discrete Luenberger
    # observer's estimate (the observer's matrices held in closures)
    m, k, c, Ts = 1.0, 4.0, 0.4, 0.05
    A = np.array([[0.0, 1.0], [-k / m, -c / m]])
    B = np.array([[0.0], [1.0 / m]])
    plant = ct.ss(A, B, [[1.0, 0.0]], [[0.0]], name="mass", inputs="f", outputs="y")
    sampled = ct.sample_system(ct.ss(A, B, [[1.0, 0.0]], 0.0), Ts)
    Ad, Bd = sampled.A, sampled.B
    L = ct.place(Ad.T, np.array([[1.0, 0.0]]).T, [0.5, 0.6]).T

    def estimate(t, xhat, u, params):
        f, y = u
        return Ad @ xhat + Bd[:, 0] * f + L[:, 0] * (y - xhat[0])

    est = ct.nlsys(estimate, lambda t, x, u, params: x, inputs=["f", "y"],
                   outputs=["p_hat", "v_hat"], states=2, dt=Ts, name="observer")
    gain = ct.nlsys(None, lambda t, x, u, params: params["kr"] * u[2] - 6.0 * u[0] - 2.0 * u[1],
                    inputs=["p_hat", "v_hat", "r"], outputs="f", name="gain",
                    params={"kr": 10.0})
    loop = interconnect([plant, est, gain], inputs="r", outputs=["y", "p_hat", "f"])
    T = np.linspace(0.0, 10.0, 201)
    return loop, T, np.array([0.5, 0.0, 0.0, 0.0]), np.where(T > 2.0, 1.0, 0.0)


CONTINUOUS = {
    "pi_first_order": pi_first_order, "dc_motor": dc_motor, "car_pi": car_pi,
    "predator_prey": predator_prey, "pendulum": pendulum, "steering": steering,
    "mrac": mrac, "two_tanks": two_tanks, "spacecraft_fig2": spacecraft_fig2,
}

MIXED = {
    "servo_pi_discrete": servo_pi_discrete,
    "spacecraft_fig2_zoh": lambda: spacecraft_fig2(Ts=0.1),
    "car_discrete_pi": lambda: car_pi(dt=0.1),
    "two_rate_servo": two_rate_servo,
    "observer": observer,
}
