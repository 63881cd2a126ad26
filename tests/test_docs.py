"""The documentation builds as the README says, on a fresh clone, offline, with figures.

The pages are built once per test run, by the README's own command, in a copy of the source
tree (what a clone holds: the files git tracks or would track) and a virtual environment that
has only what ``pip install ".[docs]"`` brings, so a notebook import that only the test
environment provides fails here as it would for a reader. The notebooks are executed at the
papers' horizons (the fast engine takes seconds), so the numbers on the pages are the ones
their text discusses.
"""

import importlib.util
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest
from clones import clean_environment, fresh_clone, new_venv

ROOT = Path(__file__).parent.parent
_spec = importlib.util.spec_from_file_location("check_screenshots",
                                               ROOT / "docs" / "check_screenshots.py")
check = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(check)
#: The README's documentation command, e.g. ``pip install ".[docs]" && python -m sphinx ...``.
README_DOCS_COMMAND = re.search(r"`(pip install \"\.\[docs\]\" && python -m sphinx [^`]+)`",
                                (ROOT / "README.md").read_text()).group(1)


@pytest.fixture(scope="module")
def html(tmp_path_factory):
    """The pages, built by the README's command in a fresh clone and a fresh environment."""
    work = tmp_path_factory.mktemp("fresh")
    clone = fresh_clone(work / "controlkit")
    env = clean_environment(new_venv(work / "venv"))
    # pip's compiling of every installed file to bytecode ahead of time is not what is
    # tested (Python compiles what it imports, as it goes); here it only costs time
    env["PIP_NO_COMPILE"] = "1"
    start = time.perf_counter()
    result = subprocess.run(["bash", "-c", README_DOCS_COMMAND], cwd=clone, env=env,
                            capture_output=True, text=True)
    seconds = time.perf_counter() - start
    # the command's failure shows the failing cell and its traceback (docs/conf.py): report
    # the warnings and the tail of the log, where sphinx summarises
    log = result.stdout + result.stderr
    warnings = [line for line in log.splitlines()
                if ("WARNING" in line and "IPKernelApp" not in line) or "ERROR" in line]
    assert result.returncode == 0, "\n".join(warnings + ["...", log[-6000:]])
    print(f"README docs command on a fresh clone: {seconds:.0f} s")
    return clone / "docs" / "_build" / "html"


def test_a_failing_notebook_cell_shows_its_error_in_the_build_output(tmp_path):
    # docs/conf.py as it is, over one notebook whose second cell fails: the build must fail
    # and print that cell and its exception, not only the notebook's path
    import nbformat

    (tmp_path / "docs").mkdir()
    (tmp_path / "notebooks").mkdir()
    shutil.copy(ROOT / "docs" / "conf.py", tmp_path / "docs" / "conf.py")
    (tmp_path / "docs" / "index.md").write_text("# t\n\n```{toctree}\nnotebooks/broken\n```\n")
    notebook = nbformat.v4.new_notebook()
    notebook.cells = [nbformat.v4.new_markdown_cell("# broken"),
                      nbformat.v4.new_code_cell("x = 1"),
                      nbformat.v4.new_code_cell("import a_module_nobody_installed")]
    nbformat.write(notebook, tmp_path / "notebooks" / "broken.ipynb")
    result = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-b", "html",
                             str(tmp_path / "docs"), str(tmp_path / "html")],
                            capture_output=True, text=True)
    log = re.sub(r"\x1b\[[0-9;]*m", "", result.stdout + result.stderr)  # no colour codes
    assert result.returncode != 0
    assert "import a_module_nobody_installed" in log
    assert "ModuleNotFoundError: No module named 'a_module_nobody_installed'" in log


def test_docs_build_with_warnings_as_errors(html):
    for page in ("index", "getting-started", "api", "theory/frit", "theory/errata",
                 "notebooks/03_online_frit_tuning"):
        assert (html / f"{page}.html").exists(), page
    api = (html / "api.html").read_text()
    assert "frit_tuner" in api and "adaptive_smc" in api and "draw_block_diagram" in api


