"""Sweep throughput: runs per second on 1 and 2 workers, and a 200-run study's wall time.

    python benchmarks/bench_sweep.py [--runs 24] [--study-samples 67]

Each run is one 20 000 s spacecraft case (``without_mec``, ``mec_fixed``, ``proposed`` in
turn) with drawn model errors, through :func:`controlkit.studies.robustness.study`.
Ratios are measured in one process, one after the other, so a loaded machine shifts both;
the loops are compiled and cached once before anything is timed.
"""

from __future__ import annotations

import argparse
import os
import time

from controlkit.studies import robustness
from controlkit.studies.spacecraft import robustness as sc_robustness

CASES = ["without_mec", "mec_fixed", "proposed"]


def timed(samples, workers, executor="processes"):
    started = time.perf_counter()
    table, _ = robustness.study("spacecraft", samples=samples, seed=1, cases=CASES,
                                           executor=executor, workers=workers,
                                           progress=False)
    elapsed = time.perf_counter() - started
    assert (table["error"] == "").all(), table["error"].unique()
    return len(table), elapsed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=120,
                        help="runs per throughput measurement (a multiple of 3)")
    parser.add_argument("--study-samples", type=int, default=67,
                        help="draws of the timed study (x 3 cases; 67 -> 201 runs)")
    args = parser.parse_args(argv)
    sc_robustness.warm(CASES)
    samples = max(1, args.runs // len(CASES))
    print(f"machine: {os.cpu_count()} CPUs; {samples * len(CASES)} runs of 20 000 s each")
    n, serial = timed(samples, None, executor="serial")
    print(f"(s) in this process     : {n / serial:6.2f} runs/s  ({serial:6.1f} s)")
    rates = {}
    for workers in (1, 2):
        n, elapsed = timed(samples, workers)
        rates[workers] = n / elapsed
        print(f"({workers}) {workers} worker process(es): {rates[workers]:6.2f} runs/s  "
              f"({elapsed:6.1f} s, includes starting the workers)")
    print(f"speed-up 2 workers / 1 worker: {rates[2] / rates[1]:.2f}x")
    n, elapsed = timed(args.study_samples, 2)
    print(f"study of {n} runs on 2 workers: {elapsed:.1f} s")


if __name__ == "__main__":
    main()
