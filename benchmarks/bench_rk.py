"""Benchmarks of :mod:`controlkit.engines.fast.rk`: compile and cache-load times, cost per step.

Run from the repository root after ``pip install ".[fast]"``::

    python benchmarks/bench_rk.py compile     # about 5 minutes
    python benchmarks/bench_rk.py runtime     # about 10 minutes

(no argument: both). Results are printed and written to ``results/bench_rk.json``. The
machine is shared and noisy: each number is the median of several runs.

compile
    Generated modules as controlkit would write them (the right-hand side a global of
    a compiled ``run``), each imported in a fresh process with its own numba cache:
    ``no integrator`` (the floor: 1000 Euler steps), ``machine linked`` (``run`` calls
    ``rk.solve_interval`` with ``rk.machine``, whose code numba then links and
    optimizes into ``run``), ``machine by pointer`` (``run`` receives the step machine
    compiled once and kept in the store, ``store.step_machine()``, and calls it through
    its address: what the engine does). For each: the first call with an empty cache
    ("cold"), the first call of a *new* diagram once rk's functions are cached, and the
    first call in a second process (all loaded from the cache). Each design runs with
    its own numba cache folder (``NUMBA_CACHE_DIR``) and store (``CONTROLKIT_CACHE_DIR``),
    so "cold" includes compiling the integrator. (A third design, the right-hand side a
    first-class function too, was measured and dropped: see README.md.)
runtime
    Nanoseconds per accepted step on a 2-state and a 10-state nonlinear problem over a
    1e5 s horizon: ours (machine linked or by pointer), scipy's ``solve_ivp`` with the same
    right-hand side in Python and with the numba-compiled one (python-control's "just
    jit the right-hand side"), both measured per step on a 1e3 s horizon, and a plain
    fixed-step RK4 loop making as many evaluations as our run. The problems are
    ``tests/rk_problems.py``'s.
"""

from __future__ import annotations

import functools
import json
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap

import numpy as np
from timing import median_seconds  # this folder's module

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TESTS = os.path.join(ROOT, "tests")
RESULTS = os.path.join(ROOT, "results", "bench_rk.json")
PYTHON = sys.executable

RHS_SOURCE = {
    "vdp2": '''
@numba.njit(cache=True)
def rhs(t, y, args, out):
    mu = args[0][0] + {salt}
    out[0] = y[1]
    out[1] = mu * (1.0 - y[0] * y[0]) * y[1] - y[0]
    return out
''',
}

#: The first lines of every generated module (the right-hand side pasted in at {rhs}).
HEADER = '''
import numpy as np
from controlkit import _jit
numba = _jit.numba_module()
from controlkit.engines.fast import rk, store
{rhs}

@numba.njit(cache=True)
'''
#: The problem every design solves: van der Pol from (2, 0) over 20 s, 101 points.
ARGS = "    args = (np.array([2.0]), np.zeros(2), np.zeros((0, 2)))\n"
PROBLEM = '''    y0 = np.array([2.0, 0.0])
    t_eval = np.linspace(0.0, 20.0, 101)
    y_eval = np.zeros((101, 2))
    work = rk.make_workspace(2, 0, 101)
'''
#: ``run``'s call of the integrator, through ``{machine}``.
SOLVE = '''    y_end = np.empty(y0.shape[0])
    return rk.solve_interval({machine}, rhs, args, {{index}}, 0.0, 20.0, y0, 1e-3,
                             np.full(y0.shape[0], 1e-6), np.inf, 0.0, t_eval, 0, True,
                             y_eval, y_end, work, 0, False)


def first_call():
'''

LINKED_TEMPLATE = (HEADER + "def run(y0, t_eval, y_eval, work):\n" + ARGS
                   + SOLVE.format(machine="rk.machine") + PROBLEM
                   + "    return run(y0, t_eval, y_eval, work), y_eval[-1]\n")

POINTER_TEMPLATE = (HEADER + "def run(machine, y0, t_eval, y_eval, work):\n" + ARGS
                    + SOLVE.format(machine="machine") + PROBLEM
                    + "    return run(store.step_machine(), y0, t_eval, y_eval, work), "
                      "y_eval[-1]\n")

BASELINE_TEMPLATE = HEADER + '''def run(y0, t_eval, y_eval, work):
    """No integrator: 1000 explicit Euler steps (the floor of a diagram's compile time)."""
    args = (np.array([2.0]), np.zeros(2), np.zeros((0, 2)))
    y = np.empty(y0.shape[0])
    slope = np.empty(y0.shape[0])
    for i in range(y.shape[0]):
        y[i] = y0[i]
    for _ in range(1000):
        rhs(0.0, y, args, slope)
        for i in range(y.shape[0]):
            y[i] += 1e-3 * slope[i]
    for i in range(y.shape[0]):
        y_eval[y_eval.shape[0] - 1, i] = y[i]
    return 0, {index}


def first_call():
    y0 = np.array([2.0, 0.0])
    y_eval = np.zeros((101, 2))
    return run(y0, np.zeros(101), y_eval, None), y_eval[-1]
'''

