"""Continuous and sampled-data diagrams: controlkit against python-control (issue 22's table).

For diagrams of ``tests/continuous_diagrams.py``, each over a short horizon (100 s) and a
long one (10^5 s, 1001 evaluation times each), three ways:

- ``controlkit.input_output_response``: the first call in a fresh process (the store as
  it is: a user's second session), the first call of the same diagram built again in
  that running process as a newly wired one (a block renamed: its module never
  compiled, so the engine's rule decides between Python and compiling it now) and the
  median of later calls (``compile=True``: the diagram's module, compiled);
- ``control.input_output_response`` (python-control; a sampled-data diagram, which it
  cannot run, is timed on controlkit's plain-Python reference instead);
- "just jit the right-hand side": scipy's ``solve_ivp`` calling the diagram's compiled
  right-hand side (what a user gets by compiling the right-hand side alone), states only.

A reference slower than ``--budget`` seconds is run over a shorter horizon and scaled to
the full one (marked ``~``). Then 1000 runs of one continuous diagram over parameter draws,
in one call, against python-control's time per run.

Run: ``python benchmarks/bench_continuous.py [--budget 60] [--only ROW ...] [--notebook]``
(about 10-20 minutes for all; a row is ``diagram`` or ``diagram:horizon``, ``many`` the
1000 runs; ``--notebook``: 2 s between the import and the first call, and before the
later calls and the new wiring, as a person takes between cells).
The machine is shared: compare the ratios, measured in the same process.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent
TESTS = HERE.parent / "tests"

CONTINUOUS = ("pi_first_order", "dc_motor", "car_pi", "steering", "spacecraft_fig2")
MIXED = ("servo_pi_discrete", "two_rate_servo", "spacecraft_fig2_zoh")
HORIZONS = {"short": 100.0, "long": 1e5}


def _case(name, horizon):
    """The diagram, and its time points and inputs stretched to ``horizon``."""
    from continuous_diagrams import CONTINUOUS as C
    from continuous_diagrams import MIXED as M

    loop, T, X0, U = {**C, **M}[name]()
    U = np.atleast_2d(U) if np.ndim(U) else np.zeros((0, T.size))
    scale = horizon / T[-1]
    T_new = np.linspace(0.0, horizon, 1001)
    U_new = np.array([np.interp(T_new / scale, T, row) for row in U]) if len(U) else \
        np.zeros((0, T_new.size))
    return loop, T_new, np.asarray(X0, dtype=float), U_new


def _times(ratio):
    """A speed ratio as the tables print it: one decimal below 10 (0.4x, 6.5x, 115x)."""
    return f"{ratio:.1f}x" if ratio < 10 else f"{ratio:.0f}x"


def _timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return time.perf_counter() - start, result


def _reference(loop, T, X0, U, budget):
    """python-control's time (or controlkit's Python reference for a sampled-data one)."""
    import control as ct

    import controlkit

    def run(T_, U_):
        if type(loop).__name__ == "SampledDataSystem":
            return controlkit.input_output_response(loop, T_, U_, X0, engine="python-control")
        return ct.input_output_response(loop, T_, U_, X0)

    short = max(3, T.size // 100)  # time the first 1 % first, to judge the whole
    seconds, _ = _timed(run, T[:short], U[:, :short])
    estimate = seconds * T[-1] / T[short - 1]
    if estimate <= budget:
        seconds, _ = _timed(run, T, U)
        return seconds, ""
    return estimate, "~"


def _jit_rhs(loop, T, X0, U):
    """solve_ivp with the diagram's compiled right-hand side (states only)."""
    import scipy.integrate

    from controlkit import _jit
    from controlkit.engines.fast import loops, store
    from controlkit.engines.fast.run import prepare

    job = prepare(loop, compiled=True)
    plan = job.plan
    module = store.import_module(store.module_file(job.source, "diagram"), job.kernels())
    rhs = _jit.dispatcher(loops.diagram_rhs)  # the diagram's right-hand side, compiled alone
    nx = loop.nstates
    args = (module.evaluate, module.derivatives, np.array(X0, dtype=float),
            np.empty(nx), plan.continuous, T, U,
            np.empty((U.shape[0], 1)), job.P, np.zeros(plan.ny), np.zeros(plan.nu),
            np.zeros(plan.ny), np.zeros(nx))

    def fun(t, y):
        out = np.empty(plan.continuous.size)
        rhs(t, y, args, out)
        return out

    fun(T[0], np.asarray(X0)[plan.continuous])  # compile before timing
    return _timed(scipy.integrate.solve_ivp, fun, (T[0], T[-1]),
                  np.asarray(X0)[plan.continuous], t_eval=T)[0]


