"""Random diagrams in python-control's idiom, and their comparison with python-control.

The differential fuzzer of issue 33: :func:`make_case` draws a diagram and a call from a
seed; :func:`compare` runs the call through ``control.input_output_response`` (for a
diagram of continuous and discrete blocks, which python-control cannot build, through
controlkit's plain-Python reference, ``engine="python-control"``) and through the drop-in
``controlkit.input_output_response``, and says whether they answered alike. Used by
tests/test_fuzz.py (a fixed set of seeds, and a longer run under the ``slow`` marker) and
benchmarks/fuzz.py (counts over many seeds).

The blocks are written the way python-control's examples and course notebooks write them:
``ct.nlsys`` with ``(t, x, u, params)`` functions reading ``params.get`` with defaults, a
``params`` dict handed to a helper, ``map(params.get, ...)``, scalar ``np.clip``, ``math``,
``min``/``max``, lambdas, closures made by a factory, a ``functools.partial``, a callable
object, bound methods, a decorated function, branches, loops over coefficients, lookup
tables, ``ct.tf``/``ct.ss``/``ct.sample_system`` and ``ct.summing_junction``. A few are
hazards a student's code has: a square root or logarithm of a state that can leave the
domain, a table indexed by a state that can run off its end, ``round`` of a Python float,
a ``print``. Their numbers are drawn so that most loops stay bounded over the horizon; the
functions stay cheap (a template compiles once and is reused by every diagram).

Each diagram is one of: a feedback loop (reference, error junction, controller, optional
filters and disturbance, plant), an open chain, two parallel branches mixed, or a lone
system (also with sizes left for python-control to find). Discrete diagrams run at
:data:`TS`; continuous ones in continuous time; mixed ones put continuous plants under
discrete controllers at :data:`TS` or ``2 TS``.

Verdicts (:class:`Verdict`): ``equal``; ``differ`` (a number, a shape, a label, the time
points, the printed text (not for mixed diagrams, whose reference calls the functions in
its own pattern) or a warning of python-control's differs; ``detail`` says which and by
how much);
``same error`` (both raise the same exception type; ``detail`` says whether the messages
differ); ``other error`` (python-control raises and controlkit raises another type or
answers, or controlkit raises where python-control answers); ``diverged`` (python-control
returns non-finite numbers and controlkit refuses them with a ``FloatingPointError``, as
controlkit does by design). :func:`judged_apart` runs the seeds in a child process, so
that a run which kills its process (compiled code reading far outside an array) is the
verdict ``crashed`` and the seeds after it are still judged; with a time limit, a case
over it is ``too long``.

    python tests/fuzz_diagrams.py FIRST COUNT RESULTS [HAZARD_RATE [LIMIT]]

judges seeds FIRST .. FIRST+COUNT-1 and appends one JSON line per seed to the file
RESULTS (the child process of :func:`judged_apart`).

Tolerances: discrete runs to 1e-12 of each signal's size (at least 1), continuous and
mixed ones to 1e-9 (docs/sampled-data.md: "to 1e-9" for RK45, RK23, DOP853).
"""

from __future__ import annotations

import contextlib
import functools
import io
import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import control as ct
import numpy as np

import controlkit

#: Sampling period of the discrete blocks (a mixed diagram's slower ones run at 2 TS).
TS = 0.05
#: Largest difference allowed, relative to each signal's size (at least 1).
TOLERANCE = {"discrete": 1e-12, "continuous": 1e-9, "mixed": 1e-9}
KINDS = ("discrete", "continuous", "mixed")
VERDICTS = ("equal", "differ", "same error", "other error", "diverged", "crashed",
            "too long")


# ============================================================================ the blocks
#
# Each template builds one SISO block: template(rng, dt, name, inputs, outputs) -> system.
# dt = 0: continuous; dt = TS (or 2 TS): discrete; a static block gets dt=None.
# Plants have no direct feedthrough (their output is a function of their state), so any
# loop closed through a plant is free of algebraic loops.

def _draw(rng, low, high, digits=3):
    """A number in [low, high), rounded to ``digits`` significant digits (readable cases)."""
    value = float(rng.uniform(low, high))
    return float(f"{value:.{digits}g}")


# --- plants: state x, input u, output y -----------------------------------------------
# lag:       dx/dt = (-x + gain u) / tau                      params tau, gain

def lag_rate(t, x, u, params):
    tau = params.get("tau", 1.0)
    gain = params.get("gain", 1.0)
    return (-x + gain * u) / tau


# tank:      dh/dt = (max(q, 0) - c sqrt(max(h, 0))) / A      params area, outflow
def tank_rate(t, x, u, params):
    area, outflow = params["area"], params["outflow"]
    level = max(x[0], 0.0)
    return [(np.clip(u[0], 0, None) - outflow * np.sqrt(level)) / area]


# pendulum:  theta'' = (tau - b theta' - m g l sin theta) / (m l^2); y = theta
def pendulum_rate(t, x, u, params):
    m, length, b, g = map(params.get, ["m", "l", "b", "g"])
    theta, omega = x
    return np.array([omega, (u[0] - b * omega - m * g * length * np.sin(theta))
                     / (m * length ** 2)])


def first_state(t, x, u, params):
    return x[0]


# friction:  mass on a spring with Coulomb friction, smoothed (tanh) so that a stuck mass
#            does not make an integrator chatter; y = position
def friction_rate(t, x, u, params={}):  # noqa: B006 - python-control's examples do this
    k = params.get("k", 4.0)
    c = params.get("c", 0.3)
    mu = params.get("mu", 0.2)
    position, velocity = x[0], x[1]
    friction = mu * np.tanh(velocity / params.get("v_smooth", 0.05))
    return [velocity, u[0] - k * position - c * velocity - friction]


# car:       m dv/dt = F clip(u, -1, 1) - rho CdA |v| v / 2
def car_rate(t, x, u, params):
    mass = params.get("mass", 1000.0)
    rho, CdA = params.get("rho", 1.2), params.get("CdA", 0.7)
    force = params.get("fmax", 4000.0) * np.clip(u[0], -1, 1)
    drag = 0.5 * rho * CdA * abs(x[0]) * x[0]
    return (force - drag) / mass