def test_constants_read_as_written_in_the_api_page(html):
    # napoleon read the text before a comment's first colon as a type ("Type: Wheel axes
    # v1, v2 (Table 2)" under "the z wheel has failed"); docs/conf.py joins them again
    api = (html / "api.html").read_text()
    assert 'field-odd">Type<' not in api
    text = re.sub(r"\s+", " ", re.sub(r"<[^>]+>", " ", api))
    assert "Wheel axes v1 , v2 (Table 2): the z wheel has failed." in text


def test_every_notebook_page_shows_its_figures(html):
    pages = sorted((html / "notebooks").glob("*.html"))
    assert len(pages) == len(list((ROOT / "notebooks").glob("*.ipynb")))
    for page in pages:
        figures = check.IMG.findall(page.read_text())
        assert len(figures) >= 2, (page.name, len(figures))


def test_notebook_pages_print_the_papers_horizon_numbers(html):
    text = (html / "notebooks" / "03_online_frit_tuning.html").read_text()
    worst = dict(re.findall(r"(proposed(?:_literal)?)\s+worst error over the last half "
                            r"([0-9.]+) deg", text))
    # at 20 000 s the degrees reading meets 0.05 deg and the literal one misses it
    assert float(worst["proposed"]) < 0.05 < float(worst["proposed_literal"])


def test_no_page_loads_a_script_from_the_network(html):
    pages = list(html.rglob("*.html"))
    assert pages
    offenders = [p.name for p in pages if check.NETWORK_SCRIPT.search(p.read_text())]
    assert offenders == []
    math_page = (html / "theory" / "mec.html").read_text()
    assert '_static/mathjax/tex-chtml.js"' in math_page
    assert (html / "_static" / "mathjax" / "tex-chtml.js").exists()


def test_network_script_pattern_catches_cdn_links():
    assert check.NETWORK_SCRIPT.search('<script defer src="https://cdn.example/x.js">')
    assert check.NETWORK_SCRIPT.search("<script src='//cdn.example/x.js'>")
    assert not check.NETWORK_SCRIPT.search('<script src="_static/mathjax/tex-chtml.js">')


@pytest.mark.skipif(check.find_chromium() is None, reason="chromium not installed")
def test_pages_render_in_a_real_browser_offline(html, tmp_path):
    binary = check.find_chromium()
    for page in ("theory/mec", "notebooks/03_online_frit_tuning"):
        png = check.screenshot(binary, html / f"{page}.html", tmp_path / f"{page}.png")
        assert png.stat().st_size > 20_000
    dom = check.rendered_dom(binary, html / "theory" / "mec.html")
    assert "mjx-container" in dom  # MathJax typeset the equations from _static


#: For every code block of a page: its width and the room for text, and each line too wide for
#: that room, measured in the block's own font (a line that wraps, with ``white-space:
#: pre-wrap``, is one of those)
_CODE_FIT = """() => {
  const measure = document.createElement('canvas').getContext('2d');
  return [...document.querySelectorAll('div.body pre')].map(pre => {
    const style = getComputedStyle(pre);
    measure.font = style.fontSize + ' ' + style.fontFamily;
    const room = pre.clientWidth - parseFloat(style.paddingLeft)
                 - parseFloat(style.paddingRight);
    return {scrolls: pre.scrollWidth > pre.clientWidth + 1,
            right: pre.getBoundingClientRect().right,
            wide: pre.textContent.split('\\n').filter(
              line => measure.measureText(line).width > room)};
  });
}"""


@pytest.mark.skipif(check.find_chromium() is None, reason="chromium not installed")
def test_no_code_block_is_cut_off_in_a_1280_px_window(html):
    from playwright.sync_api import sync_playwright

    pages = [p for p in html.rglob("*.html") if not {"_static", "_sources"} & set(p.parts)]
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=check.find_chromium(),
                                             args=list(check.FLAGS[:4]))
        window = browser.new_page(viewport={"width": 1280, "height": 900})
        blocks = 0
        for page in pages:
            window.goto(page.resolve().as_uri())
            for block in window.evaluate(_CODE_FIT):
                blocks += 1
                # nothing behind a scroll bar or past the window's edge, and a line of the
                # repository's 99 characters fits; only longer ones (a shell command) wrap
                assert not block["scrolls"] and block["right"] <= 1280, page.name
                assert all(len(line) > 99 for line in block["wide"]), (page.name, block["wide"])
        browser.close()
    assert blocks > 100
