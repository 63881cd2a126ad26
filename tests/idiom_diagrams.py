"""Diagrams whose functions are written the way python-control's examples and course
notebooks write them, awkward parts included: ``params`` handed to helpers, read through
``map(params.get, ...)``, an alias, literal key loops and a key in a variable; scalar
``np.clip``, ``min``/``max``, ``np.sign`` and ``math``; imports and lambdas inside a
function; closures over numbers, arrays, python-control systems and their ``params``; a
``functools.partial``, a callable object, bound methods and a decorated function.

The models are our own (a car, a servo arm, hares and lynx, a bicycle, an adaptive loop,
a state estimator, a heater), discrete or sampled so that the fast engine compiles them.
Shared by tests/test_user_functions.py and benchmarks/bench_user_diagrams.py; each
builder returns ``(loop, T, X0, U, params)`` and the names of the functions it covers.
"""

import functools
import math

import control as ct
import numpy as np

from controlkit.blocks.sampling import sample_nlsys

TS = 0.05


# --- a car under a PI speed controller with anti-windup ---------------------------------
#
# car:  state v (m/s); inputs throttle (0..1), gear (1..5), slope (rad); output v
#       parameters mass, ratios, c_roll, rho, CdA (engine: torque_max, omega_peak, rolloff)
# pi:   state z (integrated error); inputs v, v_ref; output throttle; parameters kp, ki, kaw

def engine_torque(omega, params={}):  # noqa: B006 - python-control's examples do this
    # peak torque at omega_peak, falling off on both sides, never negative
    torque_max = params.get("torque_max", 200.0)
    omega_peak = params.get("omega_peak", 420.0)
    rolloff = params.get("rolloff", 0.4)
    return np.clip(torque_max * (1 - rolloff * (omega / omega_peak - 1) ** 2), 0, None)


def car_dynamics(t, x, u, params={}):  # noqa: B006
    from math import copysign, sin

    sign = lambda v: copysign(1, v)  # noqa: E731

    mass = params.get("mass", 1500.0)
    ratios = params.get("ratios", [40, 25, 16, 12, 10])  # gear ratio over wheel radius
    speed = x[0]
    throttle = np.clip(u[0], 0, 1)
    gear = u[1]
    slope = u[2]

    omega = ratios[int(gear) - 1] * speed
    force = ratios[int(gear) - 1] * engine_torque(omega, params) * throttle
    rolling = mass * 9.81 * params.get("c_roll", 0.01) * sign(speed)
    drag = 0.5 * params.get("rho", 1.2) * params.get("CdA", 0.75) * abs(speed) * speed
    return (force - rolling - drag - mass * 9.81 * sin(slope)) / mass


def pi_output(t, x, u, params):
    kp = params.get("kp", 0.5)
    ki = params.get("ki", 0.1)
    return kp * (u[1] - u[0]) + ki * x[0]


def pi_update(t, x, u, params):
    ki = params.get("ki", 0.1)
    kaw = params.get("kaw", 2.0)
    command = pi_output(t, x, u, params)  # the other function, handed params
    windup = kaw / ki * (np.clip(command, 0, 1) - command) if ki != 0 else 0
    return x[0] + TS * ((u[1] - u[0]) + windup)


def cruise(steps=200):
    #                       gear, slope
    #                           v
    # v_ref -->[ pi ]-- throttle -->[ car ]--+--> v
    #            ^ v                         |
    #            +---------------------------+
    car = sample_nlsys(ct.nlsys(car_dynamics, None, inputs=["throttle", "gear", "slope"],
                                outputs="v", states="v", name="car"), TS, substeps=2)
    pi = ct.nlsys(pi_update, pi_output, inputs=["v", "v_ref"], outputs="throttle",
                  states="z", dt=TS, params={"kp": 0.5, "ki": 0.1}, name="pi")
    loop = ct.interconnect([car, pi], inputs=["v_ref", "gear", "slope"],
                           outputs=["v", "throttle"], name="cruise")
    T = np.arange(steps) * TS
    slope = np.deg2rad(np.clip(4.0 * (T - 2.0), 0.0, 5.0))  # a hill from t = 2 s
    U = np.vstack([20.0 * np.ones_like(T), 4.0 * np.ones_like(T), slope])
    return loop, T, [19.0, 2.0], U, {"kaw": 1.5, "mass": 1800}


