"""User functions written in python-control's idiom compile and give python-control's numbers;
the cases that once gave a wrong answer, crashed or refused valid input do not any more."""

import functools
import sys

import control as ct
import numpy as np
import pytest
from idiom_diagrams import DIAGRAMS, cruise

import controlkit
from controlkit.engines import fast as engine
from controlkit.engines.fast import loader, usercode
from controlkit.engines.source import NotCompilable, used_params
from controlkit.simulation import simulate

ENGINES = ["python-control", "fast"]
TS = 0.05


@pytest.mark.parametrize("name", list(DIAGRAMS))
def test_idiom_diagram_is_compiled_and_equals_python_control(name):
    loop, T, X0, U, params = DIAGRAMS[name]()
    tiers = engine.explain(loop, params=params)
    assert [row.tier for row in tiers] == ["compiled"] * len(loop.syslist), tiers
    ref = ct.input_output_response(loop, T, U, X0, params=params)
    fast = simulate(loop, T, X0=X0, U=U, params=params, engine="fast")
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.states, ref.states, rtol=0, atol=1e-9)
    assert np.ptp(ref.outputs, axis=1).max() > 0.1  # the loop does something


def test_a_new_parameter_value_compiles_nothing_new():
    loop, T, X0, U, params = cruise(steps=60)
    folder = loader.cache_folder()

    def compiled_modules():
        return ({p.name for p in folder.glob("controlkit_user_*.py")},
                {m for m in sys.modules if m.startswith("controlkit_user_")})

    simulate(loop, T, X0=X0, U=U, params=params, engine="fast")
    before = compiled_modules()
    # new values, an int where a float was, and a key given that had its default
    for new in ({"kaw": 0.5, "mass": 1750.5}, {"kaw": 3, "mass": 1200, "kp": 0.8},
                {"kaw": 2.0, "mass": 2000.0, "kp": 1}):
        fast = simulate(loop, T, X0=X0, U=U, params=new, engine="fast")
        ref = ct.input_output_response(loop, T, U, X0, params=new)
        np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
        assert compiled_modules() == before
    assert {r.tier for r in engine.explain(loop, params=new)} == {"compiled"}


def integrating(block, **kwargs):
    """``block`` (a static user block from ``u`` to ``v``) feeding a discrete integrator."""
    integrator = ct.ss([[1.0]], [[TS]], [[1.0]], [[0.0]], dt=TS, inputs="v", outputs="y",
                       name="integrator")
    return ct.interconnect([block, integrator], inputs="u", outputs=["v", "y"], **kwargs)


def both_engines_agree(loop, T, X0, U, params=None):
    ref = ct.input_output_response(loop, T, U, X0, params=params, squeeze=False)
    for which in ENGINES:
        resp = simulate(loop, T, X0=X0, U=U, params=params, engine=which)
        np.testing.assert_allclose(np.reshape(resp.outputs, ref.outputs.shape), ref.outputs,
                                   rtol=0, atol=1e-12)
    return ref


# --- what Python runs is what is compiled ---------------------------------------------------

def clipped(limit):
    def decorate(fn):
        @functools.wraps(fn)
        def wrapper(t, x, u, params):
            return np.clip(fn(t, x, u, params), -limit, limit)
        return wrapper
    return decorate


@clipped(1.5)
def clipped_gain(t, x, u, params):
    return params.get("k", 2.0) * u[0]


def test_a_decorated_function_runs_the_wrapper_not_only_the_body_it_wraps():
    # the undecorated body was compiled (inspect.getsource follows __wrapped__) and agreed
    # with the wrapper at the one trial point (u < 0.75, unclipped): 2.0 here, not 1.5
    block = ct.nlsys(None, clipped_gain, inputs="u", outputs="v", dt=None, name="gain")
    loop = integrating(block)
    ref = both_engines_agree(loop, np.arange(20) * TS, [0.0], 1.0)
    assert ref.outputs[0].max() == 1.5
    assert engine.explain(loop)[0].tier == "compiled"