DESIGNS = {
    "no integrator (floor)": BASELINE_TEMPLATE,
    "machine linked": LINKED_TEMPLATE,
    "machine by pointer": POINTER_TEMPLATE,
}

DRIVER = '''
import sys, time, json
start = time.perf_counter()
sys.path[:0] = [{root!r}, {gen!r}]
import numpy as np, numba
from controlkit.engines.fast import rk
imported = time.perf_counter()
module = __import__({module!r})
loaded = time.perf_counter()
result, last = module.first_call()
called = time.perf_counter()
print(json.dumps({{"import_numba_rk": imported - start, "import_module": loaded - imported,
                  "first_call": called - loaded, "status": int(result[0]),
                  "last": list(map(float, last)),
                  "run_cache_hits": sum(module.run.stats.cache_hits.values()),
                  "run_cache_misses": sum(module.run.stats.cache_misses.values())}}))
'''


def run_driver(gen_dir, module, cache_dir):
    """Import ``module`` from ``gen_dir`` in a fresh process and time its first call."""
    environment = dict(os.environ, NUMBA_CACHE_DIR=cache_dir,
                       CONTROLKIT_CACHE_DIR=os.path.join(cache_dir, "store"))
    script = DRIVER.format(root=ROOT, gen=gen_dir, module=module)
    output = subprocess.run([PYTHON, "-c", script], capture_output=True, text=True,
                            env=environment, check=True).stdout
    return json.loads(output.strip().splitlines()[-1])


def write_module(gen_dir, name, template, method, salt):
    """A generated diagram module (``salt`` makes each right-hand side a new function)."""
    from controlkit.engines.fast import rk

    source = template.format(rhs=RHS_SOURCE["vdp2"].format(salt=salt),
                             index=rk.METHOD_INDEX[method])
    with open(os.path.join(gen_dir, name + ".py"), "w") as handle:
        handle.write(textwrap.dedent(source))


def bench_compile(repeats=3, methods=("RK45",)):
    """Median first-call times (s) per design; see the module docstring.

    The machine holds the three tableaux and picks one at run time, so the method does
    not change what is compiled (``methods`` can check that).
    """
    table = {}
    for design, template in DESIGNS.items():
        for method in methods:
            cold, new_diagram, cached = [], [], []
            for _ in range(repeats):
                with tempfile.TemporaryDirectory() as gen_dir, \
                        tempfile.TemporaryDirectory() as cache_dir:
                    write_module(gen_dir, "diagram_a", template, method, "0.0")
                    write_module(gen_dir, "diagram_b", template, method, "0.0 * 2")
                    a = run_driver(gen_dir, "diagram_a", cache_dir)
                    b = run_driver(gen_dir, "diagram_b", cache_dir)
                    b_again = run_driver(gen_dir, "diagram_b", cache_dir)
                    assert a["status"] == b["status"] == b_again["status"] == 0
                    assert a["last"] == b["last"] == b_again["last"]
                    # the second process compiles nothing: run comes from the disk cache
                    assert (b_again["run_cache_hits"], b_again["run_cache_misses"]) == (1, 0)
                    assert (b["run_cache_hits"], b["run_cache_misses"]) == (0, 1)
                    cold.append(a["first_call"])
                    new_diagram.append(b["first_call"])
                    cached.append(b_again["first_call"])
            table[(design, method)] = (statistics.median(cold),
                                       statistics.median(new_diagram),
                                       statistics.median(cached))
            print(f"{design:24s} {method:7s} cold {table[(design, method)][0]:6.2f} s   "
                  f"new diagram {table[(design, method)][1]:6.2f} s   "
                  f"from cache {table[(design, method)][2]:6.2f} s", flush=True)
    return table


# ------------------------------------------------------------------------------------------
# Cost per step
# ------------------------------------------------------------------------------------------


def _compiled_callers():
    """The compiled loops the runtime benchmark times (compiled here, not cached)."""
    from controlkit import _jit
    from controlkit.engines.fast import rk

    numba = _jit.numba_module()

    @numba.njit
    def rk4_fixed(rhs, args, y0, t0, h, steps, work):
        """Classical RK4, ``steps`` steps of ``h`` (controlkit's rk4_step, as a loop)."""
        k1, k2, k3, k4, yt = work
        y = y0.copy()
        n = y.shape[0]
        t = t0
        for _ in range(steps):
            rhs(t, y, args, k1)
            for j in range(n):
                yt[j] = y[j] + (h / 2) * k1[j]
            rhs(t + h / 2, yt, args, k2)
            for j in range(n):
                yt[j] = y[j] + (h / 2) * k2[j]
            rhs(t + h / 2, yt, args, k3)
            for j in range(n):
                yt[j] = y[j] + h * k3[j]
            rhs(t + h, yt, args, k4)
            for j in range(n):
                y[j] = y[j] + (h / 6) * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
            t += h
        return y

    @numba.njit
    def linked(machine_function, rhs, args, method, t1, y0, atol, t_eval, y_eval, y_end,
               work):
        """The machine called directly (its code compiled into this caller)."""
        return rk.solve_interval(rk.machine, rhs, args, method, 0.0, t1, y0, 1e-3, atol,
                                 np.inf, 0.0, t_eval, 0, True, y_eval, y_end, work, 0,
                                 False)

    @numba.njit
    def by_pointer(machine_function, rhs, args, method, t1, y0, atol, t_eval, y_eval, y_end,
                   work):
        """The machine called through its address (the engine's way)."""
        return rk.solve_interval(machine_function, rhs, args, method, 0.0, t1, y0, 1e-3, atol,
                                 np.inf, 0.0, t_eval, 0, True, y_eval, y_end, work, 0,
                                 False)

    return rk4_fixed, linked, by_pointer


