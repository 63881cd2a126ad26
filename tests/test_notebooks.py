"""Every notebook runs top to bottom (short horizons: CONTROLKIT_QUICK=1)."""

import json
from pathlib import Path

import matplotlib.pyplot as plt
import pytest

NOTEBOOKS = sorted((Path(__file__).parent.parent / "notebooks").glob("*.ipynb"))


def test_there_are_eight_notebooks():
    assert len(NOTEBOOKS) == 8


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