def leaky(t, x, u, params, leak=0.1):
    return [x[0] + TS * (params["gain"] * u[0] - leak * x[0])]


class Gain:
    def __init__(self, scale):
        self.scale = scale

    def __call__(self, t, x, u, params):
        return self.scale * params.get("gain", 1.0) * u[0]


@pytest.mark.parametrize("kind", ["partial", "callable object", "bound method"])
def test_partials_callable_objects_and_methods_take_params_on_both_engines(kind):
    # both engines raised AttributeError (a partial has no __code__) when given params=
    if kind == "partial":
        block = ct.nlsys(functools.partial(leaky, leak=0.4), None, inputs="u", outputs="y",
                         states=1, dt=TS, params={"gain": 1.0}, name="block")
        loop = ct.interconnect([block], inputs="u", outputs="y")
    else:
        call = Gain(2.0) if kind == "callable object" else Gain(2.0).__call__
        loop = integrating(ct.nlsys(None, call, inputs="u", outputs="v", dt=None,
                                    name="block"))
    T = np.arange(30) * TS
    ref = both_engines_agree(loop, T, np.zeros(loop.nstates), 1.0, params={"gain": 3.0})
    assert abs(ref.outputs[0, -1]) > 0.5
    assert engine.explain(loop, params={"gain": 3.0})[0].tier == "compiled"


def alias_gain(t, x, u, params):
    p = params
    return p["k"] * u[0]


def variable_key_gain(t, x, u, params):
    name = "k"
    return params[name] * u[0]


@pytest.mark.parametrize("function", [alias_gain, variable_key_gain])
def test_params_read_through_an_alias_or_a_variable_key_are_accepted(function):
    # both were refused as "read by no block", even on the python-control path
    loop = integrating(ct.nlsys(None, function, inputs="u", outputs="v", dt=None,
                                name="gain", params={"k": 1.0}))
    ref = both_engines_agree(loop, np.arange(10) * TS, [0.0], 1.0, params={"k": 3.0})
    assert ref.outputs[0, 0] == 3.0
    assert used_params(function) == {"k"}


def test_a_numpy_scalar_parameter_value_compiles():
    # np.sign(b) is np.float64: written as np.float64(1.0) into a module that imports numpy
    # as _np_, it raised NameError in simulate and explain, and broke every later call
    def update(t, x, u, params):
        return [x[0] - TS * params["gamma"] * params["sign_b"] * u[0]]

    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="adapt",
                     params={"gamma": 1, "sign_b": np.sign(-0.5)})
    loop = ct.interconnect([block], inputs="u", outputs="y")
    assert engine.explain(loop)[0].tier == "compiled"
    both_engines_agree(loop, np.arange(10) * TS, [0.0], 1.0,
                       params={"sign_b": np.float64(1.0)})


def test_a_module_that_fails_to_load_is_not_left_half_loaded(tmp_path):
    source = ("import numpy as _np_\nbroken = _np_.float64(1.0) + undefined_name\n\n"
              "def kernel(t, x, u, p, out):\n    return out\n")
    for _ in range(2):  # the second attempt fails the same way, not with AttributeError
        with pytest.raises(NotCompilable, match=r"does not load \(NameError"):
            usercode.load_kernel(source, tmp_path)
    assert not [m for m in sys.modules if m.startswith("controlkit_user_")
                and getattr(sys.modules[m], "__file__", "").startswith(str(tmp_path))]


def test_a_compiled_function_is_checked_at_the_runs_initial_state():
    # 2 ** n overflows int64 in compiled code for n > 63 and stays exact in Python: the
    # two agree at the random trial points (x < 1) but not at this run's start (x = 7)
    def update(t, x, u, params):
        return [0.9 * x[0] + min(2 ** int(10 * x[0]) * 1e-21, 0.5)]

    block = ct.nlsys(update, None, inputs=0, outputs="y", states=1, dt=TS, name="odd")
    loop = ct.interconnect([block], outputs="y")
    ref = both_engines_agree(loop, np.arange(5) * TS, [7.0], np.zeros((0, 5)))
    assert ref.outputs[0, 1] == pytest.approx(0.9 * 7.0 + 0.5)


