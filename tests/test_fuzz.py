"""The differential fuzzer (issue 33, item 6): random diagrams in python-control's idiom,
run by python-control and by the drop-in, must answer alike.

tests/fuzz_diagrams.py draws the diagrams and judges the answers. The default run checks
a fixed set of seeds (about a minute once the templates are compiled); ``-m slow`` checks a
thousand more, and ``python benchmarks/fuzz.py --count 1000`` prints the counts. A seed
that fails names its diagram and call: ``python benchmarks/fuzz.py --count 1 --seed S
--show`` runs it again.
"""

import re
import sys
from pathlib import Path

import numpy as np
import pytest
from fuzz_diagrams import (
    CONTROLLERS,
    HAZARD_CONTROLLERS,
    HAZARD_PLANTS,
    KINDS,
    PLANTS,
    Run,
    compare,
    judged_apart,
    make_case,
)

#: The seeds of the default run.
SEEDS = range(60)
#: The slow run: a thousand more, a hundred per test.
MORE = range(60, 1060, 100)
#: What the drop-in may answer: python-control's numbers, python-control's exception, or
#: a refusal of the non-finite numbers python-control lets through.
ACCEPTED = ("equal", "same error", "diverged")
#: Seconds a case may take (each takes well under one once its templates are compiled):
#: beyond, a run that never ends is stopped and its seed fails as "too long"
LIMIT = 300


@pytest.fixture(scope="module")
def default_verdicts():
    # judged in one child process: a crash of compiled code fails its seed, not the session
    return judged_apart(SEEDS.start, len(SEEDS), limit=LIMIT)


@pytest.mark.parametrize("seed", SEEDS)
def test_a_random_diagram_answers_as_python_control(seed, default_verdicts):
    verdict = default_verdicts[seed]
    assert verdict.verdict in ACCEPTED, \
        f"{make_case(seed).describe()}\n{verdict.verdict}: {verdict.detail}"


@pytest.mark.slow
@pytest.mark.parametrize("first", MORE)
def test_a_thousand_more_random_diagrams_answer_as_python_control(first):
    failed = [f"{make_case(seed).describe()}\n  {verdict.verdict}: {verdict.detail}"
              for seed, verdict in judged_apart(first, 100, limit=LIMIT).items()
              if verdict.verdict not in ACCEPTED]
    assert not failed, f"{len(failed)} of 100:\n" + "\n".join(failed)


#: What the child runs instead of fuzz_diagrams.py: its judging of seed 1 dies as compiled
#: code reading far outside an array does (SIGSEGV); the other seeds are judged as usual.
CRASHING_CHILD = """
import os, signal, sys
sys.path.insert(0, {tests!r})
import fuzz_diagrams
compare = fuzz_diagrams.compare
fuzz_diagrams.compare = lambda case: (
    os.kill(os.getpid(), signal.SIGSEGV) if case.seed == 1 else compare(case))
a = sys.argv  # this script, fuzz_diagrams.py, first, count, results, hazard rate, limit
fuzz_diagrams._judge_into(int(a[2]), int(a[3]), a[4], float(a[5]), int(a[6]))
"""


def test_a_crash_of_the_process_is_the_verdict_of_its_seed_and_the_next_seeds_go_on(
        tmp_path, monkeypatch):
    import fuzz_diagrams

    child = tmp_path / "crashing_child.py"
    child.write_text(CRASHING_CHILD.format(tests=str(Path(__file__).parent)))
    python = tmp_path / "python"
    python.write_text(f'#!/bin/sh\nexec "{sys.executable}" "{child}" "$@"\n')
    python.chmod(0o755)
    monkeypatch.setattr(fuzz_diagrams.sys, "executable", str(python))
    verdicts = judged_apart(0, 3)
    assert sorted(verdicts) == [0, 1, 2]
    assert verdicts[1].verdict == "crashed" and "killed by SIGSEGV" in verdicts[1].detail
    assert verdicts[0].verdict not in ("crashed", "too long")
    assert verdicts[2].verdict not in ("crashed", "too long")


def test_the_default_seeds_cover_every_kind_structure_and_most_templates():
    cases = [make_case(seed) for seed in SEEDS]
    assert {c.kind for c in cases} == set(KINDS)
    assert {c.structure for c in cases} == {"loop", "chain", "parallel", "lone"}
    used = {block.split("=", 1)[1].removesuffix(" (sizes unknown)")
            for c in cases for block in c.blocks}
    templates = set(PLANTS) | set(CONTROLLERS) | set(HAZARD_PLANTS) | set(HAZARD_CONTROLLERS)
    assert len(used & templates) >= 0.8 * len(templates), sorted(templates - used)


def test_a_seed_draws_the_same_diagram_and_call_every_time():
    first, again = make_case(7), make_case(7)
    assert first.describe() == again.describe()
    for key, value in first.arguments.items():
        np.testing.assert_array_equal(np.asarray(value, dtype=object),
                                      np.asarray(again.arguments[key], dtype=object))


def _one_discrete_case():
    seed = next(s for s in SEEDS if make_case(s).kind == "discrete"
                and compare(make_case(s)).verdict == "equal")
    return make_case(seed)


def test_the_comparison_sees_a_difference_beyond_the_tolerance(monkeypatch):
    import fuzz_diagrams

    case = _one_discrete_case()
    reference = fuzz_diagrams.reference(case).response

    def nudged(case_):
        response = fuzz_diagrams.reference(case_).response
        response.y[..., -1] += 1e-10 * max(1.0, np.abs(reference.y).max())
        return Run(response=response)

    monkeypatch.setattr(fuzz_diagrams, "ours", nudged)
    verdict = compare(case)
    assert verdict.verdict == "differ"
    assert re.search(r"outputs \S+e-10 apart \(tolerance 1e-12\)", verdict.detail)


def test_the_comparison_sees_an_error_python_control_does_not_raise(monkeypatch):
    import fuzz_diagrams

    case = _one_discrete_case()
    monkeypatch.setattr(fuzz_diagrams, "ours", lambda case_: Run(error=IndexError("x")))
    verdict = compare(case)
    assert verdict.verdict == "other error"
    assert verdict.detail == "controlkit raises IndexError('x'), python-control answers"
