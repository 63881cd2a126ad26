"""Sphinx configuration: ``python -m sphinx -W -b html docs docs/_build/html``."""

import os
import shutil
from pathlib import Path

HERE = Path(__file__).parent
project = "controlkit"
author = "the controlkit developers"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinx.ext.mathjax", "myst_nb"]
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_ivar = True
autodoc_member_order = "bysource"
autodoc_typehints = "none"
myst_enable_extensions = ["dollarmath"]
exclude_patterns = ["_build", "**.ipynb_checkpoints"]
html_theme = "alabaster"
suppress_warnings = ["mystnb.unknown_mime_type"]

# the notebooks live in ../notebooks; render copies of them, executed on short horizons
os.environ.setdefault("CONTROLKIT_QUICK", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
nb_execution_mode = os.environ.get("CONTROLKIT_DOCS_EXECUTE", "force")
nb_execution_timeout = 300
nb_execution_raise_on_error = True
(HERE / "notebooks").mkdir(exist_ok=True)
for notebook in sorted((HERE.parent / "notebooks").glob("*.ipynb")):
    shutil.copy(notebook, HERE / "notebooks" / notebook.name)