# van der Pol: x1' = x2, x2' = mu (1 - x1^2) x2 - x1 + u
def vanderpol_rate(t, x, u, params):
    mu = params.get("mu", 1.0)
    return np.array([x[1], mu * (1 - x[0] ** 2) * x[1] - x[0] + u[0]])


# predator-prey: python-control's example, the input feeds the hares (clipped)
def predprey_rate(t, x, u, params):
    r = params.get("r", 2.0)
    d = params.get("d", 0.7)
    b = params.get("b", 0.3)
    k = params.get("k", 10.0)
    a = params.get("a", 8.0)
    c = params.get("c", 4.0)
    H, L = x[0], x[1]
    food = np.clip(u[0], -0.5, 0.5)
    dH = (r + food) * H * (1 - H / k) - (a * H * L) / (c + H)
    dL = b * (a * H * L) / (c + H) - d * L
    return np.array([dH, dL])


# thermal:   C dT/dt = P - k (T - ambient)
def thermal_rate(t, x, u, params):
    capacity = params["C"]
    loss = params["k"]
    return [(u[0] - loss * (x[0] - params.get("ambient", 20.0))) / capacity]


# motor:     L di/dt = v - R i - Kt w, J dw/dt = Kt i - b w; y = w
def motor_torque(current, params):
    return params.get("Kt", 0.05) * current


def motor_rate(t, x, u, params):
    R, L, J, b = params["R"], params["L"], params["J"], params["b"]
    current, speed = x
    vmax = params.get("vmax", 12.0)
    voltage = np.clip(u[0], -vmax, vmax)
    return [(voltage - R * current - params.get("Kt", 0.05) * speed) / L,
            (motor_torque(current, params) - b * speed) / J]


def second_state(t, x, u, params):
    return x[1]


# leaky integrator made by a factory (a closure over a number)
def leaky_integrator(leak):
    def rate(t, x, u, params):
        return -leak * x + u
    return rate


# bicycle:   kinematic model at speed v, steering input; y = lateral position
def bicycle_rate(t, x, u, params):
    v = params.get("v", 5.0)
    wheelbase = params.get("wheelbase", 3.0)
    delta = np.clip(u[0], -0.5, 0.5)
    return np.array([v * np.cos(x[2]), v * np.sin(x[2]), v / wheelbase * np.tan(delta)])


def lateral_position(t, x, u, params):
    return x[1]


def euler(rate):
    """The discrete update x + TS f(t, x, u), as notebooks step a model they integrate."""
    def update(t, x, u, params):
        return x + TS * np.asarray(rate(t, x, u, params))
    return update


def _plant(rate, output, states, params):
    def build(rng, dt, name, inputs, outputs):
        values = {key: _draw(rng, *bounds) for key, bounds in params.items()}
        return ct.nlsys(rate if dt == 0 else euler(rate), output, inputs=inputs,
                        outputs=outputs, states=states, dt=dt, name=name, params=values)
    return build


LEAKY = {0.2: leaky_integrator(0.2), 0.5: leaky_integrator(0.5)}


def leaky_plant(rng, dt, name, inputs, outputs):
    rate = LEAKY[0.2 if rng.random() < 0.5 else 0.5]
    return ct.nlsys(rate if dt == 0 else euler(rate), None, inputs=inputs, outputs=outputs,
                    states=1, dt=dt, name=name)


def lambda_plant(rng, dt, name, inputs, outputs):
    if dt == 0:
        rate = lambda t, x, u, params: -params.get("a", 1.0) * x + params.get("b", 1.0) * u  # noqa: E731
    else:
        rate = lambda t, x, u, params: x + TS * (-params["a"] * x + params["b"] * u)  # noqa: E731
    return ct.nlsys(rate, None, inputs=inputs, outputs=outputs, states=1, dt=dt, name=name,
                    params={"a": _draw(rng, 0.5, 3.0), "b": _draw(rng, 0.5, 2.0)})


def _stable_tf(rng, order):
    """A strictly proper, stable continuous transfer function of the given order."""
    if order == 1:
        a = _draw(rng, 0.5, 4.0)
        return ct.tf([_draw(rng, 0.5, 2.0) * a], [1.0, a])
    wn, zeta = _draw(rng, 0.8, 4.0), _draw(rng, 0.3, 1.2)
    return ct.tf([_draw(rng, 0.5, 2.0) * wn ** 2], [1.0, 2 * zeta * wn, wn ** 2])


def tf_plant(rng, dt, name, inputs, outputs):
    plant = _stable_tf(rng, int(rng.integers(1, 3)))
    if dt:
        plant = ct.sample_system(plant, dt, method="zoh" if rng.random() < 0.7 else "tustin")
        if ct.ss(plant).D[0, 0] != 0:  # tustin's feedthrough: not a plant (loops need none)
            plant = ct.sample_system(_stable_tf(rng, 1), dt)
    return ct.tf(plant, inputs=inputs, outputs=outputs, name=name)


def ss_plant(rng, dt, name, inputs, outputs):
    n = int(rng.integers(1, 4))
    A = np.diag([-_draw(rng, 0.5, 3.0) for _ in range(n)])
    A += np.triu(np.round(rng.uniform(-1, 1, (n, n)), 2), 1)
    B = np.round(rng.uniform(0.2, 1.5, (n, 1)), 2)
    C = np.round(rng.uniform(-1, 1.5, (1, n)), 2)
    plant = ct.ss(A, B, C, 0)
    if dt:
        plant = ct.sample_system(plant, dt)
    return ct.ss(plant, inputs=inputs, outputs=outputs, name=name)


