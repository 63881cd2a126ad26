"""The differential fuzzer over many seeds: random diagrams in python-control's idiom run by
``control.input_output_response`` and by ``controlkit.input_output_response``, with the
counts of how they compared (issue 33, item 6).

    python benchmarks/fuzz.py --count 1000 --seed 0
    python benchmarks/fuzz.py --count 1 --seed 25 --show      # one case, described

Prints the number of diagrams, how many answered equally, how many differed and why, how
many raised the same error as python-control (and with the same message), how many raised
another one (or answered where python-control raised), how many python-control let
diverge where controlkit refused (by design), how many killed their process (judged in
child processes, 50 seeds each, so the run goes on); then every seed that was not equal,
with its diagram and call, so that a reader can reproduce it with ``--show``. The diagrams and
the comparison are tests/fuzz_diagrams.py's (the test suite runs a fixed set of seeds).
"""

from __future__ import annotations

import argparse
import collections
import re
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

import fuzz_diagrams as fuzz  # noqa: E402


def _reason(verdict: str, detail: str) -> str:
    """What kind of difference a verdict's detail is: the exception types and who raised
    them, or the arrays that differ, without numbers and messages."""
    types = re.findall(r"\b([A-Z]\w*(?:Error|Exception|Interrupt))\(", detail)
    if verdict == "same error":
        return detail.split(",")[0] + (", another message" if "message" in detail else "")
    if verdict == "other error":
        if detail.startswith("controlkit raises"):
            return f"controlkit raises {types[0]}, python-control answers"
        theirs = "answers" if detail.endswith("controlkit answers") else types[-1]
        return f"python-control raises {types[0]}, controlkit {theirs}"
    if verdict == "crashed":
        return detail.split(" (")[0]
    detail = re.sub(r"\d+(\.\d+)?(e[-+]?\d+)?", "N", detail)
    return re.sub(r"\(tolerance N\)", "", detail)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--count", type=int, default=200, help="number of diagrams")
    parser.add_argument("--seed", type=int, default=0, help="first seed")
    parser.add_argument("--hazards", type=float, default=0.15,
                        help="share of blocks drawn from the hazard templates (0 to 1)")
    parser.add_argument("--show", action="store_true", help="describe every case run")
    parser.add_argument("--limit", type=int, default=300,
                        help="seconds a case may take before it is counted as too long")
    args = parser.parse_args(argv)
    verdicts, reasons, messages = collections.Counter(), collections.Counter(), 0
    kinds, fell_back, not_equal = collections.Counter(), 0, []
    started = time.perf_counter()
    end = args.seed + args.count
    for first in range(args.seed, end, 50):  # judged in child processes, 50 at a time
        judged = fuzz.judged_apart(first, min(50, end - first), args.hazards, args.limit)
        for seed, verdict in sorted(judged.items()):
            case = fuzz.make_case(seed, hazard_rate=args.hazards)
            verdicts[verdict.verdict] += 1
            kinds[case.kind] += 1
            fell_back += verdict.fell_back
            if verdict.verdict == "same error" and "message" not in verdict.detail:
                messages += 1
            if verdict.verdict != "equal":
                reasons[(verdict.verdict, _reason(verdict.verdict, verdict.detail))] += 1
                not_equal.append(f"  {verdict.verdict}: {verdict.detail}\n"
                                 f"    {case.describe()}")
            if args.show:
                print(f"{case.describe()}\n  -> {verdict.verdict} {verdict.detail}")
        print(f"... {min(first + 50, end) - args.seed} diagrams, "
              f"{time.perf_counter() - started:.0f} s", file=sys.stderr, flush=True)
    seconds = time.perf_counter() - started
    print(f"diagrams: {args.count} (seeds {args.seed}..{args.seed + args.count - 1}; "
          + ", ".join(f"{kinds[k]} {k}" for k in fuzz.KINDS) + f") in {seconds:.0f} s")
    print(f"equal: {verdicts['equal']}")
    print(f"differing: {verdicts['differ']}")
    print(f"errors that match python-control's: {verdicts['same error']} "
          f"({messages} with the same message)")
    print(f"errors that don't: {verdicts['other error']}")
    print(f"diverged (python-control returns non-finite numbers, controlkit refuses them): "
          f"{verdicts['diverged']}")
    print(f"runs where a block fell back from the fast engine (warning): {fell_back}")
    print(f"crashed (the process died): {verdicts['crashed']}")
    print(f"too long to compare (over {args.limit} s): {verdicts['too long']}")
    if reasons:
        print("why, by kind:")
        for (verdict, reason), count in reasons.most_common():
            print(f"  {count:4d}  {verdict}: {reason}")
        print("cases:")
        print("\n".join(not_equal))
    return 0


if __name__ == "__main__":
    sys.exit(main())
