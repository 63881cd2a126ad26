"""A notebook session, timed call by call against python-control (issue 21's benchmark).

python-control's cruise-control PI loop (``benchmarks/cruise.py``, 20 000 time points) is
called 7 times with a new ``kp`` through ``params=``, then rewired with a low-pass filter on
the measured speed and called 4 more times, each call with ``controlkit.input_output_response``
and with ``control.input_output_response``: the ratio of the two times, the largest
difference of their outputs, and how ours ran (``engine_mode``: as Python or compiled).
Both the discrete loop (dt = 0.1 s: the vehicle sampled under zero-order hold) and the
continuous one (RK45) are run (``--variant short-functions``: instead a continuous loop of
one-line user functions, ``benchmarks/short_functions.py``, rewired with a filter), each
in a fresh process (so the first call of each wiring
pays what a notebook's first call pays), with the store as it is (``warm``: a user's
second session, the wirings' modules compiled by an earlier session if the engine's rule
compiled them, or ``--compile`` did) or emptied (``--cold``: a first session).

``--compile`` passes ``compile=True`` to every call (the diagram compiled when first run,
as a person asks for a long study); without it the engine's rule decides.
``--notebook`` plays the session as a person types it: a pause of ``--pause`` seconds
(default 2) after the imports' cell and after the cell that builds the loop. (An older
engine, given by ``--before``, then also gets ``CONTROLKIT_WARMUP=1``: its warm-up
thread, which a Jupyter kernel started by itself.) Without it the calls follow each other
at once, as in a script.

``--before DIR`` times another checkout of controlkit beside this one, one session after
the other for ``--rounds`` rounds, each with its own store (``--store``,
``--before-store``).

Run: ``python benchmarks/bench_session.py [--cold] [--notebook] [--compile]
[--variant discrete|continuous|short-functions] [--before DIR] [--rounds N]``. The
machine is shared: compare the ratios, measured in the same process.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from timing import add_checkout_arguments, checkout_env, load, run_child

KPS = (0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
REWIRED_KPS = (0.45, 0.55, 0.65, 0.75)


def session(variant: str, pause: float = 0.0, compile=None) -> list[dict]:
    """The 11 calls of one session in this process: per call, both times and the ratio.

    ``pause``: seconds between the imports, the building of the loop and its first call.
    """
    import inspect

    import control as ct

    import controlkit

    options = {}
    if "compile" in inspect.signature(controlkit.input_output_response).parameters:
        options["compile"] = compile
    time.sleep(pause)
    if variant == "short-functions":
        from short_functions import loop
    else:
        from cruise import loop

    dt = 0.1 if variant == "discrete" else None
    rows = []
    for label, filtered, kps in (("wiring 1", False, KPS), ("rewired", True, REWIRED_KPS)):
        sys_, T, X0, U = loop(dt, filtered=filtered)
        time.sleep(pause)
        for i, kp in enumerate(kps):
            params = {"kp": kp}
            start = time.perf_counter()
            ours = controlkit.input_output_response(sys_, T, U, X0, params=params, **options)
            t_ours = time.perf_counter() - start
            start = time.perf_counter()
            ref = ct.input_output_response(sys_, T, U, X0, params=params)
            t_ref = time.perf_counter() - start
            rows.append({"call": f"{label}, call {i + 1}", "kp": kp, "ours_s": t_ours,
                         "python_control_s": t_ref, "ratio": t_ref / t_ours,
                         "mode": getattr(ours, "engine_mode", "?"),
                         "max_difference": float(np.abs(ours.y - ref.y).max())})
    return rows


def _times(ratio) -> str:
    return f"{ratio:.1f}x" if ratio < 10 else f"{ratio:.0f}x"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cold", action="store_true",
                        help="empty stores: a first session, nothing compiled")
    parser.add_argument("--variant", choices=["discrete", "continuous", "short-functions"],
                        action="append")
    parser.add_argument("--compile", action="store_true",
                        help="compile=True on every call (default: the engine's rule)")
    parser.add_argument("--notebook", action="store_true",
                        help="a pause between the cells, as a person works")
    parser.add_argument("--pause", type=float, default=2.0,
                        help="seconds between the cells with --notebook (default 2)")
    add_checkout_arguments(parser)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--child", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.pause < 0:
        parser.error(f"--pause must be >= 0 seconds, got {args.pause}")
    if args.child:
        print(json.dumps(session(args.child, args.pause if args.notebook else 0.0,
                                 True if args.compile else None)))
        return 0
    versions = {"after": (Path(args.after).resolve() if args.after else None, args.store)}
    if args.before:
        versions = {"before": (Path(args.before).resolve(), args.before_store), **versions}
    for variant in args.variant or ["discrete", "continuous"]:
        results = {}
        for _ in range(args.rounds):
            for who, (tree, store) in versions.items():
                cold = tempfile.TemporaryDirectory(prefix="controlkit-cold-")
                extra = {}
                if args.cold:
                    Path(cold.name, "numba").mkdir()
                    store, extra["NUMBA_CACHE_DIR"] = Path(cold.name, "store"), Path(
                        cold.name, "numba")
                if args.notebook and who == "before":
                    extra["CONTROLKIT_WARMUP"] = "1"  # what its Jupyter kernel got
                child = [__file__, "--child", variant, "--pause", str(args.pause)]
                child += ["--notebook"] if args.notebook else []
                child += ["--compile"] if args.compile else []
                rows, _, _ = run_child(child, checkout_env(tree, store, **extra))
                cold.cleanup()
                results.setdefault(who, []).append((rows, load()))
        how = f", a notebook ({args.pause:g} s between cells)" if args.notebook else ""
        asked = ", compile=True" if args.compile else ""
        print(f"\n{variant} loop, {'cold' if args.cold else 'warm'} store{how}{asked} "
              f"(20 000 points per call); ours / python-control, ratio, how ours ran")
        print("| call | " + " | ".join(f"{who} (round {i + 1}, load {runs[i][1]})"
                                       for who, runs in results.items()
                                       for i in range(len(runs))) + " |")
        columns = [rows for runs in results.values() for rows, _ in runs]
        print("|---|" + "---|" * len(columns))
        for i, first in enumerate(columns[0]):
            cells = [f"{rows[i]['ours_s']:.3f} s / {rows[i]['python_control_s']:.3f} s, "
                     f"{_times(rows[i]['ratio'])}, {rows[i]['mode']}" for rows in columns]
            print(f"| {first['call']} | " + " | ".join(cells) + " |")
        diff = max(r["max_difference"] for rows in columns for r in rows)
        print(f"largest difference of the outputs: {diff:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