PLANTS = {
    "lag": _plant(lag_rate, None, 1, {"tau": (0.3, 2.0), "gain": (0.5, 2.0)}),
    "tank": _plant(tank_rate, None, 1, {"area": (0.5, 2.0), "outflow": (0.2, 1.0)}),
    "pendulum": _plant(pendulum_rate, first_state, 2,
                       {"m": (0.5, 2.0), "l": (0.5, 1.5), "b": (0.3, 1.5), "g": (9.7, 9.9)}),
    "friction": _plant(friction_rate, first_state, 2,
                       {"k": (1.0, 6.0), "c": (0.3, 1.5), "mu": (0.0, 0.4)}),
    "car": _plant(car_rate, None, 1, {"mass": (800, 2000), "CdA": (0.5, 1.0)}),
    "vanderpol": _plant(vanderpol_rate, first_state, 2, {"mu": (0.1, 1.5)}),
    "predprey": _plant(predprey_rate, first_state, 2, {"r": (1.5, 2.5), "d": (0.5, 0.9)}),
    "thermal": _plant(thermal_rate, None, 1,
                      {"C": (1.0, 5.0), "k": (0.2, 1.0), "ambient": (10.0, 25.0)}),
    "motor": _plant(motor_rate, second_state, 2,
                    {"R": (0.5, 2.0), "L": (0.3, 1.0), "J": (0.01, 0.1), "b": (0.05, 0.2)}),
    "leaky (closure)": leaky_plant,
    "lambda plant": lambda_plant,
    "bicycle": _plant(bicycle_rate, lateral_position, 3, {"v": (2.0, 8.0)}),
    "tf plant": tf_plant,
    "ss plant": ss_plant,
}


# --- hazards: code whose Python meaning a compiler can get wrong ---------------------------
# the tank again, with math.sqrt: a level that goes negative raises "math domain error"

def tank_sqrt_rate(t, x, u, params):
    return [(u[0] - params["outflow"] * math.sqrt(x[0])) / params["area"]]


# a gain table scheduled on the state: runs off its end when |x| reaches 2 (IndexError)
GAIN_TABLE = [1.0, 0.8, 0.6, 0.5]


def scheduled_rate(t, x, u, params):
    gain = GAIN_TABLE[int(abs(x[0]) * 2)]
    return [-gain * x[0] + u[0]]


# a logarithmic sensor: math.log of 1 + x, undefined once x <= -1
def log_sensor(t, x, u, params):
    return math.log(1 + x[0]) * params.get("scale", 1.0)


HAZARD_PLANTS = {
    "tank (math.sqrt)": _plant(tank_sqrt_rate, None, 1,
                               {"area": (0.5, 2.0), "outflow": (0.2, 3.0)}),
    "gain table on the state": _plant(scheduled_rate, None, 1, {}),
    "log sensor": _plant(lag_rate, log_sensor, 1, {"tau": (0.3, 2.0), "gain": (-2.0, 2.0)}),
}


# --- controllers and filters: input e (or v), output u ------------------------------------
# P:  u = clip(kp e, -umax, umax)  (static)

def p_control(t, x, u, params):
    kp = params.get("kp", 1.0)
    umax = params.get("umax", 1.0)
    return np.clip(kp * u[0], -umax, umax)


# PI with anti-windup: state z, command kp e + ki z saturated at umax
def pi_command(x, u, params):
    return params["kp"] * u[0] + params["ki"] * x[0]


def pi_output(t, x, u, params):
    umax = params.get("umax", 2.0)
    return np.clip(pi_command(x, u, params), -umax, umax)


def pi_rate(t, x, u, params):
    command = pi_command(x, u, params)
    windup = params.get("kaw", 1.0) * (pi_output(t, x, u, params) - command)
    return [u[0] + windup]


# PID with a filtered derivative: states z (integral), d (filter), output kp e + ki z + kd d'
def pid_rate(t, x, u, params):
    N = params.get("N", 10.0)
    return np.array([u[0], N * (u[0] - x[1])])


def pid_output(t, x, u, params):
    kp, ki, kd, N = map(params.get, ["kp", "ki", "kd", "N"])
    return kp * u[0] + ki * x[0] + kd * N * (u[0] - x[1])


def _controller(rate, output, states, params):
    def build(rng, dt, name, inputs, outputs):
        values = {key: _draw(rng, *bounds) for key, bounds in params.items()}
        if rate is None:
            return ct.nlsys(None, output, inputs=inputs, outputs=outputs,
                            dt=None if rng.random() < 0.7 else dt, name=name, params=values)
        return ct.nlsys(rate if dt == 0 else euler(rate), output, inputs=inputs,
                        outputs=outputs, states=states, dt=dt, name=name, params=values)
    return build


# dead zone and tanh saturation (static, scalar math)
def dead_zone(t, x, u, params):
    width = params.get("width", 0.1)
    return np.sign(u[0]) * max(abs(u[0]) - width, 0.0)


def soft_limit(t, x, u, params):
    umax = params.get("umax", 1.0)
    return umax * np.tanh(u[0] / umax) * params.get("k", 1.0)


# quantizer, numpy's rounding (what python-control's arrays do)
def quantizer(t, x, u, params):
    q = params.get("q", 0.1)
    return np.round(u[0] / q) * q


# gain scheduled by interpolation in a table
BREAKS = np.array([-2.0, -0.5, 0.0, 0.5, 2.0])
GAINS = np.array([0.4, 1.0, 1.5, 1.0, 0.4])


def scheduled_gain(t, x, u, params):
    return np.interp(u[0], BREAKS, GAINS) * u[0] * params.get("k", 1.0)


# bang-bang with a band (branches)
def bang_bang(t, x, u, params):
    band = params["band"]
    if u[0] > band:
        return params["level"]
    elif u[0] < -band:
        return -params["level"]
    return u[0] * params["level"] / band


# polynomial by Horner, coefficients from params (a loop over a list)
def polynomial(t, x, u, params):
    value = 0.0
    for c in params.get("coeffs", [0.0, 1.0]):
        value = value * u[0] + c
    return value


def polynomial_block(rng, dt, name, inputs, outputs):
    coeffs = [_draw(rng, -0.1, 0.1), _draw(rng, -0.2, 0.2), _draw(rng, 0.5, 2.0), 0.0]
    return ct.nlsys(None, polynomial, inputs=inputs, outputs=outputs, dt=None, name=name,
                    params={"coeffs": coeffs})


# gear table indexed by a clipped integer (always inside the table)
RATIOS = [3.0, 2.0, 1.4, 1.0]


