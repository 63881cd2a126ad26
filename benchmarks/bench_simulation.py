"""Per-step cost and study time of the three ways to simulate the papers' loops.

Run from the repository root after ``pip install ".[fast]"``::

    python benchmarks/bench_simulation.py            # about 2 minutes

It measures, in one process (plus one subprocess for the cold start):

(a) the python-control reference path (``control.input_output_response``),
(b) the fast engine (``controlkit.engine``, numba-compiled), warm and cold,
(c) a plain Python/numpy loop over time of the same equations: the kernels'
    uncompiled Python, called in signal order with the same RK4 - what a
    student would write by hand, without python-control and without compiling,

and prints per-step costs and ratios (b)/(a), (b)/(c). Study totals for (a)
and (c) are extrapolated from 2 000 steps per case; (b) is timed in full. The
per-step cost of (b) is that of the compiled loop alone; building the
``control.TimeResponseData`` it returns (python-control's constructor, paid by
both simulators: 0.2 s for 200 001 samples of the MEC + FRIT loop) is reported
in the study totals.
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time

import numpy as np

from controlkit.blocks import cmg as cmg_blocks
from controlkit.kernels import cmg as cmg_kernels
from controlkit.kernels import mec as mec_kernels
from controlkit.kernels import spacecraft as sc_kernels
from controlkit.scenarios import cmg as cmg_scenario
from controlkit.scenarios import spacecraft as sc_scenario
from controlkit.simulation import initial_state, simulate

SPACECRAFT_CASES = ("ideal", "without_mec", "proposed")
SPACECRAFT_STEPS = 200_000  # 20 000 s at 0.1 s
CMG_STEPS = 12_000          # 12 s at 1 ms
SAMPLE = 2_000


def plain(f):
    return getattr(f, "py_func", f)


def _rk4(rhs, t, x, u, p, h):
    n = x.size
    k1 = rhs(t, x, u, p, np.empty(n))
    k2 = rhs(t + h / 2, x + (h / 2) * k1, u, p, np.empty(n))
    k3 = rhs(t + h / 2, x + (h / 2) * k2, u, p, np.empty(n))
    k4 = rhs(t + h, x + h * k3, u, p, np.empty(n))
    return x + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4)


def plain_spacecraft(case, steps):
    """(c): the spacecraft loop of ``case`` written out by hand."""
    loop = sc_scenario.build_loop(case)
    blocks = {s.name: s for s in loop.syslist}
    P = {name: s.kernels.params for name, s in blocks.items()}
    rhs, lin = plain(sc_kernels.plant_rhs), plain(sc_kernels.linearizer_output)
    mec = "tuner" in blocks or "gain" in blocks
    tuner_update = plain(mec_kernels.tuner_update)
    q = sc_scenario.initial_attitude()
    hn = q[1:3].copy()
    xt = blocks["tuner"].x0.copy() if "tuner" in blocks else None
    F, Ts, empty = P["controller"], 0.1, np.zeros(0)
    out = np.empty((steps, 2))
    for k in range(steps):
        t = k * Ts
        h = q[1:3]
        mu_n = F * (0.0 - h)
        if mec:
            K = xt[20:24].reshape(2, 2)
            mu = mu_n + K @ (hn - h)
            xt = tuner_update(t, xt, np.concatenate([mu, h, hn]), P["tuner"], np.empty(24))
            hn = hn + Ts * mu_n
        else:
            mu = mu_n
        u = lin(t, empty, np.concatenate([mu, q]), P["linearizer"], np.empty(2))
        out[k] = u
        q = _rk4(rhs, t, q, u, P["plant"], Ts)
    return out


def plain_cmg(steps):
    """(c): the CMG loop written out by hand."""
    loop = cmg_scenario.build_loop("thesis")
    P = {s.name: s.kernels.params for s in loop.syslist}
    rhs, law, ref = (plain(cmg_kernels.plant_rhs), plain(cmg_kernels.smc_equations),
                    plain(cmg_kernels.reference_output))
    x = cmg_scenario.X0_THESIS.copy()
    a = np.zeros(4)
    Ts, empty = 0.001, np.zeros(0)
    limits = np.array([cmg_blocks.T1_MAX, cmg_blocks.T2_MAX])
    for k in range(steps):
        t = k * Ts
        r = law(a, np.concatenate([x, ref(t, empty, empty, empty, np.empty(6))]), P["smc"])
        torque, rates = np.array(r[:2]), np.array(r[2:])
        a = a + Ts * rates
        x = _rk4(rhs, t, x, np.clip(torque, -limits, limits), P["cmg"], Ts)
    return x


def per_step(fn, steps):
    start = time.perf_counter()
    fn(steps)
    return (time.perf_counter() - start) / steps


def python_control_per_step(build, X0, dt, steps):
    loop = build()
    T = np.arange(steps + 1) * dt
    start = time.perf_counter()
    simulate(loop, T, X0(loop), engine="python-control")
    return (time.perf_counter() - start) / steps


def marginal_per_step(loop, X0, dt, steps):
    """Seconds per step of the compiled loop, called as simulate_fast calls it."""
    from controlkit import engine

    run, blocks = engine.compile_system(loop)
    T = np.arange(steps) * dt
    U = np.zeros((loop.ninputs, steps))
    P = np.concatenate([b.kernels.params for b in blocks])
    Y, X = np.zeros((loop.noutputs, steps)), np.zeros((loop.nstates, steps))
    status = np.array([-1, -1])
    run(T, np.asarray(X0, float), U, P, Y, X, status, 0, 10)  # compile or load
    start = time.perf_counter()
    run(T, np.asarray(X0, float), U, P, Y, X, status, 0, steps)
    return (time.perf_counter() - start) / steps


def fast_study():
    start = time.perf_counter()
    for case in SPACECRAFT_CASES:
        sc_scenario.run(case, engine="fast")
    cmg_scenario.run("thesis", engine="fast")
    return time.perf_counter() - start


def cold_reproduce_all():
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": os.path.join(tmp, "numba"),
               "CONTROLKIT_CACHE_DIR": os.path.join(tmp, "engine")}
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

    print(f"numba: {'yes' if _jit.HAVE_NUMBA else 'NO (fast engine runs as plain Python)'}")
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
        b = marginal_per_step(loop, sc_x0(loop), 0.1, SPACECRAFT_STEPS)
        rows.append((f"spacecraft/{case}", a, b, c, SPACECRAFT_STEPS))
    a = python_control_per_step(lambda: cmg_scenario.build_loop("thesis"),
                                lambda loop: initial_state(loop, cmg=cmg_scenario.X0_THESIS),
                                0.001, SAMPLE)
    c = per_step(plain_cmg, SAMPLE)
    loop = cmg_scenario.build_loop("thesis")
    b = marginal_per_step(loop, initial_state(loop, cmg=cmg_scenario.X0_THESIS), 0.001,
                          CMG_STEPS)
    rows.append(("cmg/thesis", a, b, c, CMG_STEPS))

    print(f"\n{'loop':24s} {'(a) python-control':>19s} {'(b) fast':>10s} "
          f"{'(c) plain loop':>15s} {'a/b':>7s} {'c/b':>6s}   (per step, microseconds)")
    totals = np.zeros(3)
    for name, a, b, c, n in rows:
        totals += np.array([a, b, c]) * n
        print(f"{name:24s} {a * 1e6:19.1f} {b * 1e6:10.2f} {c * 1e6:15.1f} "
              f"{a / b:7.0f} {c / b:6.0f}")
    print(f"\nstudy (3 x 20 000 s spacecraft + 12 s CMG), stepping only: "
          f"(a) {totals[0]:.0f} s (extrapolated), (b) {totals[1]:.2f} s, "
          f"(c) {totals[2]:.0f} s (extrapolated)")
    print(f"fast study in-process, warm: {fast_study():.2f} s")
    cold = cold_reproduce_all()
    print(f"controlkit reproduce all, cold caches (compile included): {cold:.1f} s")
    print(f"controlkit reproduce all, warm caches: {warm_reproduce_all():.1f} s")


if __name__ == "__main__":
    main()
