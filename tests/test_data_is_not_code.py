"""A diagram's names, a function's defaults and the values it reads are data, whoever wrote
them: none of them becomes code in the modules the fast engine writes and imports.

Each case is an attack a review made work (the payload creates a file); each asserts that
the file is not created and that the run still gives python-control's numbers.
"""

from __future__ import annotations

import sys
import types
import warnings

import control as ct
import numpy as np
import pytest

import controlkit
from controlkit.engines.fast import store

T = np.linspace(0.0, 1.0, 11)


def _touch(path) -> str:
    return f"import os; os.system('touch {path}')"


def _gain_loop(out, name="d"):
    g = ct.nlsys(None, out, inputs="u", outputs="y", name="g")
    return ct.interconnect([g], inputs="u", outputs="y", name=name)


def _run_both(loop, compile=True):
    expected = ct.input_output_response(loop, T, np.ones_like(T))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (a block that runs as Python says so)
        ours = controlkit.input_output_response(loop, T, np.ones_like(T), compile=compile)
    np.testing.assert_array_equal(ours.outputs, expected.outputs)
    return ours


@pytest.mark.parametrize("coding", ["unicode_escape", "utf-7"])
def test_a_diagram_name_cannot_declare_the_coding_of_its_module(tmp_path, coding):
    # the name was written on the module's first line, where Python reads a coding
    # declaration: under unicode_escape repr's "\n" is a newline again, under utf-7 "+AAo-"
    target = tmp_path / "ran"
    payload = (f"coding:{coding}\n{_touch(target)}#" if coding == "unicode_escape" else
               f"coding:utf-7 +AAo-import os+ADs-os+AC4-system('touch {target}')#")
    loop = _gain_loop(lambda t, x, u, p: [2.0 * u[0]], name=payload)
    assert _run_both(loop).engine_mode == "compiled"
    controlkit.explain(loop)
    assert not target.exists()


def test_a_function_s_qualified_name_cannot_declare_the_coding_of_its_module(tmp_path):
    target = tmp_path / "ran"

    def out(t, x, u, params):
        return [3.0 * u[0]]

    out.__qualname__ = f"coding:unicode_escape\n{_touch(target)}#"
    loop = _gain_loop(out)
    controlkit.explain(loop)
    _run_both(loop)
    assert not target.exists()


def test_a_name_of_a_string_class_is_written_as_its_text(tmp_path):
    # a function's __qualname__ may be a str subclass, whose repr wrote a line of code
    # into the module's header
    target = tmp_path / "ran"

    class Name(str):
        def __repr__(self):
            return f"'x'\n{_touch(target)}\n#"

    def out(t, x, u, params):
        return [3.0 * u[0]]

    out.__qualname__ = Name("out")
    loop = _gain_loop(out)
    assert _run_both(loop).engine_mode == "compiled"
    assert not target.exists()


def test_a_kernel_s_identity_of_a_string_class_is_written_as_its_text(tmp_path):
    # a kernel block's identity (read from its function) was written by its repr into a
    # comment of the diagram's module, where a newline in it began a line of code
    from controlkit._jit import jit
    from controlkit.blocks.contract import KernelBlock

    target = tmp_path / "ran"

    class Name(str):
        def __repr__(self):
            return f"'x'\n{_touch(target)}\n#"

    @jit
    def doubled(t, x, u, p, out):
        out[0] = 2.0 * u[0]
        return out

    doubled.identity = Name("doubled")
    block = KernelBlock(doubled, feedthrough=True, dt=None, name="dbl", inputs=["u"],
                        outputs=["y"])
    loop = ct.interconnect([block], inputs="u", outputs="y", name="kernel_identity")
    ours = controlkit.input_output_response(loop, T, np.ones_like(T), compile=True)
    assert ours.engine_mode == "compiled" and ours.outputs.tolist() == [2.0] * T.size
    assert not target.exists()


def test_a_name_read_from_a_code_object_must_be_an_identifier(tmp_path):
    # a lambda's parameters are read from its code object, where a name need not be an
    # identifier: written out, "p=<code>" was a default argument run at import
    target = tmp_path / "ran"
    out = lambda t, x, u, params: [2.0 * u[0]]  # noqa: E731 - python-control's idiom
    out.__code__ = out.__code__.replace(
        co_varnames=("t", "x", "u", f"p=__import__('os').system('touch {target}')"))
    loop = _gain_loop(out)
    (row,) = controlkit.explain(loop)
    assert row.tier == "python" and "not an identifier" in row.reason, row
    assert _run_both(loop).engine_mode == "python"
    assert not target.exists()


