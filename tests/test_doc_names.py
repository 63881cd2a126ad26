"""The docs name only what exists: every ``controlkit.xxx.yyy`` that the pages, the README and
the notebooks mention imports (a module) or is found on one (a function, a class, a constant).

Getting started once sent readers to ``controlkit.diagrams`` and ``controlkit.scenarios``,
modules that had moved to ``controlkit.studies``; a reader's first import failed.
"""

import importlib
import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: ``controlkit.`` and dotted identifiers, not inside a path or a longer name
DOTTED = re.compile(r"(?<![\w./-])controlkit(?:\.[A-Za-z_]\w*)+")


def _texts():
    """``{file: text}`` of the pages (docs/**/*.md), the README and every notebook's cells."""
    pages = [p for p in (ROOT / "docs").rglob("*.md") if "_build" not in p.parts]
    texts = {p.relative_to(ROOT).as_posix(): p.read_text() for p in pages + [ROOT / "README.md"]}
    for notebook in sorted((ROOT / "notebooks").glob("*.ipynb")):
        cells = json.loads(notebook.read_text())["cells"]
        texts[notebook.relative_to(ROOT).as_posix()] = "\n".join(
            "".join(cell["source"]) for cell in cells)
    return texts


def mentioned():
    """``{dotted name: [files that mention it]}``."""
    found = {}
    for name, text in _texts().items():
        for match in DOTTED.finditer(text):
            found.setdefault(match.group(0), []).append(name)
    return {name: sorted(set(files)) for name, files in sorted(found.items())}


def resolve(dotted):
    """The object a dotted name names: the longest importable module, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            found = importlib.import_module(".".join(parts[:cut]))
        except ModuleNotFoundError as error:
            if error.name != ".".join(parts[:cut]) and not ".".join(parts[:cut]).startswith(
                    f"{error.name}."):
                raise  # the module exists but imports something missing: say so
            continue
        for attribute in parts[cut:]:
            found = getattr(found, attribute)
        return found
    raise ModuleNotFoundError(dotted)


NAMES = mentioned()


def test_the_docs_mention_the_packages_a_reader_starts_from():
    assert len(NAMES) > 50
    for name in ("controlkit.input_output_response", "controlkit.studies.spacecraft.diagrams",
                 "controlkit.drawing.draw_block_diagram", "controlkit.plot"):
        assert name in NAMES, name


@pytest.mark.parametrize("name", list(NAMES))
def test_every_controlkit_name_the_docs_mention_exists(name):
    try:
        resolve(name)
    except (ImportError, AttributeError) as error:
        raise AssertionError(f"{name}, mentioned in {', '.join(NAMES[name])}, does not "
                             f"exist: {error}") from error


def test_a_name_that_is_gone_is_reported_with_the_files_that_mention_it():
    with pytest.raises(AttributeError, match="module 'controlkit' has no attribute "
                                             "'scenarios'"):
        resolve("controlkit.scenarios")  # moved to controlkit.studies
    with pytest.raises(AttributeError, match="draw_diagram"):
        resolve("controlkit.drawing.draw_diagram")
    assert DOTTED.findall("see `controlkit.diagrams`, not controlkit/studies or "
                          "my.controlkit.x") == ["controlkit.diagrams"]
