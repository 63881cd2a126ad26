"""Per-step cost and first-call latency of diagrams built the python-control way.

Run from the repository root after ``pip install ".[fast]"``::

    python benchmarks/bench_user_diagrams.py          # about two minutes

The six diagrams of ``tests/user_diagrams.py`` (python-control primitives and user
functions only) and the seven of ``tests/idiom_diagrams.py`` (functions written as
python-control's examples and course notebooks write them: helpers handed ``params``,
``map(params.get, ...)``, scalar ``np.clip``, a partial, a callable object, a decorated
function, ...) are simulated (a) by ``control.input_output_response`` and (b) by the fast
engine compiled (``controlkit.simulation.simulate(..., engine="fast", compile=True)``,
warm: the module compiled by a first call). It prints how many blocks can be compiled,
microseconds per step and the ratio a/b. Then:

- new parameter values in one process: two diagrams called with five new values of a
  parameter (200 steps each), each call timed against python-control's;
- the latency of a first call (200 steps) in a fresh process, against python-control's time
  for the same call in that process:

  - new wiring: blocks seen before, wired in a way not seen before (a new module);
  - new user block: a user ``nlsys`` whose function was never compiled;
  - new parameter value: a user block compiled by an earlier process, called with a
    parameter value never used before.

The first call runs as the engine's rule decides (a short run: as Python); the column
"compile=True" is the same call asking for the compiled module (compiling it, or loading
it from the store), what a long run pays once.

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

from idiom_diagrams import DIAGRAMS as IDIOM_DIAGRAMS  # noqa: E402
from idiom_diagrams import cruise  # noqa: E402
from timing import checkout_env  # noqa: E402  (this folder's module)
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
    print(f"{'diagram':45s} {'compiled':>8s} {'(a) python-control':>19s} {'(b) fast':>9s} "
          f"{'a/b':>7s}   (per step, microseconds)")
    for name, build in {**DIAGRAMS, **IDIOM_DIAGRAMS}.items():
        loop, T, X0, U, params = build(steps=1000)
        try:
            rows = engine.explain(loop, params)
        except Exception as error:  # noqa: BLE001 - an engine that fails says so, and goes on
            print(f"{name:45s} fails: {type(error).__name__}: {str(error)[:60]}")
            continue
        compiled = sum(r.tier == "compiled" for r in rows)
        a = best(ct.input_output_response, loop, T, U, X0, params=params, repeat=1) / T.size
        loop, T, X0, U, params = build(steps=50000)
        simulate(loop, T[:10], X0=X0, U=U[..., :10], params=params, engine="fast",
                 compile=True)  # compiled once
        b = best(simulate, loop, T, X0=X0, U=U, params=params, engine="fast",
                 compile=True) / T.size
        print(f"{name:45s} {f'{compiled}/{len(rows)}':>8s} {a * 1e6:19.1f} {b * 1e6:9.3f} "
              f"{a / b:7.0f}")


def new_values():
    """Five calls of a diagram with new parameter values each, in one process."""
    from user_diagrams import tank_with_params

    print()
    for name, build, key in (("user nlsys with params", tank_with_params, "leak"),
                             ("cruise control", cruise, "kaw")):
        loop, T, X0, U, params = build(steps=200)
        simulate(loop, T, X0=X0, U=U, params=params, engine="fast", compile=True)  # once
        fast, ref = [], []
        for value in (0.5, 0.75, 1.0, 1.25, 1.75):
            values = {**params, key: value}
            fast.append(best(simulate, loop, T, X0=X0, U=U, params=values, engine="fast",
                             repeat=1))
            ref.append(best(ct.input_output_response, loop, T, U, X0, params=values,
                            repeat=1))
        print(f"new {key} value in one process, {name} (200 steps): fast "
              f"{', '.join(f'{t * 1e3:.0f}' for t in fast)} ms; python-control median "
              f"{np.median(ref) * 1e3:.0f} ms")


LATENCY = textwrap.dedent('''
    import sys, time, importlib
    sys.path[:0] = [{root!r}, {tests!r}, {tmp!r}]
    import numpy as np, control as ct
    from user_diagrams import lti_loop, tank_with_params
    from controlkit.simulation import simulate
    case = sys.argv[1]
    if case == "value":
        loop, T, X0, U, params = tank_with_params(steps=200)
        params = {{"leak": {leak!r}}}
    elif case == "wiring":
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
    t0 = time.perf_counter()
    simulate(loop, T, X0=X0, U=U, params=params, engine="fast")
    fast = time.perf_counter() - t0
    assert {{r.tier for r in engine.explain(loop, params)}} == {{"compiled"}}
    t0 = time.perf_counter()  # what a long run pays once: the module compiled (or loaded)
    simulate(loop, T, X0=X0, U=U, params=params, engine="fast", compile=True)
    compiled = time.perf_counter() - t0
    t0 = time.perf_counter()
    simulate(loop, T, X0=X0, U=U, params=params)
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
    print(f"\n{'first call, 200 steps':28s} {'fast (s)':>9s} {'compile=True (s)':>20s} "
          f"{'python-control (s)':>19s}")
    rng = np.random.default_rng()
    for case in ("wiring", "user block", "warm-up", "value"):
        module = f"user_block_{os.getpid()}_{rng.integers(1 << 30)}"
        source = USER_BLOCK.format(leak=0.1, cap=float(rng.uniform(2.0, 3.0)))
        (tmp / f"{module}.py").write_text(source)
        code = LATENCY.format(root=str(ROOT), tests=str(ROOT / "tests"), tmp=str(tmp),
                              gain=float(rng.uniform(1.0, 2.0)), module=module,
                              leak=float(rng.uniform(0.2, 0.4)))
        out = subprocess.run([sys.executable, "-c", code, case.split()[0].replace(
            "warm-up", "value")], check=True, capture_output=True, text=True,
            env=checkout_env()).stdout
        fast, compiled, ref = (float(v) for v in out.split()[-3:])
        if case != "warm-up":  # the value case after a process that compiled the block
            label = "new parameter value" if case == "value" else "new " + case
            print(f"{label:28s} {fast:9.2f} {compiled:20.2f} {ref:19.2f}")


if __name__ == "__main__":
    import tempfile

    per_step()
    new_values()
    with tempfile.TemporaryDirectory() as tmp:
        latency(Path(tmp))
