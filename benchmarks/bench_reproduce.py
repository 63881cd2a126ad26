"""Wall time of ``controlkit reproduce all`` (warm caches), figures serial vs in workers.

Run: ``python benchmarks/bench_reproduce.py [--repeats N] [--baseline DIR]`` (about a
minute).

Each measurement is a fresh interpreter, as a user's command is, so the import of
controlkit, python-control and matplotlib and the interpreter's exit are included. In the
same run, interleaved:

- **(a) serial**: ``reproduce(workers=0)``: each study's figures are drawn in the calling
  process after its simulations (how ``controlkit reproduce`` worked before), ending as
  the command does (:func:`controlkit.cli.main` leaves the objects to the operating system);
- **(b) workers**: ``python -m controlkit reproduce --out DIR``, the command itself: the
  figures are drawn by worker processes while the next study is simulated;
- **(h) floor**: ``python -m controlkit --help``: importing the command and exiting, the
  floor of any command;
- **(i) import**: ``import controlkit.cli`` alone (its exit collects every object);
- with ``--baseline DIR``, **(base)**: the command (b) run from another checkout of
  controlkit (e.g. ``git worktree add /tmp/main main``), with the same disk caches.

Two untimed runs of each first fill the store (the loops the engine's rule compiles,
and a baseline's background compiles). Ratios are the results to quote: the machine may
be shared, and everything is measured under the same load; the load average is printed
with them.
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
SERIAL = ("import gc, io, sys; from controlkit.studies.reproduce import reproduce; "
          "reproduce(out=sys.argv[1], log=io.StringIO(), workers=0); gc.freeze()")


def wall(args, root=ROOT) -> float:
    env = {**os.environ, "PYTHONPATH": f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"}
    started = time.perf_counter()
    subprocess.run([sys.executable, *args], check=True, env=env, cwd=root,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--baseline", type=Path,
                        help="another controlkit checkout whose command is timed alongside")
    args = parser.parse_args(argv)
    out = tempfile.mkdtemp(prefix="controlkit-bench-")
    command = ["-m", "controlkit", "reproduce", "--out", out]
    runs = {"(a) serial": lambda: wall(["-c", SERIAL, out]),
            "(b) workers": lambda: wall(command),
            "(h) floor": lambda: wall(["-m", "controlkit", "--help"]),
            "(i) import": lambda: wall(["-c", "import controlkit.cli"])}
    if args.baseline:
        runs["(base)"] = lambda: wall(command, root=args.baseline.resolve())
        wall(command, root=args.baseline.resolve())  # warm
    wall(command)  # fill the store
    wall(command)  # ... and what an older engine compiled in the background
    times = {name: [] for name in runs}
    loads = []
    for _ in range(args.repeats):
        for name, run in runs.items():
            times[name].append(run())
        loads.append(os.getloadavg()[0])
    print(f"controlkit reproduce all, warm, {os.cpu_count()} CPUs, best of {args.repeats} "
          f"(median in brackets), seconds; load average {min(loads):.2f}-{max(loads):.2f}")
    for name, values in times.items():
        values.sort()
        print(f"  {name:13s} {values[0]:6.2f}  ({values[len(values) // 2]:.2f})")
    best = {name: min(values) for name, values in times.items()}
    print(f"  ratio b/a     {best['(b) workers'] / best['(a) serial']:6.2f}")
    if args.baseline:
        print(f"  ratio b/base  {best['(b) workers'] / best['(base)']:6.2f}")


if __name__ == "__main__":
    main()