class Settings:
    """Values and a function a user function reads through an object."""


def test_values_and_helpers_read_through_objects_are_read_again_at_each_run():
    settings = Settings()
    settings.umax, settings.shape = 1.0, lambda v: 2.0 * v

    def limited(t, x, u, params):
        return min(max(settings.shape(u[0]), -settings.umax), settings.umax)

    loop = integrating(ct.nlsys(None, limited, inputs="u", outputs="v", dt=None,
                                name="limited"))
    T = np.arange(5) * TS
    first = both_engines_agree(loop, T, [0.0], 0.4)
    settings.umax, settings.shape = 0.5, lambda v: -3.0 * v  # changed between two runs
    second = both_engines_agree(loop, T, [0.0], 0.4)
    assert first.outputs[0, 0] == 0.8 and second.outputs[0, 0] == -0.5
    assert engine.explain(loop)[0].tier == "compiled"


def test_a_division_python_refuses_is_not_turned_into_inf_by_compiled_code():
    # compiled code divides like numpy (inf); two Python floats divided by zero raise
    def update(t, x, u, params):
        return [x[0] + TS * params["a"] / params["b"]]

    block = ct.nlsys(update, None, inputs=0, outputs="y", states=1, dt=TS, name="ratio",
                     params={"a": 1.0, "b": 0.0})
    loop = ct.interconnect([block], outputs="y")
    row = engine.explain(loop)[0]
    assert row.tier == "python" and "raises at every trial point" in row.reason
    for which in ENGINES:
        with pytest.raises(ZeroDivisionError):
            simulate(loop, np.arange(3) * TS, X0=[0.0], U=np.zeros((0, 3)), engine=which)


def optional_offset(t, x, u, params):
    gain = params["gain"] if params["enabled"] else 0.0
    if "offset" in params:  # read only when given
        gain = gain + params["offset"]
    low, high = params["band"]
    extra = 0.0 if params.get("note") is None else 1.0
    return [x[0] + TS * (gain * np.clip(u[0], low, high) - x[0] + extra + params["M"][1, 0])]


@pytest.mark.parametrize("params", [None, {"enabled": False}, {"offset": 1.5},
                                    {"band": [-1, 2], "gain": 0.5, "note": 3}])
def test_bool_none_tuple_and_matrix_values_and_optional_keys_compile(params):
    block = ct.nlsys(optional_offset, None, inputs="u", outputs="y", states=1, dt=TS,
                     name="block", params={"gain": 2, "enabled": True, "band": (-0.5, 0.5),
                                           "note": None, "M": np.array([[1.0, 2.0],
                                                                        [3.0, 4.0]])})
    loop = ct.interconnect([block], inputs="u", outputs="y")
    assert engine.explain(loop, params=params)[0].tier == "compiled"
    T = np.arange(20) * TS
    both_engines_agree(loop, T, [0.0], np.sin(T), params=params)


def test_an_integer_parameter_used_as_an_index_compiles_as_an_integer():
    table = np.array([0.5, 1.0, 2.0, 4.0])

    def update(t, x, u, params):
        return [x[0] + TS * table[params["gear"]] * u[0]]

    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="geared",
                     params={"gear": 1})
    loop = ct.interconnect([block], inputs="u", outputs="y")
    assert engine.explain(loop)[0].tier == "compiled"
    ref = both_engines_agree(loop, np.arange(10) * TS, [0.0], 1.0, params={"gear": 3})
    assert ref.outputs[0, -1] == pytest.approx(9 * TS * 4.0)