def test_the_store_refuses_a_module_text_python_would_read_as_other_code(tmp_path):
    text = f"# coding: unicode_escape\n# \\n{_touch(tmp_path / 'ran')}\n"
    with pytest.raises(store.StoreRefused, match="other code"):
        store.module_file(text, "diagram")


def test_a_string_whose_class_writes_code_as_its_repr_runs_as_python(tmp_path):
    target = tmp_path / "ran"

    class Label(str):
        def __repr__(self):
            return f"__import__('os').system('touch {target}') and 'fast'"

    def out(t, x, u, params, mode=Label("fast")):  # noqa: B008 - the attack itself
        return [2.0 * u[0]] if mode == "fast" else [u[0]]

    loop = _gain_loop(out)
    (row,) = controlkit.explain(loop)
    assert row.tier == "python" and "of type 'Label'" in row.reason, row
    assert _run_both(loop).engine_mode == "python"
    assert not target.exists()


def test_a_complex_number_is_written_by_its_own_two_floats(tmp_path):
    target = tmp_path / "ran"

    class Hostile(float):
        def __repr__(self):
            return f"__import__('os').system('touch {target}')"

    class Pole(complex):
        @property
        def real(self):
            return Hostile(-1.0)

    pole = Pole(-1.0, 2.0)

    def out(t, x, u, params):
        return [(pole * u[0]).imag]

    # (a subclass of a number runs as Python: compiled code would not read its own
    # attributes and operators, see test_numbers_with_operators_of_their_own_run_as_python)
    assert _run_both(_gain_loop(out)).engine_mode == "python"
    assert not target.exists()


def test_a_helper_s_name_is_not_written_as_code(tmp_path):
    target = tmp_path / "ran"

    def gain(v):
        return 2.0 * v

    gain.__name__ = f'a + """,)\n{_touch(target)}\ndef q'

    def out(t, x, u, params):
        return [gain(u[0])]

    assert _run_both(_gain_loop(out)).engine_mode == "compiled"
    assert not target.exists()


