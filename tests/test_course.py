"""A lecturer goes from a clone to a running class by the README's course section.

The fast tests read the section's commands and check each against what it relies on: the
Python version pyproject.toml requires, the ``course`` extra it installs (which must bring
Jupyter Lab and everything the notebooks import, directly or through the controlkit modules
they use), the ``controlkit`` subcommands it names and the folder Jupyter opens. The notebooks
themselves run in tests/test_notebooks.py. The slow one (``pytest -m slow``) follows the
section in a fresh clone and a fresh virtual environment, installs ``.[course]`` from the
package index, and executes every notebook in a Jupyter kernel of that environment.
"""

import ast
import importlib.metadata
import json
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from clones import clean_environment, fresh_clone
from packaging.markers import default_environment
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parent.parent
README = (ROOT / "README.md").read_text()
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
SECTION = re.search(r"^## Teaching the course from a clone\n(.*?)(?=^## )", README,
                    re.M | re.S).group(1)
#: The section's shell commands, in order
COMMANDS = [line.strip() for line in re.search(r"^```\n(.*?)^```", SECTION, re.M | re.S)
            .group(1).splitlines() if line.strip() and not line.strip().startswith("#")]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))
#: Imported by controlkit only for what no notebook of the course does by default: a sweep
#: on a Dask cluster (``executor="dask"``, the ``cluster`` extra)
NOT_FOR_THE_COURSE = {"dask", "distributed"}


def test_the_section_goes_from_git_clone_to_jupyter_lab_on_the_notebooks():
    assert COMMANDS[0].startswith("git clone ") and COMMANDS[0].split()[-1] == "controlkit"
    assert COMMANDS[1] == "cd controlkit"
    assert COMMANDS[2:4] == ["python3 -m venv .venv", ". .venv/bin/activate"]
    assert [c for c in COMMANDS if c.startswith("pip ")] == ['pip install ".[course]"']
    assert COMMANDS[-1] == "jupyter lab notebooks/" and NOTEBOOKS
    # anything else is a controlkit command that exists (say `controlkit warmup`)
    from controlkit.cli import main

    for command in COMMANDS[5:-1]:
        words = command.split()
        assert words[0] == "controlkit", command
        with pytest.raises(SystemExit) as done:
            main(words[1:] + ["--help"])
        assert done.value.code == 0, command


def test_the_section_states_the_python_version_pyproject_requires():
    required = PYPROJECT["project"]["requires-python"]
    assert required.startswith(">=")
    assert f"Python {required[2:]}\nor newer" in SECTION or f"Python {required[2:]} or newer" \
        in SECTION


def test_the_quick_start_is_left_as_it_was():
    block = re.search(r"^## Quick start.*?^```\n(.*?)^```", README, re.M | re.S).group(1)
    assert block.splitlines() == ['pip install ".[fast]" && controlkit reproduce',
                                  'pip install ".[test]" && python -m pytest -q']


def _closure(requirements):
    """The distributions ``requirements`` install, with theirs, as normalised names."""
    environment = default_environment()
    seen, todo = set(), [Requirement(r) for r in requirements]
    while todo:
        requirement = todo.pop()
        name = re.sub(r"[-_.]+", "-", requirement.name).lower()
        if requirement.marker and not requirement.marker.evaluate({**environment, "extra": ""}):
            continue
        if name in seen:
            continue
        seen.add(name)
        try:
            needs = importlib.metadata.requires(name) or []
        except importlib.metadata.PackageNotFoundError:
            continue  # not installed here: its own needs cannot be read (none are counted)
        for need in map(Requirement, needs):
            extras = set(requirement.extras)
            if need.marker is None or any(need.marker.evaluate({**environment, "extra": e})
                                          for e in extras | {""}):
                todo.append(need)
    return seen


def _imports(source, module_name=None):
    """``(absolute modules, controlkit modules)`` that ``source`` imports, at any depth
    (an import inside a function counts: it runs when the notebook calls that function);
    ``module_name`` is the module whose source it is, to read relative imports."""
    absolute, own = set(), set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: ``module`` is a module of that package
                base = module_name.split(".")[: len(module_name.split(".")) - node.level]
                module = ".".join(base + ([node.module] if node.module else []))
                names = [module] + [f"{module}.{alias.name}" for alias in node.names]
            else:
                names = [node.module] + [f"{node.module}.{alias.name}" for alias in node.names]
        else:
            continue
        for name in names:
            (own if name.split(".")[0] == "controlkit" else absolute).add(name)
    return absolute, own


