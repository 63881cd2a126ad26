"""controlkit.compat, the one place that uses what numba and python-control do not
publish: each use works with the versions installed, which pyproject.toml bounds."""

import re
import subprocess
import sys
import tomllib
from importlib import metadata
from pathlib import Path

import control as ct
import numpy as np
import pytest

from controlkit import _jit, compat

ROOT = Path(__file__).resolve().parents[1]


def _bounds(package):
    """``(lowest, below)`` of ``package`` in pyproject.toml's requirements."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    requirements = [*project["dependencies"],
                    *project["optional-dependencies"]["fast"]]
    line = next(r for r in requirements if re.match(rf"{package}\b", r))
    low = re.search(r">=([\d.]+)", line).group(1)
    high = re.search(r"<([\d.]+)", line).group(1)
    return low, high


def _version(text):
    return tuple(int(part) for part in re.findall(r"\d+", text)[:3])


@pytest.mark.parametrize("package", ["control", "numba"])
def test_the_installed_version_is_one_pyproject_admits(package):
    low, high = _bounds(package)
    installed = _version(metadata.version(package))
    assert _version(low) <= installed < _version(high), (package, installed, low, high)


def test_python_controls_aliases_read_as_python_control_reads_them():
    kwargs = {"U": [1.0, 2.0], "X0": 3.0, "return_x": True, "t_eval": [0.0, 1.0]}
    T, U, X0, return_x, t_eval = compat.timeresp_arguments(kwargs, [0.0, 1.0], 0.0, 0.0,
                                                           False, "T")
    assert (U, X0, return_x, t_eval) == ([1.0, 2.0], 3.0, True, [0.0, 1.0])
    assert kwargs == {}  # every alias consumed: what is left is python-control's to refuse


def test_an_alias_given_twice_is_refused_as_python_control_refuses_it():
    with pytest.raises(TypeError, match="inputs"):
        compat.timeresp_arguments({"U": 1.0}, [0.0, 1.0], 2.0, 0.0, False, "T")


def test_inputs_and_a_short_state_are_shaped_as_python_control_shapes_them():
    with pytest.warns(UserWarning, match="X0 too short; padding with zeros"):
        U, X0 = compat.inputs_and_state(np.ones(3), [(3,), (1, 3)], [1.0], 2)
    assert U.shape == (3,) and X0.tolist() == [1.0, 0.0]
    with pytest.raises(ValueError, match="Parameter `U`"):
        compat.inputs_and_state(np.ones(4), [(3,), (1, 3)], [1.0], 1)


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_two_processes_name_the_same_compiled_function_differently():
    # numba numbered compiled functions 1, 2, 3 in every process: the same function
    # compiled by two processes, both kept, had one name, and the second loaded was bound
    # to the first one's environment ('descr' is NULL, numba issue 10486)
    script = ("from controlkit import _jit\n"
              "numba = _jit.numba_module()\n"
              "f = numba.njit(lambda x: x + 1.0)\n"
              "f(1.0)\n"
              "print(next(iter(f.overloads.values())).fndesc.unique_name)\n")
    names = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                            check=True).stdout.strip() for _ in range(2)]
    assert all(names) and names[0] != names[1], names
    assert int(names[0].rsplit("$", 1)[1]) > 2 ** 64  # a random 128-bit id


def test_nothing_outside_compat_reads_an_unpublished_name_of_numba_or_python_control():
    private = re.compile(r"\b(?:numba|ct|control|importlib|sys|block|dispatcher)\b"
                         r"(?:\.\w+)*\._[a-z]\w*")
    found = []
    for path in (ROOT / "controlkit").rglob("*.py"):
        if path.name == "compat.py":
            continue
        for n, line in enumerate(path.read_text().splitlines(), start=1):
            code = line.split("#", 1)[0]
            if private.search(code) or re.search(r"from (?:numba|control)(?:\.[\w.]+)? import _",
                                                 code):
                found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not found, "\n".join(found)


def test_a_mixed_diagram_is_built_without_touching_python_controls_names():
    import importlib

    from controlkit.sampled_data import interconnect

    nlsys, statesp = (importlib.import_module(f"control.{m}") for m in ("nlsys", "statesp"))
    before = (nlsys.common_timebase, nlsys.InterconnectedSystem, statesp.LinearICSystem)
    plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    gain = ct.ss([], [], [], [[-0.5]], dt=0.1, name="gain", inputs="y", outputs="u")
    loop = interconnect([plant, gain], outputs="y")
    assert (nlsys.common_timebase, nlsys.InterconnectedSystem,
            statesp.LinearICSystem) == before
    assert [s.name for s in loop.syslist] == ["plant", "gain"]
    assert loop.syslist[1].dt == 0.1 and loop.base_period == 0.1