@pytest.mark.parametrize(("planted", "name", "registered"), [
    # a namespace made from data, named as a module planted on sys.path: the module
    # itself, not its number, goes into the kernel's text
    ("ck_not_the_one", "ck_not_the_one", False),
    # a module registered as 'a.b' alone (as plugin loaders do): the kernel's text said
    # `import a.b as ...`, and Python's import statement imports the package `a` by name,
    # from sys.path, first (a review ran a planted ck_parent.py, from explain already)
    ("ck_parent", "ck_parent.sub", True),
    # registered under a name Python's parser normalizes (a fullwidth 'c', NFKC): the
    # text's `import ｃk_planted` would have imported ck_planted from sys.path
    ("ck_planted", "\uff43k_planted", True),
], ids=["read from an attribute", "under a package not imported", "normalized by the parser"])
def test_a_module_is_imported_only_when_it_and_its_packages_are_imported(
        tmp_path, monkeypatch, planted, name, registered):
    target = tmp_path / "ran"
    (tmp_path / f"{planted}.py").write_text(_touch(target) + "\nk = 5.0\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    namespace = types.ModuleType(name)
    namespace.k = 2.0
    if registered:
        monkeypatch.setitem(sys.modules, name, namespace)

    def out(t, x, u, params):
        m = namespace
        return [m.k * u[0]]

    loop = _gain_loop(out)
    (row,) = controlkit.explain(loop)
    assert row.tier == "python" and name in row.reason, row
    _run_both(loop)
    assert not target.exists() and planted not in sys.modules


class _Gain(float):  # 2.0, but ten times as much on signals above 3
    def __mul__(self, other):
        return float(self) * other * (10.0 if other > 3.0 else 1.0)

    __rmul__ = __mul__


_GAIN = _Gain(2.0)


def _by_global_gain(t, x, u, params):
    return [x[0] + 0.001 * (_GAIN * u[0])]


def _by_parameter_gain(t, x, u, params):
    return [x[0] + 0.001 * (params["k"] * u[0])]


@pytest.mark.parametrize("where", ["global", "parameter", "parameter in a list",
                                   "numpy int16 parameter"])
def test_numbers_with_operators_of_their_own_run_as_python(where):
    # compiled code kept a float subclass's number and multiplied plain floats, where
    # python-control calls its __mul__: past the compared first piece, silently another
    # answer (y(5) 24.995 against 168.923); a numpy int16 parameter wraps in numpy
    update = _by_global_gain if where == "global" else _by_parameter_gain
    k = {"global": None, "parameter": _GAIN, "parameter in a list": [1.0, _GAIN],
         "numpy int16 parameter": np.int16(200)}[where]
    if where == "parameter in a list":
        update = lambda t, x, u, params: [x[0] + 0.001 * (params["k"][1] * u[0])]  # noqa: E731
    if where == "numpy int16 parameter":
        update = lambda t, x, u, params: [0.5 * x[0] + float(params["k"] * params["k"])]  # noqa: E731
    block = ct.nlsys(update, lambda t, x, u, params: x, inputs="u", outputs="y",
                     states="x", name="g", dt=0.001, params={"k": k})
    loop = ct.interconnect([block], inputs="u", outputs="y", name="subclass")
    T = np.arange(5001) * 0.001
    expected = ct.input_output_response(loop, T, T)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        ours = controlkit.input_output_response(loop, T, T, compile=True)
    np.testing.assert_array_equal(ours.outputs, expected.outputs)
    assert ours.engine_mode == "python"
    assert any("compiled code" in str(w.message) for w in said), said


def test_a_store_file_that_is_not_its_text_is_written_again(tmp_path):
    target = tmp_path / "ran"
    text = "SWAPPED_IN_A_TEST = 1\n"
    path = store.module_file(text, "diagram")
    path.write_text(_touch(target) + "\n" + text)  # changed behind the store's back
    assert store.module_file(text, "diagram").read_text() == text
    assert not target.exists()


def test_a_module_s_name_is_written_by_its_text(tmp_path, monkeypatch):
    # a str subclass's __format__ wrote code where an f-string put the module's name
    target = tmp_path / "ran"

    class Name(str):
        def __format__(self, spec):
            return f"{str(self)} as _unused\n{_touch(target)}\nimport {str(self)}"

    namespace = types.ModuleType("ck_formatted")
    namespace.k = 2.0
    monkeypatch.setitem(sys.modules, "ck_formatted", namespace)
    namespace.__name__ = Name("ck_formatted")

    def out(t, x, u, params):
        m = namespace
        return [m.k * u[0]]

    assert _run_both(_gain_loop(out)).engine_mode == "compiled"
    assert not target.exists()


def _backslash_in_an_f_string(t, x, u, params, where="C:\\runs"):
    note = f"{where}"  # noqa: F841 - what Python 3.11 cannot write back inside an f-string
    return [2.0 * u[0]]


def test_a_text_that_cannot_be_written_out_runs_as_python():
    # ast.unparse raised "Unable to avoid backslash in f-string expression part" (or wrote
    # text that did not parse), out of explain and of compile=True; Python 3.12 writes any
    # f-string back (PEP 701), and the function compiles there
    loop = _gain_loop(_backslash_in_an_f_string)
    (row,) = controlkit.explain(loop)
    if sys.version_info >= (3, 12):
        assert row.tier == "compiled", row
    else:
        assert row.tier == "python" and "cannot be written out" in row.reason, row
    assert _run_both(loop).engine_mode == row.tier


COMPLEX_POLES = np.array([complex(np.inf, 0.0), 1j, complex(0.0, np.nan)])


def test_a_complex_array_with_an_infinity_is_written_as_its_numbers():
    # repr wrote (inf+0j), a name the module does not have: NameError out of explain
    def out(t, x, u, params):
        return [COMPLEX_POLES[1].imag * u[0]]

    assert _run_both(_gain_loop(out)).engine_mode == "compiled"


def test_a_lambda_whose_file_changed_since_its_import_runs_as_python(tmp_path, monkeypatch):
    # a lambda's text is cut from its file: a file edited after the import held code
    # other than what runs, and that text was compiled
    (tmp_path / "ck_edited.py").write_text("out = lambda t, x, u, params: [2.0 * u[0]]\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import ck_edited

    monkeypatch.delitem(sys.modules, "ck_edited")
    (tmp_path / "ck_edited.py").write_text("out = lambda t, x, u, params: [3.0 * u[0]]\n")
    loop = _gain_loop(ck_edited.out)
    (row,) = controlkit.explain(loop)
    assert row.tier == "python" and "changed after it was imported" in row.reason, row
    assert _run_both(loop).engine_mode == "python"


def test_a_compile_record_of_other_types_is_ignored(tmp_path, monkeypatch):
    # a record is data: {"seconds": "1"} raised a TypeError, and every compiled run of the
    # store went to Python under that message
    (tmp_path / "diagram_x.json").write_text('{"seconds": "1", "blocks": 1, "entry": '
                                             '"run_discrete"}')
    (tmp_path / "diagram_y.json").write_text('{"seconds": 2.0, "blocks": 4, "entry": '
                                             '"run_discrete"}')
    monkeypatch.setattr(store, "folder", lambda: tmp_path)
    monkeypatch.setattr(store, "_TIMES", {})
    assert store.compile_times("run_discrete") == [0.5]


def test_a_function_s_name_normalized_by_the_parser_is_not_imported_by_it(
        tmp_path, monkeypatch):
    # `from helpers import ｔriple` would import helpers.triple, another function
    (tmp_path / "ck_helpers_nfkc.py").write_text(
        "from controlkit._jit import jit\n\n\n@jit\ndef double(v):\n    return 2.0 * v\n"
        "\n\n@jit\ndef triple(v):\n    return 3.0 * v\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import ck_helpers_nfkc as helpers

    odd = "\uff54riple"
    helpers.double.py_func.__name__ = odd
    monkeypatch.setattr(helpers, odd, helpers.double, raising=False)
    helper = helpers.double

    def out(t, x, u, params):
        return [helper(u[0])]

    ours = _run_both(_gain_loop(out))  # (compiled as a helper, not imported)
    assert ours.engine_mode == "compiled" and ours.outputs[0] == 2.0


def _factory_kernel(k):
    from controlkit._jit import jit

    @jit
    def gain(t, x, u, p, out):
        out[0] = k * u[0]
        return out

    return gain


def test_kernels_made_by_a_factory_with_other_values_are_other_modules():
    # the same code and name, another closure value: the compiled module of the first
    # was taken for the second (2.0 where python-control gave 3.0, no warning)
    from controlkit.blocks.contract import KernelBlock

    for k in (2.0, 3.0):
        block = KernelBlock(_factory_kernel(k), feedthrough=True, dt=None, name="g",
                            inputs=["u"], outputs=["y"])
        loop = ct.interconnect([block], inputs="u", outputs="y", name="factory")
        ours = _run_both(loop)
        assert ours.engine_mode == "compiled" and ours.outputs[0] == k


def test_a_kernel_s_identity_follows_the_helpers_it_calls(tmp_path, monkeypatch):
    # numba's cache knows a module by its own file: a helper edited in another module
    # would have been loaded as compiled before (an older session's numbers)
    import importlib

    from controlkit.engines.fast.codegen import kernel_identity

    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / "ck_kernel_mod.py").write_text(
        "from controlkit._jit import jit\nfrom ck_helper_mod import helper\n\n\n@jit\n"
        "def kernel(t, x, u, p, out):\n    out[0] = helper(u[0])\n    return out\n")
    identities = []
    for body in ("2.0 * v", "3.0 * v + 1.0"):  # (sizes differ: Python's .pyc is by size)
        (tmp_path / "ck_helper_mod.py").write_text(
            f"from controlkit._jit import jit\n\n\n@jit\ndef helper(v):\n    return {body}\n")
        for name in ("ck_helper_mod", "ck_kernel_mod"):
            sys.modules.pop(name, None)
        importlib.invalidate_caches()
        identities.append(kernel_identity(importlib.import_module("ck_kernel_mod").kernel))
    for name in ("ck_helper_mod", "ck_kernel_mod"):
        sys.modules.pop(name, None)
    assert identities[0] != identities[1]
    assert identities[0].startswith("ck_kernel_mod.kernel (source ")


def test_a_kernel_s_global_changed_between_calls_of_one_diagram_is_compiled_anew(
        tmp_path, monkeypatch):
    # the diagram's kept job was taken again (a review: 2.0 where python-control gave 3.0)
    import importlib

    from controlkit.blocks.contract import KernelBlock

    monkeypatch.syspath_prepend(str(tmp_path))
    (tmp_path / "ck_gain_mod.py").write_text(
        "from controlkit._jit import jit\n\nGAIN = 2.0\n\n\n@jit\n"
        "def gain(t, x, u, p, out):\n    out[0] = GAIN * u[0]\n    return out\n")
    module = importlib.import_module("ck_gain_mod")
    block = KernelBlock(module.gain, feedthrough=True, dt=None, name="g", inputs=["u"],
                        outputs=["y"])
    loop = ct.interconnect([block], inputs="u", outputs="y", name="global_gain")
    try:
        for gain in (2.0, 3.0):
            module.GAIN = gain
            assert _run_both(loop).outputs[0] == gain
    finally:
        sys.modules.pop("ck_gain_mod", None)