def geared(t, x, u, params):
    gear = int(np.clip(abs(u[0]) / params.get("shift", 1.0), 0, len(RATIOS) - 1))
    return RATIOS[gear] * u[0] * params.get("k", 0.3)


# math module: an arctangent limiter
def atan_limit(t, x, u, params):
    umax = params.get("umax", 1.0)
    return 2 * umax / math.pi * math.atan(params.get("k", 1.0) * u[0] / umax)


# min/max builtins
def clamp(t, x, u, params):
    low, high = params.get("low", -1.0), params.get("high", 1.0)
    return min(max(params.get("k", 1.0) * u[0], low), high)


# a saturation made into a block by functools.partial
def saturate(t, x, u, params, limit=1.0):
    return np.clip(u[0] * params.get("k", 1.0), -limit, limit)


PARTIALS = {1.0: functools.partial(saturate, limit=1.0),
            2.0: functools.partial(saturate, limit=2.0)}


def partial_block(rng, dt, name, inputs, outputs):
    return ct.nlsys(None, PARTIALS[1.0 if rng.random() < 0.5 else 2.0], inputs=inputs,
                    outputs=outputs, dt=None, name=name, params={"k": _draw(rng, 0.5, 3.0)})


# a proportional controller with a band, as a callable object
class Banded:
    """u = kp sign(e) min(|e|, band) + bias."""

    def __init__(self, kp, band):
        self.kp, self.band = kp, band

    def __call__(self, t, x, u, params):
        error = u[0]
        return self.kp * np.sign(error) * min(abs(error), self.band) + params.get("bias", 0.0)


BANDED = {1: Banded(kp=1.5, band=1.0), 2: Banded(kp=3.0, band=0.5)}


def object_block(rng, dt, name, inputs, outputs):
    return ct.nlsys(None, BANDED[1 if rng.random() < 0.5 else 2], inputs=inputs,
                    outputs=outputs, dt=None, name=name, params={"bias": _draw(rng, -0.1, 0.1)})


# a first-order low pass as an object's bound methods
class LowPass:
    """x' = (u - x) / tau (continuous) or x+ = a x + (1 - a) u (discrete); y = x."""

    def __init__(self, tau):
        self.tau = tau
        self.a = math.exp(-TS / tau)

    def rate(self, t, x, u, params):
        return (u - x) / self.tau

    def update(self, t, x, u, params):
        return self.a * x + (1 - self.a) * u

    def output(self, t, x, u, params):
        return x


LOW_PASSES = {0.2: LowPass(0.2), 0.5: LowPass(0.5)}


def method_block(rng, dt, name, inputs, outputs):
    low_pass = LOW_PASSES[0.2 if rng.random() < 0.5 else 0.5]
    return ct.nlsys(low_pass.rate if dt == 0 else low_pass.update, low_pass.output,
                    inputs=inputs, outputs=outputs, states=1, dt=dt, name=name)


# a decorator that limits what the function it wraps returns
def limited(limit):
    def decorate(fn):
        @functools.wraps(fn)
        def wrapper(t, x, u, params):
            value = fn(t, x, u, params)
            return math.copysign(min(abs(value), limit), value)
        return wrapper
    return decorate


@limited(1.5)
def cubic_gain(t, x, u, params):
    return params["k"] * u[0] + params["k3"] * u[0] ** 3


# a gain made by a factory (closure over a number)
def make_gain(k):
    def gain(t, x, u, params):
        return k * u[0]
    return gain


GAIN_CLOSURES = {0.5: make_gain(0.5), 2.0: make_gain(2.0)}


def closure_block(rng, dt, name, inputs, outputs):
    return ct.nlsys(None, GAIN_CLOSURES[0.5 if rng.random() < 0.5 else 2.0], inputs=inputs,
                    outputs=outputs, dt=None, name=name)


def lambda_filter(rng, dt, name, inputs, outputs):
    if dt == 0:
        rate = lambda t, x, u, params: (u - x) / params["tau"]  # noqa: E731
    else:
        rate = lambda t, x, u, params: x + TS / params["tau"] * (u - x)  # noqa: E731
    return ct.nlsys(rate, lambda t, x, u, params: x, inputs=inputs, outputs=outputs,
                    states=1, dt=dt, name=name, params={"tau": _draw(rng, 0.1, 1.0)})


# discrete only: relay with hysteresis, rate limiter, two-tap moving average
def relay_update(t, x, u, params):
    band = params.get("band", 0.1)
    if u[0] > band:
        return [1.0]
    if u[0] < -band:
        return [-1.0]
    return x


def relay_output(t, x, u, params):
    return params.get("level", 1.0) * x[0]


def rate_limit_update(t, x, u, params):
    step = params["rate"] * TS
    return x + np.clip(u - x, -step, step)


def moving_average_update(t, x, u, params):
    return np.array([u[0], x[0]])


def moving_average_output(t, x, u, params):
    return (u[0] + x[0] + x[1]) / 3


def _discrete_only(update, output, states, params, continuous):
    """A discrete block; in continuous time the ``continuous`` template instead."""
    def build(rng, dt, name, inputs, outputs):
        if dt == 0:
            return continuous(rng, dt, name, inputs, outputs)
        values = {key: _draw(rng, *bounds) for key, bounds in params.items()}
        return ct.nlsys(update, output, inputs=inputs, outputs=outputs, states=states,
                        dt=dt, name=name, params=values)
    return build


def lead_lag(rng, dt, name, inputs, outputs):
    zero, pole = _draw(rng, 0.3, 2.0), _draw(rng, 2.0, 10.0)
    compensator = ct.tf([_draw(rng, 0.5, 3.0), zero * 1.0], [1.0, pole])
    if dt:
        compensator = ct.sample_system(compensator, dt, method="tustin")
    return ct.tf(compensator, inputs=inputs, outputs=outputs, name=name)


def pi_tf(rng, dt, name, inputs, outputs):
    kp, ki = _draw(rng, 0.3, 2.0), _draw(rng, 0.1, 1.0)
    pi = ct.tf([kp, ki], [1.0, 0.0])
    if dt:
        pi = ct.sample_system(pi, dt, method="tustin" if rng.random() < 0.5 else "zoh")
    return ct.tf(pi, inputs=inputs, outputs=outputs, name=name)


