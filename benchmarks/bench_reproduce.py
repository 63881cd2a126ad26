"""Wall time of ``controlkit reproduce all`` (warm caches), figures serial vs in workers.

Run: ``python benchmarks/bench_reproduce.py [--repeats N]`` (about a minute).

Each measurement is a fresh interpreter, as a user's command is, so the import of
controlkit, python-control and matplotlib is included. In the same run, interleaved:

- **(a) serial**: ``reproduce(workers=0)``: each study's figures are drawn in the calling
  process after its simulations (how ``controlkit reproduce`` worked before);
- **(b) workers**: ``reproduce()``: the figures are drawn by worker processes while the
  next study is simulated (the default);
- **(i) import**: ``import controlkit.cli`` alone, the floor of any command.

One untimed run first fills the numba cache. The ratio b/a is the result to quote: the
machine may be shared, and both are measured under the same load.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUN = ("import io, sys; from controlkit.cli import reproduce; "
       "reproduce(out=sys.argv[1], log=io.StringIO(), workers={workers})")


def wall(code: str, *args: str) -> float:
    env = {**os.environ, "PYTHONPATH": f"{ROOT}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", code, *args], check=True, env=env, cwd=ROOT)
    return time.perf_counter() - started


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args(argv)
    out = tempfile.mkdtemp(prefix="controlkit-bench-")
    wall(RUN.format(workers="None"), out)  # warm the numba cache
    times = {"(a) serial": [], "(b) workers": [], "(i) import": []}
    for _ in range(args.repeats):
        times["(a) serial"].append(wall(RUN.format(workers=0), out))
        times["(b) workers"].append(wall(RUN.format(workers="None"), out))
        times["(i) import"].append(wall("import controlkit.cli"))
    print(f"controlkit reproduce all, warm, {os.cpu_count()} CPUs, best of {args.repeats} "
          "(median in brackets), seconds")
    for name, values in times.items():
        values.sort()
        print(f"  {name:13s} {values[0]:6.2f}  ({values[len(values) // 2]:.2f})")
    a, b = min(times["(a) serial"]), min(times["(b) workers"])
    print(f"  ratio b/a     {b / a:6.2f}")


if __name__ == "__main__":
    main()