# --- a servo arm behind a lagging actuator, PID with anti-windup ---------------------------
#
# arm:      states theta, omega; input tau; output y = l theta; parameters J, b, k, r, l
# actuator: state tau; input u; output tau; parameters umax, alpha
# pid:      states z (integral), xi (filtered derivative); inputs r, y; output u

ARM = {"J": 100, "b": 10, "k": 1, "r": 1, "l": 2}  # integers, as notebooks write them


def arm_dynamics(t, x, u, params):
    J, b, k, r = map(params.get, ["J", "b", "k", "r"])
    theta, omega = x
    return np.array([omega, (u[0] - b * omega - k * r * np.sin(theta)) / J])


def arm_position(t, x, u, params):
    return params["l"] * x[0]


def motor_lag(t, x, u, params):
    p = params  # an alias
    torque = np.clip(u, -p["umax"], p["umax"])
    return -p["alpha"] * x + p["alpha"] * torque


def servo(steps=200):
    #  r -->[ pid ]-- u -->[ actuator ]-- tau -->[ arm ]--+--> y
    #         ^ y                                          |
    #         +--------------------------------------------+
    arm = sample_nlsys(ct.nlsys(arm_dynamics, arm_position, inputs="tau", outputs="y",
                                states=["theta", "omega"], params=ARM, name="arm"), TS)
    actuator = ct.nlsys(motor_lag, None, inputs="u", outputs="tau", states="tau",
                        params={"umax": 5, "alpha": 10}, name="actuator")
    kp, ki, kd = 150.0, 40.0, 30.0  # the notebook's gains live in its namespace

    def pid_terms(x, u, params):
        a = params["a"]
        error = u[0] - u[1]
        derivative = kd * (-a * x[1] - a * u[1])
        return error, kp * error + x[0] + derivative

    def pid_update(t, x, u, params):
        limit = params.get("umax_ctrl", actuator.params["umax"])  # read from another block
        error, command = pid_terms(x, u, params)
        saturated = np.clip(command, -limit, limit)
        kaw, a = [params[name] for name in ("kaw", "a")]
        return [x[0] + TS * (ki * error + kaw * (saturated - command)),
                x[1] + TS * (-a * x[1] - a * u[1])]

    def pid_output(t, x, u, params):
        return pid_terms(x, u, params)[1]

    pid = ct.nlsys(pid_update, pid_output, inputs=["r", "y"], outputs="u",
                   states=["z", "xi"], dt=TS, params={"kaw": 2.0, "a": 10.0}, name="pid")
    loop = ct.interconnect([sample_nlsys(actuator, TS), arm, pid], inputs="r",
                           outputs=["y", "tau", "u"], name="servo")
    T = np.arange(steps) * TS
    return loop, T, np.zeros(loop.nstates), 0.5 * (T > 0.2), {"kaw": 3.0}


# --- hares and lynx, stabilised by state feedback with integral action -------------------
#
# ecosystem:  states H, L; input u (extra food); outputs H, L
#             parameters growth, death, efficiency, capacity, attack, saturation
# controller: state z; inputs H, L, r; output u = -K (x - xe) - ki z

ECOSYSTEM = {"growth": 1.6, "death": 0.56, "efficiency": 0.6, "capacity": 125.0,
             "attack": 3.2, "saturation": 50.0}


