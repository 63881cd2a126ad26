"""Look at the built documentation in a real browser, offline.

Usage (after ``python -m sphinx -b html docs docs/_build/html``)::

    python docs/check_screenshots.py docs/_build/html docs/_build/screenshots

For every page this takes a 1280 x 900 screenshot with headless Chromium (Debian package
``chromium``; ``CHROMIUM=/path`` to use another binary), with background networking off,
and reads back the page's DOM after its scripts ran. It fails when a page loads a script
from the network, when a page with equations shows them unrendered (MathJax, bundled in
``_static``, turns each into an ``mjx-container``), or when a notebook page has fewer than
two figures. Open the screenshots to judge the pages by eye.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run",
         "--window-size=1280,900", "--virtual-time-budget=10000")
NETWORK_SCRIPT = re.compile(r"<script[^>]*\bsrc=[\"']?(?:https?:)?//", re.IGNORECASE)
IMG = re.compile(r"<img\b", re.IGNORECASE)
MATH = re.compile(r'class="[^"]*\bmath\b')


def find_chromium() -> str | None:
    """Path of the Chromium binary (``$CHROMIUM``, else ``chromium`` on the PATH), or None."""
    return os.environ.get("CHROMIUM") or shutil.which("chromium")


def _chromium(binary: str, *args: str) -> subprocess.CompletedProcess:
    profile = tempfile.mkdtemp(prefix="controlkit-chromium-")
    try:
        return subprocess.run([binary, *FLAGS, f"--user-data-dir={profile}", *args],
                              capture_output=True, text=True, timeout=120)
    finally:
        shutil.rmtree(profile, ignore_errors=True)


def screenshot(binary: str, page: Path, png: Path) -> Path:
    """Screenshot of ``page`` as the browser renders it, written to ``png``."""
    png.parent.mkdir(parents=True, exist_ok=True)
    _chromium(binary, f"--screenshot={png}", page.resolve().as_uri())
    if not png.exists() or png.stat().st_size < 5_000:
        raise RuntimeError(f"no screenshot of {page}")
    return png


def rendered_dom(binary: str, page: Path) -> str:
    """The page's DOM after its scripts ran (MathJax included)."""
    return _chromium(binary, "--dump-dom", page.resolve().as_uri()).stdout


def problems(html_dir, out_dir, binary: str) -> list[str]:
    """Check every page of ``html_dir`` (see the module docstring); screenshots to ``out_dir``."""
    html_dir, out_dir = Path(html_dir), Path(out_dir)
    found = []
    for page in sorted(html_dir.rglob("*.html")):
        name = page.relative_to(html_dir).as_posix()
        if name.startswith("_"):
            continue
        text = page.read_text(encoding="utf-8")
        if NETWORK_SCRIPT.search(text):
            found.append(f"{name}: loads a script from the network")
        if name.startswith("notebooks/") and len(IMG.findall(text)) < 2:
            found.append(f"{name}: fewer than two figures")
        screenshot(binary, page, out_dir / (name.replace("/", "_")[:-5] + ".png"))
        if MATH.search(text) and "mjx-container" not in rendered_dom(binary, page):
            found.append(f"{name}: equations not rendered offline")
    return found


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 2:
        print(__doc__)
        return 2
    binary = find_chromium()
    if binary is None:
        print("chromium not found: apt-get install chromium, or set CHROMIUM=/path")
        return 2
    found = problems(argv[0], argv[1], binary)
    print("\n".join(found) or f"all pages fine; screenshots in {argv[1]}")
    return 1 if found else 0


if __name__ == "__main__":
    raise SystemExit(main())
