"""A user function's check against Python, kept on disk for later processes
(controlkit.engines.fast.usercode.compiling._Record): a later process takes the outcome
without loading the compiled kernel, a failure is not tried again, and a function that
is not the text read from its file is checked again."""

from __future__ import annotations

import importlib.util
import linecache
import os

import numpy as np
import pytest

from controlkit.engines.fast.usercode import compiling
from controlkit.engines.source import NotCompilable


def _module(path, name, text):
    """``text`` written at ``path`` and imported as the module ``name``."""
    path.write_text(text)
    linecache.checkcache(str(path))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _as_a_later_process(monkeypatch):
    """Forget this process's checks; a check run now fails the test."""
    monkeypatch.setattr(compiling, "_CHECKED", {})

    def never(*args, **kwargs):
        raise AssertionError("the kernel was compiled and checked again")

    monkeypatch.setattr(compiling, "_checked_kernel", never)


def test_a_later_process_takes_the_outcome_from_disk_and_loads_no_kernel(tmp_path,
                                                                         monkeypatch):
    code = "def gain(t, x, u, params):\n    return [params['k'] * x[0] + u[0]]\n"
    fn = _module(tmp_path / "gain_a.py", "gain_a", code).gain
    folder = tmp_path / "cache"
    folder.mkdir()
    first = compiling.compiled_kernel(fn, {"k": 2.0}, folder, 1, 1, 1)
    assert len(list((folder / "checked").glob("*.json"))) == 1
    _as_a_later_process(monkeypatch)
    later = compiling.compiled_kernel(fn, {"k": 2.0}, folder, 1, 1, 1)
    assert later.module == first.module
    # and what it hands back computes the function once called
    out = later.kernel(0.0, np.array([3.0]), np.array([1.0]), later.pack({"k": 0.5}),
                       np.empty(1))
    assert out.tolist() == [2.5]


@pytest.mark.parametrize("body, why", [
    ("return np.array([x[0]]).tobytes()", "numba cannot compile it"),
    ("return [float(len(str(x[0])))]", "its compiled version differs from it at t = 0"),
])
def test_a_function_that_does_not_compile_is_not_tried_again(tmp_path, monkeypatch, body,
                                                             why):
    code = f"import numpy as np\n\n\ndef odd(t, x, u, params):\n    {body}\n"
    fn = _module(tmp_path / "odd_a.py", "odd_a", code).odd
    folder = tmp_path / "cache"
    folder.mkdir()
    with pytest.raises(NotCompilable, match=why) as first:
        compiling.compiled_kernel(fn, {}, folder, 1, 1, 0)
    _as_a_later_process(monkeypatch)
    with pytest.raises(NotCompilable) as later:
        compiling.compiled_kernel(fn, {}, folder, 1, 1, 0)
    assert str(later.value) == str(first.value)


def test_a_function_whose_file_was_edited_back_after_its_import_is_checked_again(
        tmp_path, monkeypatch):
    # the file said 2 x when checked; a later import read 3 x; then the file went back to
    # 2 x (a checkout of the older version) with the 3 x module still running: the text
    # read is the checked one, the code that runs is not
    path = tmp_path / "scaled.py"
    two = "def scaled(t, x, u, params):\n    return [2.0 * x[0]]\n"
    three = two.replace("2.0", "3.0")
    folder = tmp_path / "cache"
    folder.mkdir()
    compiling.compiled_kernel(_module(path, "scaled_a", two).scaled, {}, folder, 1, 1, 0)
    running = _module(path, "scaled_b", three).scaled
    path.write_text(two)
    os.utime(path, (1.0, 1.0))  # a date of its own: linecache reads the text anew
    linecache.checkcache(str(path))
    for forget in (False, True):  # this process, then a later one
        if forget:
            monkeypatch.setattr(compiling, "_CHECKED", {})
        with pytest.raises(NotCompilable, match="differs from it"):
            compiling.compiled_kernel(running, {}, folder, 1, 1, 0)


def test_an_unreadable_record_is_checked_again(tmp_path, monkeypatch):
    code = "def lag(t, x, u, params):\n    return [-x[0] + u[0]]\n"
    fn = _module(tmp_path / "lag_a.py", "lag_a", code).lag
    folder = tmp_path / "cache"
    folder.mkdir()
    first = compiling.compiled_kernel(fn, {}, folder, 1, 1, 1)
    (record,) = (folder / "checked").glob("*.json")
    record.write_text('{"module": "os"}')  # not a kernel module of ours
    monkeypatch.setattr(compiling, "_CHECKED", {})
    assert compiling.compiled_kernel(fn, {}, folder, 1, 1, 1).module == first.module
    assert '"module": "controlkit_user_' in record.read_text()  # written again


def test_a_numba_helper_imported_by_name_is_part_of_the_kernels_text(tmp_path, monkeypatch):
    # numba's cache knows a kernel by its own file: an edited helper it imports must make
    # a new kernel (and a new record), or the old compiled helper runs, silently
    import sys

    monkeypatch.syspath_prepend(str(tmp_path))
    folder = tmp_path / "cache"
    folder.mkdir()
    answers = []
    for factor in ("0.0", "7.0"):
        for name in ("helper_by_name", "user_of_helper"):
            sys.modules.pop(name, None)
        (tmp_path / "helper_by_name.py").write_text(
            f"import numba\n\n\n@numba.njit\ndef nj(v):\n    return {factor} * v\n")
        user = _module(tmp_path / "user_of_helper.py", "user_of_helper",
                       "from helper_by_name import nj\n\n\n"
                       "def f(t, x, u, params):\n    return [nj(x[0]) + u[0]]\n")
        compiled = compiling.compiled_kernel(user.f, {}, folder, 1, 1, 1)
        out = compiled.kernel(0.0, np.array([2.0]), np.array([1.0]), compiled.pack({}),
                              np.empty(1))
        answers.append((compiled.module, out.tolist()))
    (first, at_zero), (second, at_seven) = answers
    assert first != second
    assert (at_zero, at_seven) == ([1.0], [15.0])


def test_a_record_made_with_numba_disabled_is_not_one_of_a_compiled_run(tmp_path,
                                                                        monkeypatch):
    # NUMBA_DISABLE_JIT runs the "compiled" kernel as Python: it always agrees
    import numba

    outcome, codes = ("text", (), "float64"), (_module.__code__,)
    compiled = compiling._Record(outcome, codes, tmp_path).path
    monkeypatch.setattr(numba.config, "DISABLE_JIT", 1)
    assert compiling._Record(outcome, codes, tmp_path).path != compiled


def test_a_list_and_an_array_of_the_same_numbers_are_checked_each(tmp_path):
    # they pack alike; Python's answer differs (a list repeated, an array doubled)
    code = "def f(t, x, u, params):\n    return [-x[0] + len(params['v'] * 2)]\n"
    fn = _module(tmp_path / "lengths.py", "lengths", code).f
    folder = tmp_path / "cache"
    folder.mkdir()
    compiling.compiled_kernel(fn, {"v": np.array([1.0, 2.0])}, folder, 1, 1, 0)
    with pytest.raises(NotCompilable, match="differs from it"):
        compiling.compiled_kernel(fn, {"v": [1.0, 2.0]}, folder, 1, 1, 0)