def static_gain(rng, dt, name, inputs, outputs):
    return ct.ss([], [], [], [[_draw(rng, 0.3, 3.0)]], inputs=inputs, outputs=outputs,
                 name=name, dt=None)


CONTROLLERS = {
    "P saturated": _controller(None, p_control, 0, {"kp": (0.5, 5.0), "umax": (0.5, 3.0)}),
    "PI anti-windup": _controller(pi_rate, pi_output, 1,
                                  {"kp": (0.5, 3.0), "ki": (0.2, 2.0), "umax": (0.5, 3.0)}),
    "PID filtered": _controller(pid_rate, pid_output, 2, {"kp": (0.5, 3.0), "ki": (0.1, 1.0),
                                                          "kd": (0.0, 0.3), "N": (5.0, 20.0)}),
    "dead zone": _controller(None, dead_zone, 0, {"width": (0.0, 0.3)}),
    "tanh limit": _controller(None, soft_limit, 0, {"umax": (0.5, 3.0), "k": (0.5, 3.0)}),
    "quantizer": _controller(None, quantizer, 0, {"q": (0.01, 0.2)}),
    "interp schedule": _controller(None, scheduled_gain, 0, {"k": (0.5, 3.0)}),
    "bang-bang band": _controller(None, bang_bang, 0, {"band": (0.05, 0.5),
                                                       "level": (0.5, 2.0)}),
    "polynomial": polynomial_block,
    "gear table": _controller(None, geared, 0, {"shift": (0.2, 1.0), "k": (0.2, 1.0)}),
    "atan limit": _controller(None, atan_limit, 0, {"umax": (0.5, 3.0), "k": (0.5, 3.0)}),
    "min/max clamp": _controller(None, clamp, 0, {"low": (-2.0, -0.5), "high": (0.5, 2.0),
                                                  "k": (0.5, 3.0)}),
    "partial": partial_block,
    "callable object": object_block,
    "bound methods": method_block,
    "decorated": _controller(None, cubic_gain, 0, {"k": (0.5, 2.0), "k3": (-0.2, 0.2)}),
    "closure gain": closure_block,
    "lambda filter": lambda_filter,
    "relay hysteresis": _discrete_only(relay_update, relay_output, 1,
                                       {"band": (0.01, 0.2), "level": (0.3, 1.5)},
                                       _controller(None, bang_bang, 0, {"band": (0.05, 0.5),
                                                                        "level": (0.5, 2.0)})),
    "rate limiter": _discrete_only(rate_limit_update, None, 1, {"rate": (0.5, 5.0)},
                                   lambda_filter),
    "moving average": _discrete_only(moving_average_update, moving_average_output, 2, {},
                                     method_block),
    "lead-lag tf": lead_lag,
    "PI tf": pi_tf,
    "ss gain": static_gain,
}


# --- hazards among the controllers --------------------------------------------------------
# round() of a Python float (Python rounds the decimal it is closest to: 0.35 -> 0.3)

def rounded(t, x, u, params):
    return round(float(u[0]) * params.get("k", 1.0), 1)


# a print while the run goes (a student's debugging line)
def chatty(t, x, u, params):
    if params.get("verbose", False) and abs(u[0]) > params.get("threshold", 1.0):
        print(f"large input {u[0]:.3f}")
    return u[0] * params.get("k", 1.0)


def chatty_block(rng, dt, name, inputs, outputs):
    return ct.nlsys(None, chatty, inputs=inputs, outputs=outputs, dt=None, name=name,
                    params={"verbose": True, "threshold": _draw(rng, 0.3, 1.0),
                            "k": _draw(rng, 0.5, 2.0)})


# a ratio of Python floats (raises ZeroDivisionError where python-control's arrays give inf)
def inverse(t, x, u, params):
    return params.get("k", 0.1) / float(u[0] - params.get("offset", 0.0))


def inverse_block(rng, dt, name, inputs, outputs):
    return ct.nlsys(None, inverse, inputs=inputs, outputs=outputs, dt=None, name=name,
                    params={"k": _draw(rng, 0.05, 0.2), "offset": 0.0})


HAZARD_CONTROLLERS = {
    "round of a float": _controller(None, rounded, 0, {"k": (0.5, 2.0)}),
    "print": chatty_block,
    "division of floats": inverse_block,
}


# ============================================================================ the diagrams

@dataclass
class Case:
    """One diagram and one call of ``input_output_response``, drawn from ``seed``."""

    seed: int
    kind: str
    structure: str
    system: object
    arguments: dict
    blocks: list = field(default_factory=list)

    def describe(self) -> str:
        shown = {k: (f"array{np.shape(v)}" if np.ndim(v) > 0 and np.size(v) > 6 else v)
                 for k, v in self.arguments.items()}
        return (f"seed {self.seed}: {self.kind} {self.structure} of "
                f"{', '.join(self.blocks)}; call {shown}")


#: Templates whose output jumps (a step, a quantum, a pole): in a loop integrated in
#: continuous time they make the solver chatter along the jump, with steps so small that
#: python-control takes minutes. They go in discrete loops, chains and parallel branches.
DISCONTINUOUS = {"quantizer", "gear table", "round of a float", "division of floats",
                 "gain table on the state"}


def _pick(rng, table, hazards, hazard_rate, smooth):
    tables = [hazards, table] if hazards and rng.random() < hazard_rate else [table]
    names = [n for n in tables[0] if not (smooth and n in DISCONTINUOUS)] or list(table)
    name = names[int(rng.integers(len(names)))]
    return name, (hazards.get(name) or table[name])


def _block_dt(kind, role, rng):
    if kind == "discrete":
        return TS
    if kind == "continuous" or role == "plant":
        return 0
    return TS if rng.random() < 0.7 else 2 * TS