def hares_and_lynx(t, x, u, params):
    coefficients = []
    for name in ("growth", "death", "efficiency", "capacity", "attack", "saturation"):
        coefficients.append(params[name])
    growth, death, efficiency, capacity, attack, saturation = coefficients
    food = np.clip(u, -growth, growth)
    eaten = attack * x[1] * x[0] / (saturation + x[0])
    return np.array([(growth + food[0]) * x[0] * (1 - x[0] / capacity) - eaten,
                     efficiency * eaten - death * x[1]])


def ecosystem(steps=200):
    Ts = 0.25
    continuous = ct.nlsys(hares_and_lynx, None, inputs="u", outputs=["H", "L"],
                          states=["H", "L"], params=ECOSYSTEM, name="ecosystem")
    xe, _ = ct.find_operating_point(continuous, [20.0, 30.0], 0.0)
    linear = continuous.linearize(xe, 0.0)
    K = ct.place(linear.A, linear.B, [-0.4, -0.5])
    ki = 0.0005
    controller = ct.nlsys(
        lambda t, x, u, params: x + Ts * (u[1] - u[2]),
        lambda t, x, u, params: -K @ (u[0:2] - xe) - ki * x[0],
        inputs=["H", "L", "r"], outputs="u", states="z", dt=Ts, name="controller")
    loop = ct.interconnect([sample_nlsys(continuous, Ts, substeps=2), controller],
                           inputs="r", outputs=["H", "L", "u"], name="ecosystem_loop")
    T = np.arange(steps) * Ts
    return loop, T, [xe[0] + 5.0, xe[1] - 3.0, 0.0], xe[1] * np.ones_like(T), {"growth": 1.65}


# --- a bicycle following a lane change with gain-scheduled steering ------------------------
#
# bicycle:    states x, y, theta; inputs v, delta; outputs x, y, theta
# controller: inputs ex, ey, etheta, v_ref, delta_ref; outputs v, delta
#             parameters pole_v, pole_1, pole_2 (complex), wheelbase
# reference:  inputs v_ref, y_ref; outputs x_ref, y_ref, theta_ref, v_ref, delta_ref

def bicycle(t, x, u, params):
    wheelbase = params.get("wheelbase", 3.0)
    max_steer = params.get("max_steer", 0.5)
    delta = np.clip(u[1], -max_steer, max_steer)
    return np.array([np.cos(x[2]) * u[0], np.sin(x[2]) * u[0],
                     u[0] / wheelbase * np.tan(delta)])


def bicycle_output(t, x, u, params):
    return x


def steering_law(t, x, u, params):
    pole_v = params.get("pole_v", -2.0)
    pole_1 = params.get("pole_1", -0.5 + 1.3j)
    pole_2 = params.get("pole_2", -0.5 - 1.3j)
    wheelbase = params.get("wheelbase", 3)
    ex, ey, etheta, v_ref, delta_ref = u

    # gains from the poles: alpha1 = -(p1 + p2), alpha2 = p1 p2 (both real)
    alpha1 = -np.real(pole_1 + pole_2)
    alpha2 = np.real(pole_1 * pole_2)
    v = v_ref - pole_v * ex
    if v_ref != 0:
        delta = delta_ref + (alpha2 * wheelbase) / v_ref ** 2 * ey \
            + (alpha1 * wheelbase) / v_ref * etheta
    else:
        delta = delta_ref  # standing still: keep the wheel straight
    return np.array([v, delta])


def lane_reference(t, x, u, params):
    v_ref, y_ref = u
    return np.array([v_ref * t, y_ref, 0, v_ref, 0])