def _module_file(name):
    path = ROOT / Path(*name.split("."))
    for candidate in (path / "__init__.py", path.with_suffix(".py")):
        if candidate.is_file():
            return candidate
    return None  # a name imported from a module (a function, a class)


def notebook_imports():
    """The top-level modules the notebooks need: their own imports and, through the
    controlkit modules they use, every module those import (lazily or not)."""
    needed, todo, done = set(), set(), set()
    for notebook in NOTEBOOKS:
        for cell in json.loads(notebook.read_text())["cells"]:
            if cell["cell_type"] == "code":
                source = "".join(line for line in cell["source"]
                                 if not line.lstrip().startswith(("%", "!")))
                absolute, own = _imports(source)
                needed |= absolute
                todo |= own
    while todo:
        name = todo.pop()
        done.add(name)
        path = _module_file(name)
        if path is None:
            continue
        # a package's __init__ resolves "." to itself, as a module inside it would
        inside = f"{name}.__init__" if path.name == "__init__.py" else name
        absolute, own = _imports(path.read_text(), inside)
        needed |= absolute
        todo |= own - done
    return {name.split(".")[0] for name in needed}


def test_the_course_extra_brings_jupyter_lab_and_all_the_notebooks_import():
    course = PYPROJECT["project"]["optional-dependencies"]["course"]
    assert any(Requirement(r).name == "jupyterlab" for r in course)
    installed = _closure(PYPROJECT["project"]["dependencies"] + course)
    assert {"jupyterlab", "ipykernel", "numba", "ipywidgets", "anywidget", "pandas"} <= installed
    providers = importlib.metadata.packages_distributions()
    modules = notebook_imports()
    assert {"numpy", "control", "ipywidgets", "pandas", "anywidget", "numba"} <= modules
    missing = {}
    for module in sorted(modules - set(sys.stdlib_module_names) - {"controlkit"}
                         - NOT_FOR_THE_COURSE):
        found = {re.sub(r"[-_.]+", "-", d).lower() for d in providers.get(module, [])}
        if not found & installed:
            missing[module] = sorted(found) or "not installed here"
    assert not missing, f'pip install ".[course]" does not bring {missing}'


def test_the_import_walk_follows_controlkit_into_its_lazy_imports():
    # notebook 6 builds a sweep; the sweep imports pandas only when it makes its table
    modules = notebook_imports()
    assert "pandas" in modules and "cloudpickle" in modules and "tqdm" in modules
    absolute, own = _imports("def f():\n    import pandas\nfrom . import rows\n",
                             "controlkit.sweep.x")
    assert absolute == {"pandas"} and own == {"controlkit.sweep", "controlkit.sweep.rows"}


@pytest.mark.slow
def test_a_fresh_clone_follows_the_section_and_runs_every_notebook(tmp_path):
    """What a lecturer does, in a copy of this tree (the clone) with nothing installed: the
    section's commands from ``cd`` on, then every notebook executed in Jupyter (short
    horizons) instead of ``jupyter lab``, which would wait for a browser."""
    clone = fresh_clone(tmp_path / "controlkit")
    setup = COMMANDS[2:-1]  # the venv, its activation, the install (and any controlkit ...)
    executed = tmp_path / "executed"
    run = " && ".join(setup + [
        "jupyter lab --version",
        "CONTROLKIT_QUICK=1 jupyter nbconvert --to notebook --execute "
        f"--ExecutePreprocessor.timeout=900 --output-dir {executed} notebooks/*.ipynb"])
    result = subprocess.run(["bash", "-c", run], cwd=clone, env=clean_environment(),
                            capture_output=True, text=True, timeout=3600)
    assert result.returncode == 0, (result.stdout + result.stderr)[-6000:]
    outputs = sorted(executed.glob("*.ipynb"))
    assert [p.name for p in outputs] == [p.name for p in NOTEBOOKS]
    for path in outputs:
        cells = json.loads(path.read_text())["cells"]
        errors = [o for c in cells for o in c.get("outputs", []) if o["output_type"] == "error"]
        assert not errors, path.name
        assert all(c.get("execution_count") for c in cells if c["cell_type"] == "code"), path
