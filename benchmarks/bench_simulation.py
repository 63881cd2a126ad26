"""Per-step cost and study time of the ways to simulate the papers' loops.

Run from the repository root after ``pip install ".[fast]"``::

    python benchmarks/bench_simulation.py            # about 2 minutes

It measures, in one process (plus subprocesses for ``controlkit reproduce``):

(a) the python-control reference path (``control.input_output_response``),
(b) the fast engine compiled (``simulate(..., compile=True)``: the diagram's module
    compiled once, kept in the store; the median of 3 warm calls of the whole horizon,
    the response object included),
(p) the fast engine as Python (``compile=False``: the same module run by Python,
    what a short run of a new diagram gets),
(c) a plain Python/numpy loop over time of the same equations: the blocks'
    kernels, uncompiled, called in signal order with the library's RK4 step -
    what a student would write by hand, without python-control and without
    compiling (it calls the library's equations rather than restating them),

and prints per-step costs and ratios a/b, c/b, a/p. Study totals for (a), (p) and (c)
are extrapolated from 2 000 steps per case; (b) is timed in full. Then ``controlkit
reproduce all`` with an empty store (every loop compiled or run as Python, as the
engine's rule decides) and with this store.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from controlkit._jit import python_function
from controlkit.kernels import cmg as cmg_kernels
from controlkit.kernels import common
from controlkit.kernels import mec as mec_kernels
from controlkit.kernels import spacecraft as sc_kernels
from controlkit.kernels.mec import MEC_INPUTS, TUNER_INPUTS
from controlkit.kernels.spacecraft import CONTROLLER_INPUTS, LINEARIZER_INPUTS
from controlkit.simulation import initial_state, simulate
from controlkit.studies.cmg import scenario as cmg_scenario
from controlkit.studies.spacecraft import scenario as sc_scenario

SPACECRAFT_CASES = ("ideal", "without_mec", "proposed")
SPACECRAFT_STEPS = 200_000  # 20 000 s at 0.1 s
CMG_STEPS = 12_000          # 12 s at 1 ms
SAMPLE = 2_000


plain = python_function  # a kernel as plain Python, uncompiled


def _rk4(rhs, t, x, u, p, h):
    """One RK4 step of a kernel ``rhs`` with ``u`` held: the library's own RK4 step."""
    work = tuple(np.empty(x.size) for _ in range(5))
    return plain(common.rk4_step)(rhs, t, x, u, p, h, work, np.empty(x.size))


def plain_spacecraft(case, steps):
    """(c): the spacecraft loop of ``case`` as a hand-written loop over the blocks' kernels."""
    loop = sc_scenario.build_loop(case)
    blocks = {s.name: s for s in loop.syslist}
    P = {name: s.kernels.params for name, s in blocks.items()}
    rhs, lin = plain(sc_kernels.plant_rhs), plain(sc_kernels.linearizer_output)
    attitude, controller = plain(sc_kernels.attitude_output), plain(sc_kernels.controller_output)
    mec, nominal = plain(mec_kernels.mec_output), plain(common.integrator_update)
    tuner_update, tuner_output = plain(mec_kernels.tuner_update), plain(mec_kernels.tuner_output)
    q = sc_scenario.initial_attitude()
    hn = blocks["nominal"].x0.copy() if "nominal" in blocks else None
    xt = blocks["tuner"].x0.copy() if "tuner" in blocks else None
    Ts, empty, r = loop.dt, np.zeros(0), np.zeros(2)
    out = np.empty((steps, 2))
    for k in range(steps):
        t = k * Ts
        h = attitude(t, empty, q, empty, np.empty(2))
        mu_n = controller(t, empty, CONTROLLER_INPUTS.pack(r=r, h=h), P["controller"],
                          np.empty(2))
        if xt is not None:
            K = tuner_output(t, xt, empty, P["tuner"], np.empty(4))
            mu = mec(t, empty, MEC_INPUTS.pack(mu_n=mu_n, hn=hn, h=h, K=K), empty, np.empty(2))
            xt = tuner_update(t, xt, TUNER_INPUTS.pack(mu=mu, h=h, hn=hn), P["tuner"],
                              np.empty(xt.size))
            hn = nominal(t, hn, mu_n, P["nominal"], np.empty(2))
        else:
            mu = mu_n
        u = lin(t, empty, LINEARIZER_INPUTS.pack(mu=mu, q=q), P["linearizer"], np.empty(2))
        out[k] = u
        q = _rk4(rhs, t, q, u, P["plant"], Ts)
    return out


def plain_cmg(steps):
    """(c): the CMG loop as a hand-written loop over the blocks' kernels."""
    loop = cmg_scenario.build_loop("thesis")
    blocks = {s.name: s for s in loop.syslist}
    P = {name: s.kernels.params for name, s in blocks.items()}
    rhs, ref = plain(cmg_kernels.plant_rhs), plain(cmg_kernels.reference_output)
    smc_output, smc_update = plain(cmg_kernels.smc_output), plain(cmg_kernels.smc_update)
    saturation = plain(common.saturation_output)
    x = cmg_scenario.X0_THESIS.copy()
    a = blocks["smc"].x0.copy()
    Ts, empty = blocks["smc"].dt, np.zeros(0)
    for k in range(steps):
        t = k * Ts
        measured = np.concatenate([x, ref(t, empty, empty, empty, np.empty(6))])
        command = smc_output(t, a, measured, P["smc"], np.empty(6))[:2]
        a = smc_update(t, a, measured, P["smc"], np.empty(a.size))
        torque = saturation(t, empty, command, P["saturation"], np.empty(2))
        x = _rk4(rhs, t, x, torque, P["cmg"], Ts)
    return x


