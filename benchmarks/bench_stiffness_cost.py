"""What the stiffness test costs a step: the compiled integrator on van der Pol, ns per
accepted step.

Run ``python benchmarks/bench_stiffness_cost.py`` (a minute, plus half a minute to compile
the step machine into an empty store) on a commit with the test and on one without (a
worktree at 1ca2f5e, with this folder's ``compiled_rk.py`` adapted to its API) and
compare the medians; the machine is shared, so run the two back to back and more than
once.
"""

import statistics
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent.parent / "tests"))
import rk_problems as P  # noqa: E402  (the tests' problems)
from compiled_rk import solve_ivp  # noqa: E402  (this folder's module)


def ns_per_step(method, horizon=20_000.0, repeats=7):
    """The median time of an accepted step over ``repeats`` runs to ``horizon``."""
    args = (np.array([2.0]), *P.no_table())
    solve_ivp(P.van_der_pol, (0.0, 10.0), [2.0, 0.0], method=method, args=args)  # compile
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        result = solve_ivp(P.van_der_pol, (0.0, horizon), [2.0, 0.0], method=method,
                              args=args)
        times.append((time.perf_counter() - start) / result["n_accepted"] * 1e9)
    return result["n_accepted"], statistics.median(times)


if __name__ == "__main__":
    for method in ("RK45", "DOP853"):
        steps, ns = ns_per_step(method)
        print(f"{method}: {steps} accepted steps, {ns:.0f} ns a step (median of 7)")
