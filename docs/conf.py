"""Sphinx configuration: ``python -m sphinx -W -b html docs docs/_build/html``."""

import os
import shutil
from pathlib import Path

from nbclient.output_widget import OutputWidget

HERE = Path(__file__).parent
project = "controlkit"
author = "the controlkit developers"
# equations: MathJax from the sphinx-mathjax-offline wheel, copied into _static, so the pages
# render their maths without a network (see the docs extra in pyproject.toml)
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax",
              "sphinx-mathjax-offline", "myst_nb"]
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_ivar = True
autodoc_member_order = "bysource"
autodoc_typehints = "none"
myst_enable_extensions = ["dollarmath"]
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
html_theme = "alabaster"
# wide enough that the notebooks' figures and code show at a readable size
html_theme_options = {"page_width": "1240px", "sidebar_width": "240px"}
# notebook cells: code and output in a font small enough for 99-character lines
html_static_path = ["_static"]
html_css_files = ["notebooks.css"]
suppress_warnings = ["mystnb.unknown_mime_type"]
# sliders are for a live kernel: their cells' output is removed from the pages, and no
# page loads the widget manager's scripts from the network
nb_ipywidgets_js = {}
# the diagram editor (notebook 7) also sends its static drawing as SVG: a page without a kernel
# shows that drawing; widgets without such a picture (sliders) are chosen as before
nb_mime_priority_overrides = [("html", "application/vnd.jupyter.widget-view+json", 45)]

# the notebooks live in ../notebooks; render copies of them, executed at the papers' horizons
# (the fast engine takes seconds) so the numbers printed on each page are the papers' ones.
# No MPLBACKEND here: the kernel keeps its inline backend, so every figure is captured.
os.environ.pop("CONTROLKIT_QUICK", None)
os.environ.pop("MPLBACKEND", None)
nb_execution_mode = os.environ.get("CONTROLKIT_DOCS_EXECUTE", "force")
nb_execution_timeout = 300
# a notebook cell that fails is a warning that carries the cell and its traceback, and -W
# makes the build fail on it (raising instead would report only the notebook's path, the
# traceback being left in a temporary log file); the other notebooks still run, so one
# build lists every broken cell
nb_execution_raise_on_error = False
nb_execution_show_tb = True
# a cell's printed lines in one box, as in Jupyter (not one box per flush of the stream)
nb_merge_streams = True
# A slider's cell (ipywidgets' interact) draws into an Output widget. nbclient, standing in for
# the browser, sends each output it collects there back to the kernel, on the socket where it
# waits for the cell's reply; on a busy machine that send can take the reply's wake-up (zmq's
# edge-triggered descriptor, jupyter/nbclient#312), and the cell waits out the whole
# nb_execution_timeout before the build goes on: 300 s lost, with nothing reported. The
# pages show no slider (those cells' output is removed) and the kernel needs no copy of what
# the widget shows, so nothing is sent back.
OutputWidget.sync_state = lambda self: None
(HERE / "notebooks").mkdir(exist_ok=True)
for notebook in sorted((HERE.parent / "notebooks").glob("*.ipynb")):
    shutil.copy(notebook, HERE / "notebooks" / notebook.name)


def _keep_constant_descriptions_whole(app, what, name, obj, options, lines):
    """Undo napoleon's reading of ``#:`` comments as ``type: description``.

    For a module constant (or a property), napoleon takes the text before the first colon of its
    comment as the constant's type ("Wheel axes v1, v2 (Table 2): the z wheel has
    failed" became "the z wheel has failed. Type: Wheel axes ..."). Our comments never
    give a type that way, so the two parts are joined again.
    """
    if what not in ("data", "attribute", "property"):
        return
    typed = [i for i, line in enumerate(lines) if line.startswith(":type: ")]
    if len(typed) != 1:
        return
    head = lines[typed[0]][len(":type: "):]
    del lines[typed[0]]
    while lines and not lines[-1].strip():
        lines.pop()
    first = next((i for i, line in enumerate(lines) if line.strip()), None)
    if first is None:
        lines.append(head)
    else:
        lines[first] = f"{head}: {lines[first].lstrip()}"


def setup(app):
    # after napoleon (priority 500), which split the comment
    app.connect("autodoc-process-docstring", _keep_constant_descriptions_whole, priority=600)