def per_step(fn, steps):
    start = time.perf_counter()
    fn(steps)
    return (time.perf_counter() - start) / steps


def python_control_per_step(build, X0, dt, steps):
    loop = build()
    T = np.arange(steps + 1) * dt
    start = time.perf_counter()
    simulate(loop, T, X0=X0(loop), engine="python-control")
    return (time.perf_counter() - start) / steps


def fast_per_step(loop, X0, dt, steps, compile, repeats=3):
    """Seconds per step of the fast engine, compiled (``compile=True``: the module
    compiled or loaded by a first call, then the median of ``repeats`` calls) or as Python
    (one call)."""
    T = np.arange(steps) * dt
    if compile:
        simulate(loop, T[:10], X0=X0, engine="fast", compile=True)  # compile, or load
    times = []
    for _ in range(repeats if compile else 1):
        start = time.perf_counter()
        resp = simulate(loop, T, X0=X0, engine="fast", compile=compile)
        times.append(time.perf_counter() - start)
    assert resp.engine_mode == ("compiled" if compile else "python"), resp.engine_mode
    return float(np.median(times)) / steps


def fast_study():
    start = time.perf_counter()
    for case in SPACECRAFT_CASES:
        sc_scenario.run(case, engine="fast")
    cmg_scenario.run("thesis", engine="fast")
    return time.perf_counter() - start


def cold_reproduce_all():
    with tempfile.TemporaryDirectory() as tmp:
        os.mkdir(os.path.join(tmp, "numba"))
        env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, "numba"),
               "CONTROLKIT_CACHE_DIR": os.path.join(tmp, "store")}
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "controlkit", "reproduce", "all",
                        "--out", os.path.join(tmp, "out")], env=env, check=True,
                       capture_output=True)
        return time.perf_counter() - start


def warm_reproduce_all():
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        subprocess.run([sys.executable, "-m", "controlkit", "reproduce", "all",
                        "--out", tmp], check=True, capture_output=True)
        return time.perf_counter() - start


def main():
    from controlkit import _jit

    print(f"numba: {'yes' if _jit.available() else 'NO (fast engine runs as plain Python)'}")
    q0 = sc_scenario.initial_attitude()

    def sc_x0(loop):  # build_loop starts the ideal model and the tuner at h(0) = q0[1:3]
        return initial_state(loop, plant=q0)

    # warm-up: imports, first calls and compilation stay out of the timings
    for case in SPACECRAFT_CASES:
        python_control_per_step(lambda c=case: sc_scenario.build_loop(c), sc_x0, 0.1, 20)
        plain_spacecraft(case, 20)
    plain_cmg(20)
    rows = []
    for case in SPACECRAFT_CASES:
        a = python_control_per_step(lambda c=case: sc_scenario.build_loop(c), sc_x0, 0.1, SAMPLE)
        c = per_step(lambda n, c=case: plain_spacecraft(c, n), SAMPLE)
        loop = sc_scenario.build_loop(case)
        b = fast_per_step(loop, sc_x0(loop), 0.1, SPACECRAFT_STEPS, compile=True)
        p = fast_per_step(loop, sc_x0(loop), 0.1, SAMPLE, compile=False)
        rows.append((f"spacecraft/{case}", a, b, p, c, SPACECRAFT_STEPS))
    a = python_control_per_step(lambda: cmg_scenario.build_loop("thesis"),
                                lambda loop: initial_state(loop, cmg=cmg_scenario.X0_THESIS),
                                0.001, SAMPLE)
    c = per_step(plain_cmg, SAMPLE)
    loop = cmg_scenario.build_loop("thesis")
    x0 = initial_state(loop, cmg=cmg_scenario.X0_THESIS)
    b = fast_per_step(loop, x0, 0.001, CMG_STEPS, compile=True)
    p = fast_per_step(loop, x0, 0.001, SAMPLE, compile=False)
    rows.append(("cmg/thesis", a, b, p, c, CMG_STEPS))

    print(f"\n{'loop':24s} {'(a) python-control':>19s} {'(b) compiled':>13s} "
          f"{'(p) as Python':>14s} {'(c) plain loop':>15s} {'a/b':>7s} {'c/b':>6s} "
          f"{'a/p':>6s}   (per step, microseconds)")
    totals = np.zeros(4)
    for name, a, b, p, c, n in rows:
        totals += np.array([a, b, p, c]) * n
        print(f"{name:24s} {a * 1e6:19.1f} {b * 1e6:13.2f} {p * 1e6:14.1f} {c * 1e6:15.1f} "
              f"{a / b:7.0f} {c / b:6.0f} {a / p:6.1f}")
    print(f"\nstudy (3 x 20 000 s spacecraft + 12 s CMG): (a) {totals[0]:.0f} s "
          f"(extrapolated), (b) {totals[1]:.2f} s, (p) {totals[2]:.0f} s (extrapolated), "
          f"(c) {totals[3]:.0f} s (extrapolated)")
    print(f"fast study in-process, warm: {fast_study():.2f} s")
    cold = cold_reproduce_all()
    print(f"controlkit reproduce all, empty store (the engine's rule: compiles what pays): "
          f"{cold:.1f} s")
    print(f"controlkit reproduce all, this store: {warm_reproduce_all():.1f} s")


if __name__ == "__main__":
    main()