def steering_loop(dt, *, merged_params=False):
    """The bicycle, its controller and its lane reference wired: continuous (``dt`` 0) or
    with the bicycle sampled at :data:`TS` and the static blocks on any timebase (``dt``
    None); with ``merged_params`` the loop's ``params`` are its blocks'."""
    vehicle = ct.nlsys(bicycle, bicycle_output, states=3, inputs=["v", "delta"],
                       outputs=["x", "y", "theta"], params={"wheelbase": 3.0, "max_steer": 0.5},
                       name="bicycle")
    if dt is None:
        vehicle = sample_nlsys(vehicle, TS)
    controller = ct.nlsys(None, steering_law, inputs=["ex", "ey", "etheta", "vd", "deltad"],
                          outputs=["v", "delta"], dt=dt, name="controller",
                          params={"pole_v": -2.0, "pole_1": -0.6 + 1.0j,
                                  "pole_2": -0.6 - 1.0j, "wheelbase": 3})
    reference = ct.nlsys(None, lane_reference, inputs=["v_ref", "y_ref"],
                         outputs=["xd", "yd", "thetad", "vd", "deltad"], dt=dt,
                         name="reference")
    return ct.interconnect(
        [reference, controller, vehicle],
        connections=[["controller.ex", "reference.xd", "-bicycle.x"],
                     ["controller.ey", "reference.yd", "-bicycle.y"],
                     ["controller.etheta", "reference.thetad", "-bicycle.theta"],
                     ["controller.vd", "reference.vd"],
                     ["controller.deltad", "reference.deltad"],
                     ["bicycle.v", "controller.v"], ["bicycle.delta", "controller.delta"]],
        inplist=["reference.v_ref", "reference.y_ref"], inputs=["v_ref", "y_ref"],
        outlist=["bicycle.x", "bicycle.y", "bicycle.theta", "controller.delta"],
        outputs=["x", "y", "theta", "delta"], name="steering",
        **({"params": reference.params | vehicle.params | controller.params}
           if merged_params else {}))


def steering(steps=200):
    #  [v_ref, y_ref] --> reference --> (-) --> controller --> bicycle --+--> x, y, theta
    #                                    ^                                |
    #                                    +--------------------------------+
    loop = steering_loop(None, merged_params=True)
    T = np.arange(steps) * TS
    U = np.vstack([8.0 * np.ones_like(T), np.ones_like(T)])
    return loop, T, [0.0, -1.0, 0.0], U, {"pole_1": -0.8 + 0.8j, "pole_2": -0.8 - 0.8j}


# --- model-reference adaptive control by the MIT rule ------------------------------------
#
# controller: states x1 (filtered r), kr, x3 (filtered y), ky; inputs r, ym, y; output u
#             parameters gamma, a_m, sign_b

def mit_rule(t, x, u, params):
    gamma = params["gamma"]
    a_m = params["a_m"]
    sign_b = params["sign_b"]

    r, y_model, y = u[0], u[1], u[2]
    error = y_model - y
    return [x[0] + TS * (a_m * x[0] + a_m * r),
            x[1] - TS * gamma * x[0] * error * sign_b,
            x[2] + TS * (a_m * x[2] + a_m * y),
            x[3] - TS * gamma * x[2] * error * sign_b]


def adaptive_control(t, x, u, params):
    return [x[3] * u[2] + x[1] * u[0]]


def mrac(steps=200):
    b = 0.5
    plant = ct.sample_system(ct.ss(-1.0, b, 1.0, 0.0), TS, inputs="u", outputs="y",
                             states="y", name="plant")
    model = ct.sample_system(ct.ss(-2.0, 2.0, 1.0, 0.0), TS, inputs="r", outputs="ym",
                             states="ym", name="model")
    controller = ct.nlsys(mit_rule, adaptive_control, inputs=["r", "ym", "y"], outputs="u",
                          states=4, dt=TS, name="controller",
                          params={"gamma": 1, "a_m": -2.0, "sign_b": np.sign(b)})
    loop = ct.interconnect([plant, model, controller], inputs="r", outputs=["y", "ym", "u"],
                           name="mrac")
    T = np.arange(steps) * TS
    return loop, T, np.zeros(loop.nstates), np.sign(np.sin(0.6 * T) + 1e-9), {"gamma": 2}