def make_case(seed: int, hazard_rate: float = 0.15) -> Case:
    """The diagram and call drawn from ``seed`` (a hazard block with ``hazard_rate``)."""
    rng = np.random.default_rng(seed)
    kind = KINDS[int(rng.integers(3))]
    structure = ["loop", "loop", "loop", "chain", "parallel", "lone"][int(rng.integers(6))]
    if kind == "mixed" and structure == "lone":
        structure = "loop"
    used = []
    smooth = kind != "discrete" and structure == "loop"  # see DISCONTINUOUS

    def plant(name, inputs, outputs):
        label, build = _pick(rng, PLANTS, HAZARD_PLANTS, hazard_rate, smooth)
        used.append(f"{name}={label}")
        return build(rng, _block_dt(kind, "plant", rng), name, inputs, outputs)

    def controller(name, inputs, outputs):
        label, build = _pick(rng, CONTROLLERS, HAZARD_CONTROLLERS, hazard_rate, smooth)
        used.append(f"{name}={label}")
        return build(rng, _block_dt(kind, "controller", rng), name, inputs, outputs)

    build_interconnect = controlkit.interconnect if kind == "mixed" else ct.interconnect
    if structure == "lone":
        system = plant("plant", "u", "y")
        if rng.random() < 0.3 and isinstance(system, ct.NonlinearIOSystem) \
                and not isinstance(system, ct.StateSpace):
            # sizes left for python-control to find from U and X0 (python-control's test_find_size)
            system = ct.nlsys(system.updfcn, system.outfcn, dt=system.dt, name="plant",
                              params=system.params)
            used[-1] += " (sizes unknown)"
    elif structure == "loop":
        #  r -->[prefilter]--> rf -->(+)--> e -->[controller]--> u -->(+)--> up -->[plant]--+--> y
        #                             ^ -ym                           ^ d                  |
        #                             +------------[sensor]<----------+--------------------+
        blocks = [plant("plant", "up", "y"), controller("controller", "e", "u")]
        reference = "r"
        if rng.random() < 0.3:
            blocks.append(controller("prefilter", "r", "rf"))
            reference = "rf"
        measured = "y"
        if rng.random() < 0.3:
            blocks.append(controller("sensor", "y", "ym"))
            measured = "ym"
        blocks.append(ct.summing_junction([reference, f"-{measured}"], "e", name="error"))
        inputs = ["r"]
        if rng.random() < 0.4:
            blocks.append(ct.summing_junction(["u", "d"], "up", name="disturbance"))
            inputs.append("d")
        else:
            blocks.append(ct.summing_junction(["u"], "up", name="disturbance"))
        outputs = ["y", "u"] if rng.random() < 0.6 else ["y"]
        system = build_interconnect(blocks, inputs=inputs, outputs=outputs, name="loop")
    elif structure == "chain":
        count = int(rng.integers(2, 4))
        signals = ["r"] + [f"s{i}" for i in range(count)]
        blocks = []
        for i in range(count):
            if rng.random() < 0.5:
                blocks.append(plant(f"b{i}", signals[i], signals[i + 1]))
            else:
                blocks.append(controller(f"b{i}", signals[i], signals[i + 1]))
        if not any(getattr(b, "nstates", 0) for b in blocks):
            blocks.append(plant("last", signals[-1], "y_last"))
            signals.append("y_last")
        system = build_interconnect(blocks, inputs="r", outputs=signals[-1], name="chain")
    else:  # parallel branches, mixed by a summing junction or a user's function
        blocks = [plant("upper", "r", "y1"), controller("lower", "r", "v2"),
                  plant("lower_plant", "v2", "y2")]
        if rng.random() < 0.5:
            blocks.append(ct.summing_junction(["y1", "-y2"], "y", name="mix"))
        else:
            weights = [_draw(rng, 0.3, 1.5), _draw(rng, -1.5, -0.3)]
            blocks.append(ct.nlsys(None, lambda t, x, u, params: params["w"] @ u,
                                   inputs=["y1", "y2"], outputs="y", dt=None, name="mix",
                                   params={"w": np.array(weights)}))
        system = build_interconnect(blocks, inputs="r", outputs=["y", "y1"], name="parallel")
    arguments = _call(rng, kind, system, used)
    return Case(seed, kind, structure, system, arguments, used)


