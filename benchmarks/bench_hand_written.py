"""The distance to the limit: the generated loop against the same equations written by hand.

Two discrete diagrams built the python-control way, each also written as one numba loop by
hand (no diagram, no kernels, no parameter vector: the equations inlined):

- ``cruise``: python-control's cruise-control example (``benchmarks/cruise.py``) at
  dt = 0.1 s, the vehicle sampled under zero-order hold (one RK4 step per sample) under the
  discrete anti-windup PI;
- ``servo``: a DC motor's angle and speed, sampled exactly (``ct.sample_system``, zoh),
  under a discrete PI whose voltage a user ``nlsys`` saturates at 12 V.

For each: the nanoseconds per step of ``controlkit.input_output_response(...,
compile=True)`` (warm: the diagram's module compiled, the median of 5 calls over 10^6
steps), of the diagram's compiled module alone (its entry point ``run_discrete`` on arrays
made once), and of the hand-written loop over the same arrays; the ratios (the goal of
issue 21: the generated loop within 3x of the one written by hand), and the largest
difference of the outputs.

Run: ``python benchmarks/bench_hand_written.py`` (about a minute). The machine is shared:
compare the ratios, measured in the same process.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import control as ct
import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import cruise  # noqa: E402  (this folder's modules)
from timing import median_seconds  # noqa: E402

import controlkit  # noqa: E402
from controlkit import _jit  # noqa: E402

numba = _jit.numba_module()
STEPS = 1_000_000


@numba.njit(cache=True)
def _cruise_accel(v, throttle, gear, theta):
    """benchmarks/cruise.py's vehicle_update with the example's default parameters."""
    m, g, Cr, Cd, rho, A = 1600.0, 9.8, 0.01, 0.32, 1.3, 2.4
    Tm, omega_m, beta = 190.0, 420.0, 0.4
    alpha_n = (40.0, 25.0, 16.0, 12.0, 10.0)[int(gear) - 1]
    throttle = min(max(throttle, 0.0), 1.0)
    omega = alpha_n * v
    torque = max(Tm * (1 - beta * (omega / omega_m - 1) ** 2), 0.0)
    F = alpha_n * torque * throttle
    Fg = m * g * math.sin(theta)
    Fr = m * g * Cr * math.copysign(1.0, v)
    Fa = 1 / 2 * rho * Cd * A * abs(v) * v
    return (F - (Fg + Fr + Fa)) / m


@numba.njit(cache=True)
def cruise_by_hand(U, v0, z0, dt):
    """The cruise loop, one sample a pass: PI output, RK4 of the vehicle, PI update."""
    kp, ki, kaw = 0.5, 0.1, 2.0
    n = U.shape[1]
    Y = np.empty((2, n))
    v, z = v0, z0
    for k in range(n):
        vref, gear, theta = U[0, k], U[1, k], U[2, k]
        u = kp * (vref - v) + ki * z
        Y[0, k] = v
        Y[1, k] = u
        k1 = _cruise_accel(v, u, gear, theta)
        k2 = _cruise_accel(v + dt / 2 * k1, u, gear, theta)
        k3 = _cruise_accel(v + dt / 2 * k2, u, gear, theta)
        k4 = _cruise_accel(v + dt * k3, u, gear, theta)
        rate = (vref - v) + kaw / ki * (min(max(u, 0.0), 1.0) - u)
        v = v + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        z = z + dt * rate
    return Y


def servo(dt=0.01):
    """Motor (angle, speed) sampled exactly, a discrete PI, a user nlsys saturating at 12 V."""
    motor = ct.sample_system(ct.ss([[0.0, 1.0], [0.0, -4.0]], [[0.0], [8.0]], np.eye(2), 0.0),
                             dt, method="zoh", inputs="v", outputs=["theta", "w"],
                             states=["theta", "w"], name="motor")
    pi = ct.sample_system(ct.ss(ct.tf([2.0, 1.0], [1.0, 0.0])), dt, method="tustin",
                          inputs="e", outputs="v_cmd", name="pi")

    def saturate(t, x, u, params):
        return np.clip(u[0], -params["v_max"], params["v_max"])

    amplifier = ct.nlsys(None, saturate, inputs="v_cmd", outputs="v", params={"v_max": 12.0},
                         dt=dt, name="amplifier")
    error = ct.summing_junction(["r", "-theta"], "e", name="error")
    loop = ct.interconnect([motor, pi, amplifier, error], inputs="r", outputs=["theta", "v"],
                           name="servo")
    return loop, motor, pi


@numba.njit(cache=True)
def servo_by_hand(r, Am, Bm, Ap, Bp, Cp, Dp, v_max):
    """The servo loop: error, PI (state space), saturation, motor update."""
    n = r.shape[0]
    Y = np.empty((2, n))
    th, w, z = 0.0, 0.0, 0.0
    for k in range(n):
        e = r[k] - th
        v = min(max(Cp * z + Dp * e, -v_max), v_max)
        Y[0, k] = th
        Y[1, k] = v
        th, w = Am[0, 0] * th + Am[0, 1] * w + Bm[0] * v, Am[1, 0] * th + Am[1, 1] * w + Bm[1] * v
        z = Ap * z + Bp * e
    return Y


def loop_alone(loop, T, U, X0):
    """A call of the diagram's compiled module alone: no argument checks, no pieces, no
    response object.

    ``controlkit.input_output_response`` adds to it what a user's call needs (``T`` checked,
    output and state arrays filled, a ``TimeResponseData`` that copies them): the time of
    that is the difference of the two columns.
    """
    from controlkit.engines.fast.run import prepare

    job = prepare(loop, compiled=True)
    U = np.ascontiguousarray(np.broadcast_to(np.atleast_2d(U), (loop.ninputs, T.size)),
                             dtype=float)
    Y, X = np.empty((loop.noutputs, T.size)), np.empty((loop.nstates, T.size))
    status = np.full(2, -1, dtype=np.int64)
    args = (T, np.asarray(X0, dtype=float), U, job.P, Y, X, status, 0, T.size)
    run = job.entry("run_discrete", args)
    return lambda: run(*args)


def main() -> int:
    rows = []
    # --- cruise
    loop, _, X0, _ = cruise.loop(dt=0.1)
    T = np.arange(STEPS) * 0.1
    theta = np.deg2rad(np.clip(4.0 * (T - 10.0), 0.0, 4.0))
    U = np.vstack([20.0 * np.ones_like(T), 4.0 * np.ones_like(T), theta])
    ours = controlkit.input_output_response(loop, T, U, X0, compile=True)  # compiles once
    hand = cruise_by_hand(U, X0[0], X0[1], 0.1)
    rows.append(("cruise (2 states, 2 user nlsys)",
                 median_seconds(lambda: controlkit.input_output_response(loop, T, U, X0,
                                                                         compile=True)),
                 median_seconds(loop_alone(loop, T, U, X0)),
                 median_seconds(lambda: cruise_by_hand(U, X0[0], X0[1], 0.1)),
                 float(np.abs(ours.outputs - hand).max())))
    # --- servo
    loop, motor, pi = servo()
    T = np.arange(STEPS) * 0.01
    r = np.where(T % 4.0 < 2.0, 1.0, -1.0)
    ours = controlkit.input_output_response(loop, T, r, np.zeros(3), compile=True)
    args = (r, motor.A, motor.B[:, 0].copy(), pi.A[0, 0], pi.B[0, 0], pi.C[0, 0], pi.D[0, 0],
            12.0)
    hand = servo_by_hand(*args)
    rows.append(("servo (3 states, LTI + user nlsys)",
                 median_seconds(lambda: controlkit.input_output_response(
                     loop, T, r, np.zeros(3), compile=True)),
                 median_seconds(loop_alone(loop, T, r, np.zeros(3))),
                 median_seconds(lambda: servo_by_hand(*args)),
                 float(np.abs(ours.outputs - hand).max())))
    print(f"{STEPS:,} steps a call, median of 5 warm calls, nanoseconds a step")
    print("| diagram | controlkit.input_output_response | its generated loop alone | "
          "by hand | ratio (call) | ratio (loop) | max difference |")
    print("|---|---|---|---|---|---|---|")
    for name, call_s, loop_s, hand_s, diff in rows:
        ns = [f"{s / STEPS * 1e9:.0f}" for s in (call_s, loop_s, hand_s)]
        print(f"| {name} | {' | '.join(ns)} | {call_s / hand_s:.2f}x | {loop_s / hand_s:.2f}x "
              f"| {diff:.1e} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