# --- a state estimator beside the plant it watches ---------------------------------------
#
# car:       states x, y, theta; inputs v, delta; the kinematic bicycle again
# estimator: states xh, yh, thetah; inputs y (x and y measured), v, delta; parameter L
# observer:  a Luenberger observer of a sampled mass-spring-damper held in a closure

CAR = {"wheelbase": 3.0, "max_steer": 0.5}


def unicycle(t, x, u, params):
    wheelbase = params["wheelbase"]
    max_steer = params["max_steer"]
    delta = np.clip(u[1], -max_steer, max_steer)
    return np.array([np.cos(x[2]) * u[0], np.sin(x[2]) * u[0],
                     u[0] / wheelbase * np.tan(delta)])


def estimation(steps=200):
    car = ct.nlsys(unicycle, None, inputs=["v", "delta"], outputs=["x", "y", "theta"],
                   states=["x", "y", "theta"], params=CAR, name="car")
    C = np.eye(2, 3)
    linear = car.linearize([0.0, 0.0, 0.0], [10.0, 0.0])
    L = ct.place(linear.A.T, C.T, [-1.0, -2.0, -3.0]).T

    def estimator_update(t, xhat, u, params):
        y = u[0:2]
        inputs = u[2:4]
        # the car's own equations (its updfcn, with its params dict), corrected by L
        rate = car.updfcn(t, xhat, inputs, CAR) - params["L"] @ (C @ xhat - y)
        return xhat + TS * rate

    estimator = ct.nlsys(estimator_update, lambda t, x, u, params: x,
                         inputs=["ym[0]", "ym[1]", "v", "delta"],
                         outputs=["xh", "yh", "thetah"], states=3, dt=TS,
                         params={"L": L}, name="estimator")
    msd = ct.sample_system(ct.ss([[0.0, 1.0], [-4.0, -0.4]], [[0.0], [1.0]], [[1.0, 0.0]],
                                 0.0), TS)
    gain = ct.place(msd.A.T, msd.C.T, [0.5, 0.6]).T

    def observer_update(t, x, u, params):
        correction = params.get("L_msd", gain) @ (u[1:2] - msd.C @ x)
        return msd.A @ x + msd.B @ u[0:1] + correction

    spring = ct.ss(msd.A, msd.B, msd.C, msd.D, dt=TS, inputs="f", outputs="p",
                   name="spring")
    observer = ct.nlsys(observer_update, lambda t, x, u, params: x[0], inputs=["f", "p"],
                        outputs="ph", states=2, dt=TS, name="observer")
    loop = ct.interconnect(
        [sample_nlsys(car, TS), estimator, spring, observer],
        connections=[["estimator.ym[0]", "car.x"], ["estimator.ym[1]", "car.y"],
                     ["observer.p", "spring.p"]],
        inplist=[["car.v", "estimator.v"], ["car.delta", "estimator.delta"],
                 ["spring.f", "observer.f"]],
        inputs=["v", "delta", "f"],
        outlist=["car.x", "car.y", "car.theta", "estimator.xh", "estimator.yh",
                 "estimator.thetah", "spring.p", "observer.ph"],
        outputs=["x", "y", "theta", "xh", "yh", "thetah", "p", "ph"], name="estimation")
    T = np.arange(steps) * TS
    U = np.vstack([10.0 * np.ones_like(T), 0.1 * np.sin(0.5 * T), np.cos(T)])
    X0 = [0.0, 0.5, 0.05, 0.0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0]
    return loop, T, X0, U, None


# --- a heater: a partial, a callable object, bound methods, a decorated function ----------
#
# heater:     state temperature; input power; parameters capacity, ambient; loss bound
# thermostat: inputs setpoint, temperature; output power (a callable object)
# filter:     a first-order filter of the power (bound methods of an object)
# feedforward: input setpoint; output power, rate-limited by a decorator

