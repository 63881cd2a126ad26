"""The Python examples of the README and the docs run as printed.

Each page's ``python`` blocks run in order in one namespace (as a reader pastes them into one
notebook), in a temporary folder; a function a page shows from an example script of its own
(``{literalinclude}`` of a file under ``docs/`` with ``:pyobject:``) is defined where the
page shows it. Where a block shows what it prints as comment lines right after the statement
that prints (``for row in explain(loop): print(...)`` followed by
``# pendulum | compiled | ...``), the printed lines must be those; a block that ends with
``# SomeError: message`` must raise that error with that message.
"""

from __future__ import annotations

import ast
import builtins
import contextlib
import io
import linecache
import re
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])
FENCE = re.compile(r"^```python\n(.*?)^```"
                   r"|^```\{literalinclude\} (\S+)\n(?:.*?\n)*?:pyobject: (\w+)\n.*?^```",
                   re.DOTALL | re.MULTILINE)
RAISES = re.compile(r"^# (\w+(?:Error|Exception|Problem)): (.+)\Z", re.MULTILINE)


def _included(page: Path, path: str, name: str) -> str | None:
    """The source of ``name`` in an example script of the docs, else None (library code)."""
    script = (page.parent / path).resolve()
    if (ROOT / "docs") not in script.parents:
        return None
    text = script.read_text()
    node = next(n for n in ast.parse(text).body if getattr(n, "name", None) == name)
    return ast.get_source_segment(text, node) + "\n"


def python_blocks(page: Path) -> list[str]:
    blocks = []
    for code, path, name in FENCE.findall(page.read_text()):
        if path:
            code = _included(page, path, name)
        if code:
            blocks.append(code)
    return blocks


def printed_comments(block: str) -> list[str]:
    """The comment lines that follow a statement calling ``print`` (the shown output)."""
    lines = block.splitlines()
    shown = []
    for i, line in enumerate(lines):
        if "print(" in line and not line.lstrip().startswith("#"):
            j = i + 1
            while j < len(lines) and lines[j].startswith("# "):
                shown.append(lines[j][2:])
                j += 1
    return shown


def shown_value(line: str):
    """The value a comment shows after an expression (``loop.rates  # {...}``), else None."""
    _, sep, comment = line.partition("  # ")
    if not sep:
        return None
    for text in (comment.strip(), comment.split(":")[0].strip()):
        try:
            return (ast.literal_eval(text), text)
        except (ValueError, SyntaxError):
            continue
    return None


def run_showing_values(block: str, filename: str, namespace: dict) -> None:
    """Run ``block`` statement by statement; an expression's shown value must be its value
    (a number to the digits shown, anything else equal)."""
    lines = block.splitlines()
    for statement in ast.parse(block).body:
        code = compile(ast.Module([statement], []), filename, "exec")
        shown = shown_value(lines[statement.end_lineno - 1])
        if not isinstance(statement, ast.Expr) or shown is None:
            exec(code, namespace)
            continue
        value = eval(compile(ast.Expression(statement.value), filename, "eval"), namespace)
        expected, text = shown
        where = f"{filename}: {lines[statement.lineno - 1].strip()}"
        if isinstance(expected, float):
            decimals = len(text.partition(".")[2])
            assert abs(float(value) - expected) <= 0.5 * 10.0 ** -decimals, (where, value)
        else:
            assert value == expected, (where, value)


def test_the_pages_have_examples_and_the_shown_output_is_found():
    pages = {page.name: python_blocks(page) for page in PAGES}
    assert pages["README.md"] and pages["fast-blocks.md"] and pages["getting-started.md"]
    assert printed_comments(pages["fast-blocks.md"][0])[0].startswith("pendulum | compiled")


@pytest.mark.parametrize("page", [p for p in PAGES if python_blocks(p)],
                         ids=lambda p: p.name)
def test_a_pages_examples_run_and_print_what_they_show(page, tmp_path, monkeypatch):
    import matplotlib.pyplot as plt

    monkeypatch.chdir(tmp_path)
    namespace = {"__name__": f"example_{page.stem}"}
    for number, block in enumerate(python_blocks(page)):
        # as IPython does for a cell: the source is kept where inspect finds it
        filename = f"<{page.name} example {number}>"
        linecache.cache[filename] = (len(block), None, block.splitlines(True), filename)
        out = io.StringIO()
        raises = RAISES.search(block.rstrip())
        with contextlib.redirect_stdout(out):
            if raises:
                error = getattr(builtins, raises[1], Exception)
                with pytest.raises(error, match=re.escape(raises[2])):
                    exec(compile(block, filename, "exec"), namespace)
            else:
                run_showing_values(block, filename, namespace)
        plt.close("all")
        shown = printed_comments(block)
        if shown:
            assert out.getvalue().splitlines()[: len(shown)] == shown
