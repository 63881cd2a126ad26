"""The README's Python snippets run as written, and its Quick start matches .ci/run."""

import re
from pathlib import Path

import matplotlib.pyplot as plt
import pytest

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
SNIPPETS = re.findall(r"^```python\n(.*?)^```", README, re.M | re.S)


def test_readme_has_snippets():
    assert len(SNIPPETS) >= 2


@pytest.mark.parametrize("number", range(len(SNIPPETS)))
def test_snippet_runs_as_written(number):
    try:
        exec(compile(SNIPPETS[number], f"README.md snippet {number}", "exec"), {})
    finally:
        plt.close("all")


def test_quick_start_has_two_commands_and_ci_runs_the_second():
    block = re.search(r"^## Quick start.*?^```\n(.*?)^```", README, re.M | re.S).group(1)
    commands = [line for line in block.splitlines() if line.strip()]
    assert len(commands) == 2 and "controlkit reproduce" in commands[0]
    assert commands[1] in (ROOT / ".ci" / "run").read_text()
