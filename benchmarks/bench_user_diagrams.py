"""Per-step cost and first-call latency of diagrams built the python-control way.

Run from the repository root after ``pip install ".[fast]"``::

    python benchmarks/bench_user_diagrams.py          # about a minute

The six diagrams of ``tests/user_diagrams.py`` (python-control primitives and user
functions only) are simulated (a) by ``control.input_output_response`` and (b) by the fast
engine (``controlkit.simulation.simulate(..., engine="fast")``, warm caches). It prints
microseconds per step and the ratio a/b, then the latency of a first call (200 steps) in a
fresh process, against python-control's time for the same call in that process:

- new wiring: blocks seen before (their kernels cached on disk), wired in a way not seen
  before (the loop is generated and compiled);
- new user block: a user ``nlsys`` whose function was never compiled (its kernel is
  compiled).

A loop not compiled yet runs as Python for short runs
(``controlkit.engines.fast.loader.COMPILE_AFTER_STEPS``); the column "+ loop compiled" is
what compiling it costs on top, paid by the first long run.

The machine is shared: compare the ratios, measured in the same run.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import control as ct
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from user_diagrams import DIAGRAMS  # noqa: E402

from controlkit.engines import fast as engine  # noqa: E402
from controlkit.simulation import simulate  # noqa: E402


def best(fn, *args, repeat=3, **kwargs):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn(*args, **kwargs)
        times.append(time.perf_counter() - t0)
    return min(times)


def per_step():
    print(f"{'diagram':28s} {'(a) python-control':>19s} {'(b) fast':>9s} {'a/b':>7s}"
          "   (per step, microseconds)")
    for name, build in DIAGRAMS.items():
        loop, T, X0, U, params = build(steps=1000)
        assert {r.tier for r in engine.explain(loop, params)} == {"compiled"}
        a = best(ct.input_output_response, loop, T, U, X0, params=params, repeat=1) / T.size
        loop, T, X0, U, params = build(steps=50000)
        simulate(loop, T[:10], X0, U[..., :10], params=params, engine="fast")  # warm
        b = best(simulate, loop, T, X0, U, params=params, engine="fast") / T.size
        print(f"{name:28s} {a * 1e6:19.1f} {b * 1e6:9.3f} {a / b:7.0f}")


LATENCY = textwrap.dedent('''
    import sys, time, importlib
    sys.path[:0] = [{root!r}, {tests!r}, {tmp!r}]
    import numpy as np, control as ct
    from user_diagrams import lti_loop, tank_with_params
    from controlkit.simulation import simulate
    case = sys.argv[1]
    if case == "wiring":
        loop, T, X0, U, params = lti_loop(steps=200)
        # the same blocks, the output scaled by a gain never used before: a new loop
        loop = ct.interconnect(loop.syslist, inplist=["r", "d"], inputs=["r", "d"],
                               outlist=[("plant", "y", {gain!r}), "u"], outputs=["ys", "u"])
    else:
        user = importlib.import_module({module!r})
        loop, T, X0, U, params = tank_with_params(steps=200)
        plant = ct.nlsys(user.tank, None, inputs="q", outputs="level",
                         states="level", dt=T[1], params={{"area": 1.5}}, name="tank")
        loop = ct.interconnect([plant, loop.syslist[1]], inputs="level_ref",
                               outputs=["level", "q"])
    from controlkit.engines import fast as engine
    from controlkit.engines.fast import loader
    t0 = time.perf_counter()
    simulate(loop, T, X0, U, params=params, engine="fast")
    fast = time.perf_counter() - t0
    assert {{r.tier for r in engine.explain(loop, params)}} == {{"compiled"}}
    loader.COMPILE_AFTER_STEPS = 0  # what a long run pays on top: the loop compiled
    t0 = time.perf_counter()
    simulate(loop, T, X0, U, params=params, engine="fast")
    compiled = time.perf_counter() - t0
    t0 = time.perf_counter()
    simulate(loop, T, X0, U, params=params)
    ref = time.perf_counter() - t0
    print(fast, compiled, ref)
''')

USER_BLOCK = textwrap.dedent('''
    import numpy as np

    def tank(t, x, u, params):
        area = params["area"]
        leak = params.get("leak", {leak!r})
        inflow = min(max(u[0], 0.0), {cap!r})
        return x + 0.05 * (inflow - leak * np.sqrt(abs(x[0]))) / area
''')


def latency(tmp: Path):
    print(f"\n{'first call, 200 steps':28s} {'fast (s)':>9s} {'+ loop compiled (s)':>20s} "
          f"{'python-control (s)':>19s}")
    rng = np.random.default_rng()
    for case in ("wiring", "user block"):
        module = f"user_block_{os.getpid()}_{rng.integers(1 << 30)}"
        source = USER_BLOCK.format(leak=0.1, cap=float(rng.uniform(2.0, 3.0)))
        (tmp / f"{module}.py").write_text(source)
        code = LATENCY.format(root=str(ROOT), tests=str(ROOT / "tests"), tmp=str(tmp),
                              gain=float(rng.uniform(1.0, 2.0)), module=module)
        out = subprocess.run([sys.executable, "-c", code, case.split()[0]], check=True,
                             capture_output=True, text=True, env=os.environ).stdout
        fast, compiled, ref = (float(v) for v in out.split()[-3:])
        print(f"{'new ' + case:28s} {fast:9.2f} {compiled:20.2f} {ref:19.2f}")


if __name__ == "__main__":
    import tempfile

    per_step()
    with tempfile.TemporaryDirectory() as tmp:
        latency(Path(tmp))