def _call(rng, kind, system, used) -> dict:
    """The keyword arguments of one call: time points, inputs, initial state, options."""
    count = int(rng.integers(20, 81))
    if kind == "continuous":
        end = _draw(rng, 2.0, 8.0)
        if rng.random() < 0.2:  # non-uniform time points
            T = np.concatenate([[0.0], np.sort(np.round(rng.uniform(0, end, count - 1), 3))])
            T = np.unique(T)
        else:
            T = np.linspace(0.0, end, count)
    else:
        T = np.arange(count) * TS
    ninputs = system.ninputs if system.ninputs is not None else 1
    shape = rng.integers(4)
    if shape == 0:
        U = _draw(rng, -1.5, 1.5)
    elif shape == 1:
        U = np.where(T >= T[len(T) // 4], _draw(rng, 0.5, 1.5), 0.0)
        U = np.vstack([U] + [0.2 * np.sin(T)] * (ninputs - 1)) if ninputs > 1 else U
    elif shape == 2:
        U = np.vstack([_draw(rng, 0.3, 1.5) * np.sin(_draw(rng, 0.5, 3.0) * T)
                       for _ in range(ninputs)])
        U = U[0] if ninputs == 1 and rng.random() < 0.5 else U
    else:
        U = [_draw(rng, -1.0, 1.0) for _ in range(ninputs)]
    if system.ninputs is None:  # python-control counts the inputs from U: rows, or a list
        U = np.atleast_2d(U) if np.ndim(U) else [U]
    nstates = system.nstates if system.nstates is not None else 1
    if system.nstates is None:  # a lone system of unknown sizes: X0 and U give them
        nstates = 2 if any(n in used[-1] for n in ("pendulum", "friction", "vanderpol",
                                                    "predprey", "motor")) else 1
        if "bicycle" in used[-1]:
            nstates = 3
    draw_x0 = rng.integers(4)
    if draw_x0 == 0 and system.nstates is not None:
        X0 = 0.0
    elif draw_x0 == 1 and nstates > 1 and system.nstates is not None:
        X0 = [_draw(rng, -0.5, 0.5)]  # short: python-control pads it with zeros, and warns
    else:
        X0 = [_draw(rng, -0.5, 0.5) for _ in range(nstates)]
    if any("predprey" in name for name in used) or any("tank" in name for name in used):
        X0 = [round(abs(v) + 0.5, 3) for v in X0] if np.ndim(X0) else X0
    arguments = {"timepts": T, "inputs": U, "initial_state": X0}
    if rng.random() < 0.3:
        arguments["return_states"] = True
    if rng.random() < 0.3:
        arguments["squeeze"] = bool(rng.random() < 0.5)
    if rng.random() < 0.2:
        arguments["transpose"] = True
    if rng.random() < 0.2:
        arguments["params"] = _overrides(rng, system)
    if kind != "discrete":
        if rng.random() < 0.3:
            arguments["solve_ivp_method"] = ["RK23", "DOP853", "RK45"][int(rng.integers(3))]
        if rng.random() < 0.2:
            arguments["solve_ivp_kwargs"] = ({"rtol": 1e-6, "atol": 1e-9}
                                             if rng.random() < 0.5 else {"max_step": 0.2})
        if kind == "continuous" and rng.random() < 0.15:
            arguments["evaluation_times"] = np.linspace(T[0], T[-1], int(rng.integers(5, 30)))
    if rng.random() < 0.15:  # python-control's aliases
        arguments = {{"timepts": "T", "inputs": "U", "initial_state": "X0",
                      "return_states": "return_x"}.get(k, k): v for k, v in arguments.items()}
    return arguments


def _overrides(rng, system) -> dict:
    """New values for one or two of the parameters the blocks declare."""
    declared = {}
    for block in getattr(system, "syslist", [system]):
        for key, value in (getattr(block, "params", None) or {}).items():
            if isinstance(value, float):
                declared[key] = value
    if not declared:
        return {}
    keys = sorted(declared)
    chosen = [keys[int(i)] for i in rng.choice(len(keys), min(2, len(keys)), replace=False)]
    return {key: float(f"{declared[key] * _draw(rng, 0.7, 1.3):.3g}") for key in chosen}


# ============================================================================ running one

@dataclass
class Run:
    """What one engine did with a case: its response or its exception, what it printed and
    which warnings it gave."""

    response: object = None
    error: BaseException | None = None
    printed: str = ""
    warned: list = field(default_factory=list)


@dataclass
class Verdict:
    """How controlkit's answer compares with the reference's (see the module's docstring)."""

    verdict: str
    detail: str = ""
    fell_back: bool = False


def _run(function, case, **extra) -> Run:
    run = Run()
    printed = io.StringIO()
    with warnings.catch_warnings(record=True) as caught, contextlib.redirect_stdout(printed):
        warnings.simplefilter("always")
        try:
            run.response = function(case.system, **case.arguments, **extra)
        except Exception as error:  # noqa: BLE001 - any error is an answer to compare
            run.error = error
    run.printed = printed.getvalue()
    run.warned = [(w.category.__name__, str(w.message)) for w in caught]
    return run


def reference(case) -> Run:
    """python-control's answer (controlkit's Python reference for a mixed diagram)."""
    if case.kind == "mixed":
        return _run(controlkit.input_output_response, case, engine="python-control")
    return _run(ct.input_output_response, case)


def ours(case) -> Run:
    """The drop-in's answer; the engine's as Python (``compile=False``) for a diagram's run
    the drop-in leaves to python-control (too short for preparing a new diagram to pay),
    which the same diagram run again, or for longer, gets."""
    from controlkit.simulation import _starts_engine

    times = case.arguments.get("timepts", case.arguments.get("T"))
    extra = {} if getattr(case.system, "syslist", None) is None or _starts_engine(
        case.system, np.size(times)) else {"compile": False}
    return _run(controlkit.input_output_response, case, **extra)


def _scaled_error(ours_, ref, per_signal=True) -> float:
    """The largest difference relative to each signal's size (at least 1); over time along
    the last axis when ``per_signal``, else relative to the largest value of all."""
    ours_ = np.asarray(ours_, dtype=float)
    ref = np.asarray(ref, dtype=float)
    if ours_.size == 0:
        return 0.0
    same = (ours_ == ref) | (np.isnan(ours_) & np.isnan(ref))
    size = np.abs(np.where(np.isfinite(ref), ref, 0.0))
    if per_signal and ref.ndim:
        scale = np.maximum(1.0, size.max(axis=-1, keepdims=True))
    else:
        scale = max(1.0, float(size.max()))
    with np.errstate(invalid="ignore"):
        error = np.where(same, 0.0, np.abs(ours_ - ref) / scale)
    return float(np.where(np.isnan(error), np.inf, error).max())


def _nonfinite(response) -> bool:
    arrays = [response.outputs, response.states]
    return any(not np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrays)


def _differences(case, ref, got) -> list[str]:
    """What differs between two responses (empty: nothing beyond the tolerance)."""
    tolerance = TOLERANCE[case.kind]
    found = []
    if type(got) is not type(ref):
        return [f"response type {type(got).__name__} vs {type(ref).__name__}"]
    legacy_ref, legacy_got = tuple(ref), tuple(got)  # t, y[, x] as the user unpacks them
    if len(legacy_ref) != len(legacy_got):
        found.append(f"unpacks to {len(legacy_got)} values, python-control {len(legacy_ref)}")
    for name in ("output_labels", "state_labels", "input_labels"):  # (None: sizes unknown)
        ours, theirs = list(getattr(got, name) or []), list(getattr(ref, name) or [])
        if ours != theirs:
            found.append(f"{name} {ours} vs {theirs}")
    pairs = [("time", got.time, ref.time), ("outputs", got.outputs, ref.outputs),
             ("states", got.states, ref.states), ("inputs", got.inputs, ref.inputs)]
    unpacked = zip(legacy_got, legacy_ref, strict=False)  # a length apart is named above
    pairs += [(f"unpacked[{i}]", a, b) for i, (a, b) in enumerate(unpacked)]
    for name, a, b in pairs:
        if np.shape(a) != np.shape(b):
            found.append(f"{name} shape {np.shape(a)} vs {np.shape(b)}")
        elif name == "time":
            if not np.array_equal(np.asarray(a, float), np.asarray(b, float)):
                found.append(f"time points differ by {np.max(np.abs(np.subtract(a, b))):.3g}")
        else:  # unpacked arrays may be transposed (time first): scaled by their largest
            error = _scaled_error(a, b, per_signal=not name.startswith("unpacked"))
            if error > tolerance:
                found.append(f"{name} {error:.3g} apart (tolerance {tolerance:g})")
    return found


def _ours_warnings(run) -> list:
    return [w for w in run.warned if "engine not used" not in w[1]]


def compare(case) -> Verdict:
    """Run ``case`` on both and judge (see :data:`VERDICTS`)."""
    ref, got = reference(case), ours(case)
    fell_back = any("engine not used" in message for _, message in got.warned)
    if ref.error is not None:
        if got.error is None:
            return Verdict("other error", f"python-control raises {_name(ref.error)}, "
                                          f"controlkit answers", fell_back)
        if type(got.error) is not type(ref.error):
            return Verdict("other error", f"python-control raises {_name(ref.error)}, "
                                          f"controlkit {_name(got.error)}", fell_back)
        same = str(got.error) == str(ref.error)
        return Verdict("same error", f"{type(ref.error).__name__}"
                                     + ("" if same else f", message {_name(got.error)} vs "
                                                        f"{_name(ref.error)}"), fell_back)
    if got.error is not None:
        if isinstance(got.error, FloatingPointError) and _nonfinite(ref.response):
            return Verdict("diverged", _name(got.error), fell_back)
        return Verdict("other error", f"controlkit raises {_name(got.error)}, python-control "
                                      f"answers", fell_back)
    found = _differences(case, ref.response, got.response)
    # a mixed diagram's reference is controlkit's own loop, whose calls are its own
    if case.kind != "mixed" and got.printed != ref.printed:
        found.append(f"printed {got.printed.count(chr(10))} lines, python-control "
                     f"{ref.printed.count(chr(10))}")
    ref_warned = sorted(set(m for c, m in ref.warned if c == "UserWarning"))
    got_warned = sorted(set(m for c, m in _ours_warnings(got) if c == "UserWarning"))
    missing = [m for m in ref_warned if m not in got_warned]
    if missing:
        found.append(f"warnings missing: {missing}")
    if found:
        return Verdict("differ", "; ".join(found), fell_back)
    return Verdict("equal", "", fell_back)


def _name(error) -> str:
    text = str(error).splitlines()[0] if str(error) else ""
    return f"{type(error).__name__}({text[:160]!r})"


# ============================================================================ many, apart

class _TooLong(Exception):
    pass


def _alarm(signum, frame):
    raise _TooLong


def _judge_into(first, count, results, hazard_rate=0.15, limit=0) -> None:
    """Judge the seeds and append ``{"seed", "verdict", "detail", "fell_back"}`` lines to
    the file ``results``, one as soon as each seed is judged."""
    signal.signal(signal.SIGALRM, _alarm)
    for seed in range(first, first + count):
        signal.alarm(limit)
        try:
            verdict = compare(make_case(seed, hazard_rate))
        except _TooLong:
            verdict = Verdict("too long", f"over {limit} s")
        finally:
            signal.alarm(0)
        with open(results, "a") as file:
            file.write(json.dumps({"seed": seed, **vars(verdict)}) + "\n")
        if (seed - first + 1) % 50 == 0:
            print(f"... {seed - first + 1} diagrams", file=sys.stderr, flush=True)


def judged_apart(first, count, hazard_rate=0.15, limit=0):
    """``{seed: Verdict}`` for ``count`` seeds from ``first``, judged in a child process.

    A seed whose run kills the child (a crash of compiled code) is ``crashed``, and a new
    child goes on after it. With ``limit`` seconds, a case over it is ``too long``: the
    child's alarm stops Python code; a compiled loop that never returns (the alarm cannot
    stop it) is killed once no verdict has come for twice that, plus half a minute.
    """
    verdicts, seed, end = {}, first, first + count
    env = {**os.environ, "CONTROLKIT_MODULES": os.environ.get("CONTROLKIT_MODULES", "never")}
    with tempfile.TemporaryDirectory() as folder:
        results, errors = Path(folder) / "verdicts.jsonl", Path(folder) / "stderr.txt"
        while seed < end:
            with open(errors, "w") as stderr:
                child = subprocess.Popen([sys.executable, __file__, str(seed), str(end - seed),
                                          str(results), str(hazard_rate), str(limit)],
                                         env=env, stdout=subprocess.DEVNULL, stderr=stderr)
                hung = _wait_for_the_child(child, results, 2 * limit + 30 if limit else 0)
            for line in results.read_text().splitlines() if results.exists() else []:
                row = json.loads(line)
                judged = row.pop("seed")
                verdicts[judged] = Verdict(**row)
            seed = max(verdicts, default=first - 1) + 1
            if seed < end:  # the child died, or was stopped, while it judged this seed
                if hung:
                    verdicts[seed] = Verdict("too long", f"no answer in {2 * limit + 30} s "
                                                         f"(stopped: a loop that never ends)")
                else:
                    how = (f"killed by {signal.Signals(-child.returncode).name}"
                           if child.returncode < 0 else f"exit status {child.returncode}")
                    tail = " ".join(errors.read_text().strip().splitlines()[-1:])[:300]
                    verdicts[seed] = Verdict("crashed", f"the process was {how} ({tail})")
                seed += 1
    return verdicts


def _wait_for_the_child(child, results, patience) -> bool:
    """Wait for ``child`` to end; with ``patience`` seconds, kill it once no verdict has
    come for that long, and say so (True)."""
    import time

    seen, since = -1, time.monotonic()
    while child.poll() is None:
        judged = results.stat().st_size if results.exists() else 0
        if judged != seen:
            seen, since = judged, time.monotonic()
        elif patience and time.monotonic() - since > patience:
            child.kill()
            child.wait()
            return True
        time.sleep(0.05)
    return False


if __name__ == "__main__":
    first_, count_, results_ = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
    options = [float(sys.argv[4])] if len(sys.argv) > 4 else []
    options += [int(sys.argv[5])] if len(sys.argv) > 5 else []
    _judge_into(first_, count_, results_, *options)
