"""The diagram editor in a real browser: Voila serves a notebook, headless Chromium edits it.

- Notebook 7: open Fig. 3, run it (requirement met), delete the MEC block, drag a wire
  from the controller's output to the linearized plant's input, run again and read from
  the page that the pointing error misses the 0.05 deg requirement.
- Notebook 0's sampled-data loop (its own cells, up to the loop, then an editor): give
  the set point a step at t = 1 s, delete the junction and undo the deletion, save the
  diagram, reload the page, load the file, run, and read the speed's overshoot from the
  page; it is the engine's.

Screenshots are written to ``$CONTROLKIT_WIDGET_SHOTS`` (default: the test's temporary
folder).

Needs Debian's ``chromium`` (``CHROMIUM=/path`` for another binary), Playwright's Python
package (its own browsers are not used) and Voila; skipped, saying which is missing,
without them.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
NOTEBOOK = ROOT / "notebooks" / "07_rewire_with_the_mouse.ipynb"
CHROMIUM = os.environ.get("CHROMIUM") or shutil.which("chromium")
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync"]
MISSING = [name for name, found in (
    ("chromium (apt-get install chromium)", CHROMIUM),
    ("playwright (pip install playwright)", importlib.util.find_spec("playwright")),
    ("voila (pip install voila)", importlib.util.find_spec("voila")),
    ("anywidget (pip install anywidget)", importlib.util.find_spec("anywidget"))) if not found]

pytestmark = pytest.mark.skipif(bool(MISSING), reason="the browser test needs "
                                + ", ".join(MISSING))


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def voila(request, tmp_path):
    """Voila serving a notebook (notebook 7, or the test's ``notebook`` parameter) on
    127.0.0.1; its URL."""
    notebook = getattr(request, "param", NOTEBOOK)
    if callable(notebook):
        notebook = notebook(tmp_path)
    port = _free_port()
    log = open(tmp_path / "voila.log", "w")  # noqa: SIM115 - closed below
    server = subprocess.Popen(
        [sys.executable, "-m", "voila", "--no-browser", f"--port={port}",
         "--Voila.ip=127.0.0.1", "--VoilaConfiguration.show_tracebacks=True", str(notebook)],
        stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                socket.create_connection(("127.0.0.1", port), 0.5).close()
                break
            except OSError:
                if server.poll() is not None:
                    break
                time.sleep(0.2)
        else:
            pytest.fail("voila did not start in 60 s")
        if server.poll() is not None:
            pytest.fail("voila stopped: " + (tmp_path / "voila.log").read_text()[-2000:])
        yield f"http://127.0.0.1:{port}/"
    finally:
        server.terminate()
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()
        log.close()


def _centre(locator):
    box = locator.bounding_box()
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def test_rewire_fig3_with_the_mouse_misses_the_requirement(voila, tmp_path):
    from playwright.sync_api import sync_playwright

    shots = Path(os.environ.get("CONTROLKIT_WIDGET_SHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1150})
            errors = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.goto(voila, wait_until="commit", timeout=60_000)
            editor = page.locator(".ck-editor").first
            editor.wait_for(timeout=90_000)
            node = editor.locator(".react-flow__node[data-id='mec']")
            node.wait_for(timeout=30_000)
            assert editor.locator("[data-testid=problems]").inner_text() == (
                "wiring: no problems")

            # Fig. 3 as the paper draws it meets the requirement
            editor.locator("[data-testid=run]").click()
            measure = editor.locator("[data-testid=measure]")
            measure.wait_for(timeout=60_000)
            assert measure.inner_text().endswith("requirement met")
            time.sleep(0.3)  # the chart's last frame
            editor.screenshot(path=str(shots / "fig3_before.png"))

            # delete the model error compensator
            node.click()
            editor.locator("[data-testid=delete-block]").click()
            node.wait_for(state="detached", timeout=10_000)
            problems = editor.locator("[data-testid=problems]")
            # the kernel checks the new wiring and answers: wait for its words (on a busy
            # machine the deletion is drawn well before they arrive)
            unconnected = ("unconnected input: linearizer.mu of block 'linearizer' has no "
                           "driver (python-control reads it as 0)")
            page.wait_for_function("([el, t]) => el.innerText === t",
                                   arg=[problems.element_handle(), unconnected],
                                   timeout=30_000)
            assert problems.inner_text() == unconnected

            # drag a wire from the controller's mu_n to the linearizer's mu
            source = editor.locator(".react-flow__handle[data-port='controller.mu_n']")
            target = editor.locator(".react-flow__handle[data-port='linearizer.mu']")
            (sx, sy), (tx, ty) = _centre(source), _centre(target)
            page.mouse.move(sx, sy)
            page.mouse.down()
            page.mouse.move((sx + tx) / 2, (sy + ty) / 2, steps=6)
            page.mouse.move(tx, ty, steps=6)
            page.mouse.up()
            page.wait_for_function(
                "el => el.innerText === 'wiring: no problems'",
                arg=problems.element_handle(), timeout=30_000)

            # run again: the requirement is missed, and the page says by how much
            editor.locator("[data-testid=run]").click()
            page.wait_for_function("el => el.innerText.endsWith('requirement missed')",
                                   arg=measure.element_handle(), timeout=60_000)
            text = measure.inner_text()
            worst = float(re.search(r"worst over the last half ([0-9.]+) deg", text).group(1))
            assert worst > 0.05 and "> 0.05 deg" in text
            assert editor.locator("[data-testid=status]").inner_text().startswith(
                "ran 200,000 steps in ")
            time.sleep(0.3)
            editor.screenshot(path=str(shots / "fig3_without_mec.png"))
            assert errors == []
        finally:
            browser.close()
    for name in ("fig3_before.png", "fig3_without_mec.png"):
        assert (shots / name).stat().st_size > 30_000


# ---------------------------------------------------------------------- notebook 0's loop

FIRST_LOOP = ROOT / "notebooks" / "00_first_loop.ipynb"


def first_loop_notebook(folder):
    """Notebook 0's code cells up to its sampled-data loop, then an editor on that loop."""
    import nbformat

    cells = nbformat.read(FIRST_LOOP, as_version=4).cells
    code = [c.source for c in cells if c.cell_type == "code"]
    last = next(i for i, source in enumerate(code)
                if "sampled = controlkit.interconnect(" in source)
    notebook = nbformat.v4.new_notebook()
    notebook.cells = [nbformat.v4.new_code_cell(source) for source in code[:last + 1]]
    notebook.cells.append(nbformat.v4.new_code_cell(
        "from controlkit.widget import DiagramEditor\n\n"
        "editor = DiagramEditor(sampled, horizon=2.0, scopes=['motor.w', 'pi.v'])\n"
        "editor"))
    path = folder / "first_loop_in_the_editor.ipynb"
    nbformat.write(notebook, path)
    return path


def _wait_text(page, selector, text, timeout=20_000):
    page.wait_for_function("([s, t]) => { const e = document.querySelector(s); "
                           "return e && e.innerText.includes(t); }",
                           arg=[selector, text], timeout=timeout)


@pytest.mark.parametrize("voila", [first_loop_notebook], indirect=True)
def test_notebook_0s_sampled_loop_step_undo_save_reload_run(voila, tmp_path):
    import json

    import numpy as np
    from playwright.sync_api import sync_playwright

    shots = Path(os.environ.get("CONTROLKIT_WIDGET_SHOTS", tmp_path))
    shots.mkdir(parents=True, exist_ok=True)
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        try:
            page = browser.new_page(viewport={"width": 1400, "height": 1000},
                                    accept_downloads=True)
            errors = []
            page.on("pageerror", lambda error: errors.append(str(error)))
            page.goto(voila, wait_until="commit", timeout=60_000)
            editor = page.locator(".ck-editor").first
            editor.wait_for(timeout=120_000)
            junction = editor.locator(".react-flow__node[data-id='error']")
            junction.wait_for(timeout=30_000)
            # python-control refuses this loop; the editor opens it, rates as the drawing
            assert editor.locator("[data-testid=problems]").inner_text() == (
                "wiring: no problems")
            assert editor.locator(".react-flow__node[data-id='pi'] .ck-sub").inner_text() == (
                "dt = 0.02")
            assert editor.locator(".react-flow__node[data-id='motor'] .ck-sub").inner_text() \
                == "continuous"

            # a step of the set point at t = 1 s
            editor.locator(".react-flow__node[data-id='in:error:w_ref']").click()
            inspector = editor.locator("[data-testid=input-inspector]")
            inspector.locator("[data-testid=source-kind]").select_option("step")
            inspector.locator("input[data-field=value]").fill("1")
            inspector.locator("input[data-field=time]").fill("1")
            inspector.locator("[data-testid=apply-source]").click()
            _wait_text(page, "[data-input=w_ref]", "step 1 at 1 s")

            # delete the junction: w_ref stays, unattached; Ctrl+Z brings the junction back
            junction.click()
            page.keyboard.press("Delete")
            junction.wait_for(state="detached", timeout=10_000)
            editor.locator(".react-flow__node[data-id='in:free:w_ref']").wait_for(
                timeout=10_000)
            editor.screenshot(path=str(shots / "first_loop_deleted.png"))
            page.keyboard.press("Control+z")
            junction.wait_for(timeout=10_000)
            editor.locator(".react-flow__node[data-id='in:error:w_ref']").wait_for(
                timeout=10_000)
            _wait_text(page, "[data-input=w_ref]", "step 1 at 1 s")

            # save: the browser receives the diagram file
            with page.expect_download(timeout=20_000) as download:
                editor.locator("[data-testid=save]").click()
            saved = tmp_path / download.value.suggested_filename
            download.value.save_as(saved)
            data = json.loads(saved.read_text())
            assert data["format"] == "controlkit.widget/2"
            assert data["setup"]["sources"]["w_ref"] == {
                "kind": "step", "value": 1.0, "time": 1.0, "initial": 0.0}

            # reload the page (a new kernel, the loop as opened), then load the file
            page.reload(wait_until="commit")
            editor = page.locator(".ck-editor").first
            editor.wait_for(timeout=120_000)
            editor.locator(".react-flow__node[data-id='error']").wait_for(timeout=30_000)
            _wait_text(page, "[data-input=w_ref]", "0")
            page.set_input_files("[data-testid=load-file]", str(saved))
            _wait_text(page, "[data-input=w_ref]", "step 1 at 1 s")

            # run, and read the result from the page
            editor.locator("[data-testid=run]").click()
            readout = editor.locator("[data-trace='motor.w']")
            readout.wait_for(timeout=60_000)
            assert editor.locator("[data-testid=status]").inner_text().startswith(
                "ran 2,000 steps in ")
            text = readout.inner_text()
            final, peak, when = (float(v) for v in re.findall(
                r"final ([-0-9.e]+),\s*largest ([-0-9.e]+) at t = ([-0-9.e]+) s", text)[0])
            editor.locator("[data-testid=scope-chart]").scroll_into_view_if_needed()
            time.sleep(0.3)  # the chart's last frame
            editor.screenshot(path=str(shots / "first_loop_step_at_1s.png"))
            assert errors == []
        finally:
            browser.close()

    from test_widget import sampled_speed_loop

    import controlkit

    T = np.linspace(0.0, 2.0, 2001)
    expected = controlkit.input_output_response(sampled_speed_loop(), T,
                                                np.where(T >= 1.0, 1.0, 0.0)).outputs[0]
    k = int(np.argmax(expected))
    assert abs(peak - expected[k]) < 1e-5 and abs(when - T[k]) < 1e-9
    assert abs(final - expected[-1]) < 1e-5
    assert 1.0005 < peak < 1.002 and 1.0 < when < 2.0  # the sampled PI's small overshoot
    for name in ("first_loop_deleted.png", "first_loop_step_at_1s.png"):
        assert (shots / name).stat().st_size > 30_000


def test_a_label_naming_an_object_s_own_member_is_drawn_as_its_text():
    # the editor's TeX looked macros up with `name in GREEK`, true for every object's
    # inherited members: a shared file's label "$\constructor$" showed "function Object()
    # { [native code] }" (the front end's source, run in the browser the editor runs in)
    from playwright.sync_api import sync_playwright

    source = (ROOT / "widget-src" / "src" / "tex.js").read_text().replace("export ", "")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=FLAGS)
        try:
            page = browser.new_page()
            shown = page.evaluate(f"() => {{ {source}; return [texToHtml('$\\\\constructor$'), "
                                  f"texToHtml('$\\\\toString$'), texToHtml('$\\\\alpha$')]; }}")
        finally:
            browser.close()
    assert "native code" not in "".join(shown)
    assert "\\constructor" in shown[0] and "\\toString" in shown[1] and "α" in shown[2]