def test_a_parameter_compiled_code_cannot_take_sends_its_block_to_python_by_name():
    def valve(t, x, u, params):
        gain = params["gain"] if params["mode"] == "fast" else 0.5 * params["gain"]
        return gain * u[0]

    loop = integrating(ct.nlsys(None, valve, inputs="u", outputs="v", dt=None, name="valve",
                                params={"gain": 2.0, "mode": "fast"}))
    row = engine.explain(loop, params={"mode": "slow"})[0]
    assert row.tier == "python"
    assert "parameter 'mode' is a str" in row.reason
    ref = both_engines_agree(loop, np.arange(10) * TS, [0.0], 1.0, params={"mode": "slow"})
    assert ref.outputs[0, 0] == 1.0


def test_a_params_use_not_understood_accepts_every_key_and_runs_as_python():
    def total(t, x, u, params):
        return sum(params.values()) * u[0]

    loop = integrating(ct.nlsys(None, total, inputs="u", outputs="v", dt=None, name="total",
                                params={"a": 1.0}))
    row = engine.explain(loop, params={"b": 2.0})[0]
    assert row.tier == "python" and "params.values" in row.reason
    ref = both_engines_agree(loop, np.arange(5) * TS, [0.0], 1.0, params={"b": 2.0})
    assert ref.outputs[0, 0] == 3.0


# --- the compiled-code cache is the user's own -----------------------------------------------

def test_a_cache_folder_others_can_write_is_not_used(tmp_path, monkeypatch):
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)  # anyone could drop a module there that the engine would import
    monkeypatch.setattr(loader, "CACHE_DIR", shared)
    with pytest.warns(UserWarning, match=r"does not use the compiled-code cache .*shared: it "
                                         r"can be written by others \(mode 777\)"):
        folder = loader.cache_folder()
    assert folder != shared and folder.name.startswith("controlkit-engine-")
    assert folder.stat().st_mode & 0o777 == 0o700
    assert folder.stat().st_uid == shared.stat().st_uid
    kernel, name = usercode.load_kernel(usercode.kernel_source(
        lambda t, x, u, params: 2.0 * u, {}), folder)
    assert (folder / f"{name}.py").exists() and not any(shared.iterdir())


def test_a_cache_folder_that_cannot_be_made_gives_a_private_one_not_a_shared_tmp(
        tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setattr(loader, "CACHE_DIR", blocker / "engine")
    with pytest.warns(UserWarning, match=r"it cannot be created"):
        folder = loader.cache_folder()
    assert folder.name != "controlkit-engine" and folder.name.startswith("controlkit-engine-")
    assert folder.stat().st_mode & 0o777 == 0o700


def test_a_module_file_edited_after_its_import_gives_python_controls_answer(tmp_path):
    # the engine reads a function's source from its file, which an editor may have changed
    # since the import: the compiled version then differs from what runs and the block runs
    # as Python, and its feedthrough is asked of the function, not of the new text (it
    # once came from the text, "reads only x", and the loop lagged by an evaluation)
    import importlib.util

    path = tmp_path / "edited_model.py"
    path.write_text("def controller(t, x, u, params):\n"
                    "    return params['k'] * (u[0] - u[1])\n")
    spec = importlib.util.spec_from_file_location("edited_model", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    path.write_text("def controller(t, x, u, params):\n"
                    "    return params['k'] * x\n")
    plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs="u", outputs="y", name="plant")
    controller = ct.nlsys(None, module.controller, inputs=["r", "y"], outputs="u",
                          params={"k": 2.0}, name="k")
    loop = ct.interconnect([plant, controller], inputs="r", outputs="y")
    T = np.linspace(0.0, 4.0, 81)
    ours = controlkit.input_output_response(loop, T, 1.0, [0.0])
    ref = ct.input_output_response(loop, T, 1.0, [0.0])
    np.testing.assert_allclose(ours.outputs, ref.outputs, rtol=1e-9, atol=1e-12)
    assert engine.explain(loop)[1].tier == "python"