def child(name, horizon_label, budget, pause=0.0):
    """One row, measured in this (fresh) process (``pause``: seconds between the import
    and the diagram's building, as a person takes in a notebook)."""
    import controlkit

    time.sleep(pause)

    loop, T, X0, U = _case(name, HORIZONS[horizon_label])
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a fallback to python-control would not be ours
        first, _ = _timed(controlkit.input_output_response, loop, T, U, X0)
        time.sleep(pause)  # the next cell
        controlkit.input_output_response(loop, T, U, X0, compile=True)  # compiled once
        warm = statistics.median(
            _timed(controlkit.input_output_response, loop, T, U, X0, compile=True)[0]
            for _ in range(5))
        time.sleep(pause)  # the person wires the blocks anew in the next cell
        rewired = _new_wiring(name, horizon_label)
    ref, mark = _reference(loop, T, X0, U, budget)
    jit = _jit_rhs(loop, T, X0, U) if type(loop).__name__ != "SampledDataSystem" else None
    return {"name": name, "horizon": horizon_label, "first": first, "warm": warm,
            "rewired": rewired, "reference": ref, "mark": mark, "jit_rhs": jit}


def _new_wiring(name, horizon_label):
    """The first call of a newly wired diagram of known blocks in a running session: the
    diagram built again with a block renamed, so that its module was never compiled (the
    engine's rule runs it as Python, or compiles it first when the run, timed on its
    first tenth of a second, would take longer as Python)."""
    import uuid

    import controlkit

    loop, T, X0, U = _case(name, HORIZONS[horizon_label])
    loop.syslist[0].name += f"_{uuid.uuid4().hex[:8]}"  # the block names are in the module
    return _timed(controlkit.input_output_response, loop, T, U, X0)[0]


def many(budget):
    """1000 runs of the car's PI loop over parameter draws, in one call."""
    import control as ct
    from continuous_diagrams import car_pi

    import controlkit

    loop, T, X0, U = car_pi()
    rng = np.random.default_rng(0)
    draws = [{"kp": float(rng.uniform(0.2, 1.0)), "ki": float(rng.uniform(0.05, 0.3))}
             for _ in range(1000)]
    controlkit.input_output_response(loop, T, U, X0, params=draws[:2], compile=True)
    out = {}
    for threads in (1, 2):
        import numba

        numba.set_num_threads(threads)
        out[f"ours_{threads}"] = _timed(controlkit.input_output_response, loop, T, U, X0,
                                        params=draws, compile=True)[0]
    per_run, _ = _timed(lambda: [ct.input_output_response(loop, T, U, X0, params=p)
                                 for p in draws[:20]])
    out["python_control"] = per_run / 20 * 1000
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budget", type=float, default=60.0,
                        help="longest reference run in seconds (beyond: scaled, marked ~)")
    parser.add_argument("--only", nargs="+", metavar="ROW",
                        help="rows to run, as diagram or diagram:horizon (short, long)")
    parser.add_argument("--notebook", action="store_true",
                        help="each row as in a notebook: 2 s between the import and the "
                             "first call, and between the later cells")
    parser.add_argument("--child", nargs=2, help=argparse.SUPPRESS)
    parser.add_argument("--pause", type=float, default=0.0, help=argparse.SUPPRESS)
    parser.add_argument("--many", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    sys.path[:0] = [str(TESTS), str(HERE)]
    if args.child:
        print(json.dumps(child(*args.child, args.budget, args.pause)))
        return 0
    if args.many:
        print(json.dumps(many(args.budget)))
        return 0
    from timing import checkout_env

    env = checkout_env()
    print("| diagram | horizon | first call | new wiring | warm call | python-control "
          "| ratio first | ratio new wiring | ratio warm | jit rhs (solve_ivp) "
          "| ratio vs jit rhs |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name in (*CONTINUOUS, *MIXED):
        for label in HORIZONS:
            if args.only and name not in args.only and f"{name}:{label}" not in args.only:
                continue
            out = subprocess.run([sys.executable, __file__, "--child", name, label,
                                  "--budget", str(args.budget),
                                  "--pause", "2" if args.notebook else "0"], env=env,
                                 capture_output=True, text=True)
            if out.returncode:
                print(f"| {name} | {label} | failed: {out.stderr.strip().splitlines()[-1]} |")
                continue
            r = json.loads(out.stdout.strip().splitlines()[-1])
            reference = "reference (Python)" if name in MIXED else "python-control"
            jit = f"{r['jit_rhs']:.3f} s" if r["jit_rhs"] is not None else "-"
            vs_jit = _times(r['jit_rhs'] / r['warm']) if r["jit_rhs"] else "-"
            print(f"| {name} | {label} | {r['first']:.3f} s | {r['rewired']:.4f} s | "
                  f"{r['warm']:.4f} s | {r['mark']}{r['reference']:.2f} s ({reference}) | "
                  f"{r['mark']}{_times(r['reference'] / r['first'])} | "
                  f"{r['mark']}{_times(r['reference'] / r['rewired'])} | "
                  f"{r['mark']}{_times(r['reference'] / r['warm'])} | {jit} | {vs_jit} |",
                  flush=True)
    if args.only and "many" not in args.only:
        return 0
    out = subprocess.run([sys.executable, __file__, "--many"], env=env, capture_output=True,
                         text=True, check=True)
    m = json.loads(out.stdout.strip().splitlines()[-1])
    print(f"\n1000 runs of car_pi over parameter draws: ours {m['ours_1']:.2f} s on 1 "
          f"thread, {m['ours_2']:.2f} s on 2; python-control ~{m['python_control']:.1f} s "
          f"(20 runs, scaled): {_times(m['python_control'] / m['ours_1'])} and "
          f"{_times(m['python_control'] / m['ours_2'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
