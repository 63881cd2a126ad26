"""The diagram editor in a real browser: Voila serves notebook 7, headless Chromium edits it.

Open Fig. 3, run it (requirement met), delete the MEC block, drag a wire from the
controller's output to the linearized plant's input, run again and read from the page
that the pointing error misses the 0.05 deg requirement. Screenshots before and after the
edit are written to ``$CONTROLKIT_WIDGET_SHOTS`` (default: the test's temporary folder).

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
def voila(tmp_path):
    """Voila serving notebook 7 on 127.0.0.1; its URL."""
    port = _free_port()
    log = open(tmp_path / "voila.log", "w")  # noqa: SIM115 - closed below
    server = subprocess.Popen(
        [sys.executable, "-m", "voila", "--no-browser", f"--port={port}",
         "--Voila.ip=127.0.0.1", "--VoilaConfiguration.show_tracebacks=True", str(NOTEBOOK)],
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
            assert problems.inner_text() == ("unconnected input: linearizer.mu of block "
                                             "'linearizer' has no driver (python-control "
                                             "reads it as 0)")

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
                arg=problems.element_handle(), timeout=10_000)

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