def _evaluate_compiled(rhs, args, n, t, y):
    """scipy's ``fun(t, y)`` around a compiled ``rhs(t, y, args, out)``."""
    out = np.empty(n)
    rhs(t, y, args, out)
    return out


def bench_runtime(repeats=5, horizon=1e5, scipy_horizon=1e3):
    """Nanoseconds per step of each integrator on two problems; see the module docstring."""
    import rk_problems as P
    import scipy.integrate

    from controlkit.engines.fast import rk, store

    rk4_fixed, linked, by_pointer = _compiled_callers()
    problems = P.make_problems()
    cases = {
        "van_der_pol (2 states)": problems["van_der_pol"],
        "chain10 (10 states)": problems["chain10"],
    }
    machine_pointer = store.step_machine()
    rows = []
    for label, problem in cases.items():
        for method in ("RK45", "DOP853", "RK23"):
            n = problem.y0.shape[0]
            args = problem.args
            index = rk.METHOD_INDEX[method]
            t_eval = np.linspace(0.0, horizon, 1001)
            y_eval = np.zeros((t_eval.shape[0], n))
            y_end = np.zeros(n)
            atol = np.full(n, 1e-6)
            work = rk.make_workspace(n, 0, t_eval.shape[0])
            variants = {
                "linked": (linked, machine_pointer, problem.rhs),
                "machine by pointer": (by_pointer, machine_pointer, problem.rhs),
            }
            per_step = {}
            counts = {}
            for name, (caller, machine_value, rhs_value) in variants.items():
                call = functools.partial(caller, machine_value, rhs_value, args, index,
                                         horizon, problem.y0, atol, t_eval, y_eval, y_end,
                                         work)
                status, _ = call()
                assert status == rk.SUCCESS
                seconds = median_seconds(call, repeats)
                counts[name] = (int(work.ints[rk.N_ACCEPTED]), int(work.ints[rk.NFEV]))
                per_step[name] = seconds / counts[name][0] * 1e9
            steps, nfev = counts["linked"]

            # scipy on a shorter horizon (its cost per step does not depend on the horizon)
            short_eval = np.linspace(0.0, scipy_horizon, 11)
            jitted_fun = functools.partial(_evaluate_compiled, problem.rhs, args, n)
            for name, fun in (("scipy, Python rhs", problem.scipy_fun()),
                              ("scipy, jitted rhs", jitted_fun)):
                step_count = scipy.integrate.solve_ivp(fun, (0.0, scipy_horizon), problem.y0,
                                                       method=method).t.size - 1
                call = functools.partial(scipy.integrate.solve_ivp, fun, (0.0, scipy_horizon),
                                         problem.y0, method=method, t_eval=short_eval)
                per_step[name] = median_seconds(call, max(1, repeats // 2)) / step_count * 1e9

            # plain RK4 making as many evaluations as our run
            rk4_steps = max(1, nfev // 4)
            rk4_work = tuple(np.zeros(n) for _ in range(5))
            h = horizon / rk4_steps
            rk4_fixed(problem.rhs, args, problem.y0, 0.0, h, 10, rk4_work)
            call = functools.partial(rk4_fixed, problem.rhs, args, problem.y0, 0.0, h,
                                     rk4_steps, rk4_work)
            seconds = median_seconds(call, repeats)
            row = {"problem": label, "method": method, "steps": steps, "nfev": nfev,
                   "ns_per_step": per_step,
                   "ns_per_evaluation_ours": per_step["linked"] * steps / nfev,
                   "ns_per_evaluation_rk4": seconds / (4 * rk4_steps) * 1e9}
            rows.append(row)
            print(f"{label} {method}: {steps} steps, {nfev} evaluations over {horizon:g} s; "
                  f"ns per evaluation: ours {row['ns_per_evaluation_ours']:.0f}, "
                  f"RK4 loop {row['ns_per_evaluation_rk4']:.0f}", flush=True)
            for name, value in per_step.items():
                print(f"    {name:28s} {value:10.0f} ns/step", flush=True)
    return rows


if __name__ == "__main__":
    sys.path[:0] = [ROOT, TESTS]
    which = sys.argv[1:] or ["compile", "runtime"]
    results = {}
    if "compile" in which:
        results["compile"] = {f"{design} / {method}": times
                              for (design, method), times in bench_compile().items()}
    if "runtime" in which:
        results["runtime"] = bench_runtime()
    os.makedirs(os.path.dirname(RESULTS), exist_ok=True)
    with open(RESULTS, "w") as handle:
        json.dump(results, handle, indent=1)
    print(f"written to {RESULTS}")
