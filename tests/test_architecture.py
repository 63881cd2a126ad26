"""docs/architecture.md draws the package as it is: every module it names exists, every
module and package of ``controlkit/`` is named, and no module is longer than the page says.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
PACKAGE = ROOT / "controlkit"
#: The page's limit on a module's length, and the modules it names as over it.
LIMIT = int(re.search(r"Modules stay at (\d+) lines at most", PAGE.read_text())[1])


def _names(text: str) -> list[str]:
    """Module names in a line's list: ``a, b (what b does), c (+ d, e)`` -> a b c d e."""
    extra = [n for group in re.findall(r"\(\+([^)]*)\)", text) for n in group.split(",")]
    plain = re.sub(r"\([^)]*\)", "", text)
    return [n.strip().removesuffix(".py") for n in plain.split(",") + extra if n.strip()]


def drawn_tree() -> set[str]:
    """The paths the page's tree names, relative to ``controlkit/`` (``sweep/points.py``,
    ``engines/fast/rk/``)."""
    block = re.search(r"^```\n(controlkit/\n.*?)^```", PAGE.read_text(), re.M | re.S)[1]
    paths: set[str] = set()
    parents: list[tuple[int, list[str]]] = [(0, [""])]  # (indent, folders at that level)
    last_folders = [""]
    for line in block.splitlines()[1:]:
        indent = len(line) - len(line.lstrip())
        head = re.match(r"\s*((?:[\w.]+/,?\s*)+)\s{2,}(.*)$", line)
        if head is None and re.match(r"\s*[\w.]+/\s*$", line):
            head = re.match(r"\s*([\w.]+/)()$", line.rstrip())
        if head is None:  # a module list: of the top level, or a folder's continued
            folders = last_folders if indent > parents[-1][0] else [""]
            if folders == [""]:
                parents = [(0, [""])]
            for folder in folders:
                paths.update(f"{folder}{name}.py" for name in _names(line))
            continue
        while parents and parents[-1][0] >= indent:
            parents.pop()
        base = parents[-1][1] if parents else [""]
        own = [n.strip().rstrip(",") for n in head[1].split() if n.strip().rstrip(",")]
        folders = [f"{b}{o}" for b in base for o in own]
        paths.update(folders)
        for folder in folders:
            paths.update(f"{folder}{name}.py" for name in _names(head[2]))
        parents.append((indent, folders))
        last_folders = folders
    return paths


def package_tree() -> set[str]:
    """The modules and packages of ``controlkit/`` (package ``__init__`` files aside)."""
    paths = {f"{p.relative_to(PACKAGE).as_posix()}/" for p in PACKAGE.rglob("*")
             if p.is_dir() and (p / "__init__.py").exists()}
    paths |= {p.relative_to(PACKAGE).as_posix() for p in PACKAGE.rglob("*.py")
              if p.name != "__init__.py"}
    return paths


def test_the_tree_names_what_exists_and_everything_that_exists():
    drawn, real = drawn_tree(), package_tree()
    assert len(drawn) > 60
    assert sorted(drawn - real) == [], "named on the page, not in the package"
    assert sorted(real - drawn) == [], "in the package, not on the page"


def test_modules_over_the_limit_are_the_ones_the_page_names():
    text = PAGE.read_text()
    over = {p.relative_to(PACKAGE).as_posix(): len(p.read_text().splitlines())
            for p in PACKAGE.rglob("*.py") if len(p.read_text().splitlines()) > LIMIT}
    named = dict(re.findall(r"`([\w/]+\.py)`, (\d+)\)", text))
    assert {path: str(lines) for path, lines in over.items()} == named
