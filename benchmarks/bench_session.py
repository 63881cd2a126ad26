"""A notebook session, timed call by call against python-control (issue 21's benchmark).

python-control's cruise-control PI loop (``benchmarks/cruise.py``, 20 000 time points) is
called 7 times with a new ``kp`` through ``params=``, then rewired with a low-pass filter on
the measured speed and called 4 more times, each call with ``controlkit.input_output_response``
and with ``control.input_output_response``: the ratio of the two times, and the largest
difference of their outputs. Both the discrete loop (dt = 0.1 s: the vehicle sampled under
zero-order hold) and the continuous one (RK45) are run, each in a fresh process (so the
first call of each wiring pays what a notebook's first call pays), with the disk cache as
it is (``warm``: a user's second session) or emptied (``cold``: a first session, which
also compiles the engine's driver once).

``--notebook`` plays the session as a person types it: ``CONTROLKIT_WARMUP=1`` (what a
Jupyter kernel gets by itself: numba's start runs in a thread from ``import controlkit``
on, see :mod:`controlkit._warmup`) and a pause of ``--pause`` seconds (default 2) after
the imports' cell and after the cell that builds the loop. Without it the calls follow
each other at once, as in a script.

Run: ``python benchmarks/bench_session.py [--cold] [--notebook] [--variant discrete|continuous]``.
The machine is shared: compare the ratios, measured in the same process.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).parent

KPS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
REWIRED_KPS = (0.45, 0.55, 0.65, 0.75)


def session(variant: str, pause: float = 0.0) -> list[dict]:
    """The 11 calls of one session in this process: per call, both times and the ratio.

    ``pause``: seconds between the imports, the building of the loop and its first call.
    """
    import control as ct

    import controlkit

    time.sleep(pause)
    from cruise import loop

    dt = 0.1 if variant == "discrete" else None
    rows = []
    for label, filtered, kps in (("wiring 1", False, KPS), ("rewired", True, REWIRED_KPS)):
        sys_, T, X0, U = loop(dt, filtered=filtered)
        time.sleep(pause)
        for i, kp in enumerate(kps):
            params = {"kp": kp}
            start = time.perf_counter()
            ours = controlkit.input_output_response(sys_, T, U, X0, params=params)
            t_ours = time.perf_counter() - start
            start = time.perf_counter()
            ref = ct.input_output_response(sys_, T, U, X0, params=params)
            t_ref = time.perf_counter() - start
            rows.append({"call": f"{label}, call {i + 1}", "kp": kp, "ours_s": t_ours,
                         "python_control_s": t_ref, "ratio": t_ref / t_ours,
                         "max_difference": float(np.abs(ours.y - ref.y).max())})
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cold", action="store_true",
                        help="empty caches: the engine and the loops compile from nothing")
    parser.add_argument("--variant", choices=["discrete", "continuous"], action="append")
    parser.add_argument("--notebook", action="store_true",
                        help="numba's start in a thread (CONTROLKIT_WARMUP=1) and a pause "
                             "between the cells, as a person works")
    parser.add_argument("--pause", type=float, default=2.0,
                        help="seconds between the cells with --notebook (default 2)")
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.pause < 0:
        parser.error(f"--pause must be >= 0 seconds, got {args.pause}")
    if args.child:
        print(json.dumps(session(args.child, args.pause if args.notebook else 0.0)))
        return 0
    for variant in args.variant or ["discrete", "continuous"]:
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(HERE),
                                                           os.environ.get("PYTHONPATH", "")]))
        if args.cold:
            folder = tempfile.mkdtemp(prefix="controlkit-cold-")
            env.update(CONTROLKIT_CACHE_DIR=folder + "/engine",
                       NUMBA_CACHE_DIR=folder + "/numba")
        env["CONTROLKIT_WARMUP"] = "1" if args.notebook else "0"
        child = [sys.executable, __file__, "--child", variant, "--pause", str(args.pause)]
        out = subprocess.run(child + (["--notebook"] if args.notebook else []), env=env,
                             capture_output=True, text=True, check=True).stdout
        rows = json.loads(out.strip().splitlines()[-1])
        how = f", a notebook ({args.pause:g} s between cells)" if args.notebook else ""
        print(f"\n{variant} loop, {'cold' if args.cold else 'warm'} cache{how} "
              f"(20 000 points per call)")
        print(f"{'call':<22}{'ours':>10}{'python-control':>16}{'ratio':>9}{'max diff':>11}")
        for r in rows:
            print(f"{r['call']:<22}{r['ours_s']:>9.3f}s{r['python_control_s']:>15.3f}s"
                  f"{r['ratio']:>8.0f}x{r['max_difference']:>11.1e}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
