"""Every notebook runs top to bottom, worked solutions included (short horizons:
CONTROLKIT_QUICK=1; under the ``slow`` marker, as tests/test_docs.py runs them all at the
papers' horizons), and ends with exercises whose solutions are folded away."""

import json
import re
from pathlib import Path

import matplotlib.pyplot as plt
import pytest

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


def test_the_course_starts_with_a_first_loop_and_has_nine_notebooks_and_their_sequels():
    # a sequel to notebook n is numbered nb ("02b_..."), and sorts right after it
    numbers = [p.name.split("_")[0] for p in NOTEBOOKS]
    assert [n for n in numbers if n.isdigit()] == [f"{i:02d}" for i in range(9)]
    for n in numbers:
        assert n[:2].isdigit() and n[2:] in ("", "b", "c"), n
        if n[2:]:
            assert numbers.index(n) > numbers.index(n[:2]), n
    assert NOTEBOOKS[0].name == "00_first_loop.ipynb"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_ends_with_exercises_and_folded_worked_solutions(path):
    cells = json.loads(path.read_text())["cells"]
    start = next(i for i, c in enumerate(cells)
                 if c["cell_type"] == "markdown" and "".join(c["source"]).startswith(
                     "## Exercises"))
    listing = "".join(cells[start]["source"])
    exercises = re.findall(r"^(\d+)\. ", listing, re.M)
    assert 2 <= len(exercises) <= 4 and exercises == [str(i + 1) for i in range(len(exercises))]
    solutions = cells[start + 1:]
    assert len(solutions) == len(exercises)  # one per exercise, and nothing after them
    for number, cell in enumerate(solutions, 1):
        source = "".join(cell["source"])
        assert cell["cell_type"] == "code" and source.startswith(f"# Solution {number}\n")
        # folded in Jupyter (source and output) and on the documentation pages
        assert cell["metadata"]["jupyter"] == {"source_hidden": True, "outputs_hidden": True}
        assert "hide-cell" in cell["metadata"]["tags"]
        assert "assert " in source  # a worked solution checks its answer


@pytest.mark.slow  # the documentation's build runs every notebook at the papers' horizons in
# a fresh environment and fails on a failing cell (tests/test_docs.py); this in-process run
# at short horizons is the quick check while writing one (``-m slow``)
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_runs_without_error(path, monkeypatch, tmp_path):
    monkeypatch.setenv("CONTROLKIT_QUICK", "1")
    monkeypatch.chdir(tmp_path)
    cells = json.loads(path.read_text())["cells"]
    assert cells[0]["cell_type"] == "markdown" and "What this notebook teaches" in "".join(
        cells[0]["source"])
    namespace = {"__name__": "__main__"}
    for number, cell in enumerate(cells):
        if cell["cell_type"] != "code":
            continue
        source = "".join(cell["source"])
        try:
            exec(compile(source, f"{path.name}[cell {number}]", "exec"), namespace)
        except Exception as error:  # name the cell that broke
            raise AssertionError(f"{path.name}, cell {number} failed: {error!r}") from error
        finally:
            plt.close("all")
    assert any("draw_block_diagram" in "".join(c["source"]) for c in cells)
