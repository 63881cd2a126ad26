"""Sweep throughput: a robustness sweep in the caller, on 1 worker and on 2.

    python benchmarks/bench_sweep.py [--runs 48] [--horizon 2000] [--rounds 3]
                                     [--before DIR]

Each run is one spacecraft case (``without_mec``, ``mec_fixed``, ``proposed`` in turn)
over ``--horizon`` seconds with drawn model errors, through
:func:`controlkit.studies.robustness.study` (which compiles the cases' loops in the
caller before the workers start, and the workers load them). Each measurement is a fresh
process (as ``controlkit sweep`` is): the time of the ``study`` call (the warm-up, the
pool's start and the runs) and the process's wall time (imports and exit too), in the
caller (``executor="serial"``), on 1 worker process and on 2, on 1 thread and on 2 (a
study's default where numba compiles); with ``--before DIR`` another checkout measured
the same way, interleaved, each with its own store. The speed-ups are one setup's time
over another's within one round (the machine is shared: a loaded machine shifts both):
1 worker over 2, 1 thread over 2, and 2 workers over 2 threads.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

from timing import add_checkout_arguments, checkout_env, load, run_child

CASES = ["without_mec", "mec_fixed", "proposed"]
SETUPS = {"in the caller": ("serial", None), "1 worker": ("processes", 1),
          "2 workers": ("processes", 2), "1 thread": ("threads", 1),
          "2 threads": ("threads", 2)}
#: The speed-ups printed: (numerator setup, denominator setup), within one round.
RATIOS = (("1 worker", "2 workers"), ("1 thread", "2 threads"), ("2 workers", "2 threads"))


def child(samples, horizon, executor, workers):
    from controlkit.studies import robustness

    started = time.perf_counter()
    table, _ = robustness.study("spacecraft", samples=samples, seed=1, cases=CASES,
                                horizon=horizon, executor=executor, workers=workers,
                                progress=False)
    elapsed = time.perf_counter() - started
    assert (table["error"] == "").all(), table["error"].unique()
    return {"runs": len(table), "study_s": elapsed}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=48, help="runs (a multiple of 3)")
    parser.add_argument("--horizon", type=float, default=2000.0,
                        help="simulated seconds per run (a multiple of 0.1; 20 000 is the "
                             "paper's)")
    parser.add_argument("--rounds", type=int, default=3)
    add_checkout_arguments(parser)
    parser.add_argument("--child", nargs=4, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        samples, horizon, executor, workers = args.child
        print(json.dumps(child(int(samples), float(horizon), executor,
                               None if workers == "-" else int(workers))))
        return 0
    if args.runs < 3 or args.runs % 3:
        parser.error(f"--runs must be a positive multiple of 3, got {args.runs}")
    versions = {"after": (Path(args.after).resolve() if args.after else None, args.store)}
    if args.before:
        versions = {"before": (Path(args.before).resolve(), args.before_store), **versions}
    samples = args.runs // len(CASES)
    for who, (tree, store) in versions.items():  # untimed: each store holds its loops
        # compiled (a store is cold after any edit or fresh checkout of engines/ or kernels/:
        # its key holds their names, sizes and dates), so no setup pays a compile
        _, wall, _ = run_child([__file__, "--child", 1, args.horizon, "serial", "-"],
                               checkout_env(tree, store))
        print(f"# {who}: store warmed ({wall:.1f} s)", file=sys.stderr, flush=True)
    results = {}
    for _ in range(args.rounds):
        for who, (tree, store) in versions.items():
            for setup, (executor, workers) in SETUPS.items():
                out, wall, _ = run_child(
                    [__file__, "--child", samples, args.horizon, executor, workers or "-"],
                    checkout_env(tree, store))
                out.update(wall=wall, load=load())
                results.setdefault((who, setup), []).append(out)
                print(f"# {who} {setup}: {json.dumps(out)}", file=sys.stderr, flush=True)
    print(f"\n{args.runs} spacecraft runs of {args.horizon:g} s, {args.rounds} round(s): "
          f"the study call (runs/s), and the process's wall time; medians")
    print("| engine | " + " | ".join(SETUPS) + " | load |")
    print("|---|" + "---|" * len(SETUPS) + "---|")
    for who in versions:
        cells, loads = [], []
        for setup in SETUPS:
            runs = results[(who, setup)]
            loads += [r["load"] for r in runs]
            study = statistics.median(r["study_s"] for r in runs)
            wall = statistics.median(r["wall"] for r in runs)
            cells.append(f"{study:.2f} s ({args.runs / study:.1f} runs/s), wall {wall:.1f} s")
        print(f"| {who} | " + " | ".join(cells) + f" | {min(loads)}-{max(loads)} |")
    print("\nSpeed-ups of the study call (median; each round), and of the wall time (median)")
    print("| engine | " + " | ".join(f"{b} over {a}" for a, b in RATIOS) + " |")
    print("|---|" + "---|" * len(RATIOS))
    for who in versions:
        cells = []
        for slow, fast in RATIOS:
            pairs = list(zip(results[(who, slow)], results[(who, fast)], strict=True))
            study = [a["study_s"] / b["study_s"] for a, b in pairs]
            wall = statistics.median(a["wall"] / b["wall"] for a, b in pairs)
            cells.append(f"{statistics.median(study):.2f}x "
                         f"({', '.join(f'{x:.2f}' for x in study)}), wall {wall:.2f}x")
        print(f"| {who} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
