"""python-control's own simulation tests, run through the drop-in (issue 33, item 3).

The test files of the installed python-control (``control/tests``) that simulate are copied
into a temporary folder, beside python-control's own ``conftest.py`` and a few lines that
put ``controlkit.input_output_response`` in the place of ``control.input_output_response``
(controlkit's own fall-backs to python-control still reach the original). Every test that
passes with python-control alone must pass so. About two minutes: under the ``slow``
marker (``python -m pytest tests/test_python_control_suite.py -m slow``).
"""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import control
import pytest

#: python-control's test files that call input_output_response (directly, through
#: forced_response of a nonlinear system, or phase plots), and the discrete-time tests.
FILES = ["iosys_test.py", "timeresp_test.py", "nlsys_test.py", "interconnect_test.py",
         "statefbk_test.py", "stochsys_test.py", "timeplot_test.py", "trdata_test.py",
         "response_test.py", "kwargs_test.py", "flatsys_test.py", "optimal_test.py",
         "discrete_test.py"]

#: Appended to python-control's conftest.py in the copy.
DROP_IN = '''

# --- controlkit's drop-in in the place of control.input_output_response ----------------
import os as _os
import sys as _sys
import threading as _threading
import warnings as _warnings

import control.nlsys  # noqa: F401 - control.nlsys is also a function's name: sys.modules
import control.phaseplot  # noqa: F401

_original = _sys.modules["control.nlsys"].input_output_response
_inside = _threading.local()
_calls = [0]


def _dropin(*args, **kwargs):
    if getattr(_inside, "active", False):  # controlkit running python-control itself
        return _original(*args, **kwargs)
    import controlkit
    import controlkit.engines.fast  # noqa: F401 - started: else a short run, as most are
    # here, would be python-control's own (fast_start_pays) and nothing of ours tested

    _inside.active = True
    try:
        _calls[0] += 1
        with _warnings.catch_warnings():
            _warnings.filterwarnings("ignore", message="fast engine not used")
            return controlkit.input_output_response(*args, **kwargs)
    finally:
        _inside.active = False


if not _os.environ.get("PYTHON_CONTROL_ALONE"):
    for _name in ("control", "control.nlsys", "control.phaseplot"):
        _sys.modules[_name].input_output_response = _dropin


def pytest_terminal_summary(terminalreporter):
    terminalreporter.write_line(f"calls through controlkit: {_calls[0]}")
'''


def _run(folder, tests, alone=False):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    if alone:
        env["PYTHON_CONTROL_ALONE"] = "1"
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                             "-W", "ignore", "--tb=line", "-rf", *tests], cwd=folder,
                            capture_output=True, text=True, env=env, timeout=3600)
    failed = re.findall(r"^FAILED (\S+)", result.stdout, re.MULTILINE)
    return failed, result.stdout


def _native(test_id):
    """A test's id when python-control's own function is the one parametrized."""
    return test_id.replace("[_dropin-", "[input_output_response-")


@pytest.mark.slow
def test_python_controls_simulation_tests_pass_through_the_drop_in(tmp_path):
    source = Path(control.__file__).parent / "tests"
    if not (source / "conftest.py").exists():
        pytest.skip("this python-control was installed without its tests")
    for name in FILES:
        shutil.copy(source / name, tmp_path / name)
    (tmp_path / "conftest.py").write_text((source / "conftest.py").read_text() + DROP_IN)
    failed, out = _run(tmp_path, FILES)
    calls = int(re.search(r"calls through controlkit: (\d+)", out).group(1))
    assert calls > 1000, out[-3000:]  # the drop-in was the one called
    summary = out.strip().splitlines()[-1]
    assert re.search(r"\d+ passed", summary), out[-3000:]
    if failed:  # those that fail with python-control alone too are not the drop-in's
        alone, _ = _run(tmp_path, [_native(name) for name in failed], alone=True)
        failed = [name for name in failed if _native(name) not in alone]
    assert not failed, f"{len(failed)} of python-control's tests fail through the drop-in " \
                       f"({summary}):\n" + "\n".join(
                           line for line in out.splitlines() if line.startswith("FAILED")
                           or re.match(r"\S+\.py:\d+: ", line))