def room(t, x, u, params, loss=0.1):
    capacity = params.get("capacity", 2.0)
    return x + TS * (u[0] - loss * (x[0] - params.get("ambient", 20.0))) / capacity


class Thermostat:
    """A proportional controller with a band, as an object with ``__call__``."""

    def __init__(self, kp, band):
        self.kp, self.band = kp, band

    def offset(self, params, name):
        return params.get(name, 0.0)

    def __call__(self, t, x, u, params):
        error = u[0] - u[1]
        return self.kp * np.sign(error) * min(abs(error), self.band) \
            + self.offset(params, "bias")


class LowPass:
    def __init__(self, tau):
        self.a = math.exp(-TS / tau)

    def update(self, t, x, u, params):
        return self.a * x + (1 - self.a) * u

    def output(self, t, x, u, params):
        return x


def limited(limit):
    def decorate(fn):
        @functools.wraps(fn)
        def wrapper(t, x, u, params):
            value = fn(t, x, u, params)
            return math.copysign(min(abs(value), limit), value)
        return wrapper
    return decorate


@limited(3.0)
def feedforward(t, x, u, params):
    return params["kff"] * math.tanh(u[0] / 10.0)


def heating(steps=200):
    #  setpoint --+--> thermostat --+--> (+) --> filter --> room --+--> temperature
    #             +--> feedforward -+                              |
    #                   ^ temperature -----------------------------+
    plant = ct.nlsys(functools.partial(room, loss=0.3), None, inputs="power",
                     outputs="temperature", states=1, dt=TS, name="room",
                     params={"capacity": 1.5})
    thermostat = ct.nlsys(None, Thermostat(kp=4.0, band=2.0),
                          inputs=["setpoint", "temperature"], outputs="p_fb", dt=None,
                          name="thermostat")
    lowpass = LowPass(tau=0.3)
    smoother = ct.nlsys(lowpass.update, lowpass.output, inputs="p_cmd", outputs="power",
                        states=1, dt=TS, name="filter")
    ahead = ct.nlsys(None, feedforward, inputs="setpoint", outputs="p_ff", dt=None,
                     name="feedforward", params={"kff": 5.0})
    total = ct.summing_junction(["p_fb", "p_ff"], "p_cmd", name="total")
    loop = ct.interconnect([plant, thermostat, smoother, ahead, total], inputs="setpoint",
                           outputs=["temperature", "power"], name="heating")
    T = np.arange(steps) * TS
    return loop, T, [18.0, 0.0], 21.0 + (T > 3.0), {"bias": 0.5, "ambient": 15}


DIAGRAMS = {
    "cruise control (car, PI with anti-windup)": cruise,
    "servo arm (actuator, PID)": servo,
    "hares and lynx (state feedback)": ecosystem,
    "steering (gain scheduled)": steering,
    "MRAC (MIT rule)": mrac,
    "state estimation": estimation,
    "heater (partial, object, methods, decorator)": heating,
}


#: The blocks of these diagrams whose functions call numpy's tan (python-control's own
#: examples do): where numpy computes it with code of its own, whose last bits compiled
#: code (the C library's tan) would not give, those blocks run as Python.
NUMPY_TAN = {"steering (gain scheduled)": ("bicycle",), "steering": ("bicycle",),
             "state estimation": ("car", "estimator")}


def expected_tier(diagram, block):
    """``"python"`` for a block of :data:`NUMPY_TAN` on a machine where numpy's tan is its
    own, else ``"compiled"``.

    Examples
    --------
    >>> expected_tier("cruise control (car, PI with anti-windup)", "car")
    'compiled'
    """
    # (imported here: the benchmarks build these diagrams for older engines too)
    from controlkit.engines.source.values import parts_from_c_library

    calls_tan = block in NUMPY_TAN.get(diagram, ())
    return "python" if calls_tan and parts_from_c_library("tan") else "compiled"
