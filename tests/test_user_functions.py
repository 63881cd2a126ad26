"""User functions written in python-control's idiom compile and give python-control's numbers;
the cases that once gave a wrong answer, crashed or refused valid input do not any more."""

import functools
import heapq
import math
import os
import re
import shutil
import subprocess
import sys
import warnings

import control as ct
import numpy as np
import pytest
import scipy.special
from idiom_diagrams import DIAGRAMS, cruise, expected_tier

import controlkit
from controlkit.engines import fast as engine
from controlkit.engines.fast import run, store
from controlkit.engines.source import used_params
from controlkit.simulation import simulate

ENGINES = ["python-control", "fast"]
TS = 0.05


@pytest.mark.parametrize("name", list(DIAGRAMS))
def test_idiom_diagram_is_compiled_and_equals_python_control(name):
    loop, T, X0, U, params = DIAGRAMS[name]()
    tiers = engine.explain(loop, params=params)
    assert [row.tier for row in tiers] == [expected_tier(name, row.name) for row in tiers]
    assert all("numpy.tan" in row.reason for row in tiers if row.tier == "python"), tiers
    ref = ct.input_output_response(loop, T, U, X0, params=params)
    fast = simulate(loop, T, X0=X0, U=U, params=params, engine="fast")
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.states, ref.states, rtol=0, atol=1e-9)
    assert np.ptp(ref.outputs, axis=1).max() > 0.1  # the loop does something


def compiled_modules():
    """The store's modules, those imported, and the entry points compiled in this process."""
    return ({p.name for p in store.folder().glob("*.py")},
            {m for m in sys.modules if m.startswith("controlkit_store_")},
            {source: set(entries) for source, entries in run._COMPILED.items()})


def test_a_new_parameter_value_compiles_nothing_new():
    loop, T, X0, U, params = cruise(steps=60)  # kaw 1.5, mass 1800 (an int)
    first = simulate(loop, T, X0=X0, U=U, params=params, engine="fast", compile=True)
    assert first.engine_mode == "compiled"
    before = compiled_modules()
    for new in ({"kaw": 0.5, "mass": 1750}, {"kaw": 2.25, "mass": 1200}):
        fast = simulate(loop, T, X0=X0, U=U, params=new, engine="fast", compile=True)
        ref = ct.input_output_response(loop, T, U, X0, params=new)
        np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
        assert fast.engine_mode == "compiled"
        assert compiled_modules() == before
    assert {r.tier for r in engine.explain(loop, params=new)} == {"compiled"}


def test_a_parameter_of_another_type_is_a_module_of_its_own_with_pythons_numbers():
    # an int where a float was, or a key given that had its default, changes what the
    # compiled code does with it (Python's int arithmetic is kept): a new module, compiled
    # once, and Python's numbers
    loop, T, X0, U, params = cruise(steps=60)
    simulate(loop, T, X0=X0, U=U, params=params, engine="fast", compile=True)
    before = compiled_modules()
    new = {"kaw": 3, "mass": 1750.5, "kp": 0.8}
    fast = simulate(loop, T, X0=X0, U=U, params=new, engine="fast", compile=True)
    ref = ct.input_output_response(loop, T, U, X0, params=new)
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
    assert fast.engine_mode == "compiled"
    assert compiled_modules() != before


def integrating(block, **kwargs):
    """``block`` (a static user block from ``u`` to ``v``) feeding a discrete integrator."""
    integrator = ct.ss([[1.0]], [[TS]], [[1.0]], [[0.0]], dt=TS, inputs="v", outputs="y",
                       name="integrator")
    return ct.interconnect([block, integrator], inputs="u", outputs=["v", "y"], **kwargs)


def both_engines_agree(loop, T, X0, U, params=None):
    """python-control's numbers from python-control's path and the fast engine's, its
    module run as Python and, when every block can be, compiled."""
    ref = ct.input_output_response(loop, T, U, X0, params=params, squeeze=False)
    ways = [("python-control", None), ("fast", False)]
    if {row.tier for row in engine.explain(loop, params=params)} == {"compiled"}:
        ways.append(("fast", True))
    for which, compile in ways:
        resp = simulate(loop, T, X0=X0, U=U, params=params, engine=which, compile=compile)
        np.testing.assert_allclose(np.reshape(resp.outputs, ref.outputs.shape), ref.outputs,
                                   rtol=0, atol=1e-12)
        if compile is not None:
            assert resp.engine_mode == ("compiled" if compile else "python")
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
    # the undecorated body was once compiled (inspect.getsource follows __wrapped__):
    # 2.0 here, not 1.5, once u passes 0.75
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


class _MadeByItsClass(type):
    def __call__(cls, *args):
        return "an instance"


class _NotCallable(metaclass=_MadeByItsClass):
    """An object that is not callable, though its class's class has ``__call__``."""


def test_what_a_call_runs_is_what_python_finds_and_nothing_python_would_refuse():
    from controlkit.engines.source.reading import NotCompilable, call_target

    assert call_target(Gain(2.0))[0] is Gain.__call__
    not_callable = object.__new__(_NotCallable)
    assert not callable(not_callable)
    with pytest.raises(NotCompilable, match="it is a _NotCallable, not a Python function"):
        call_target(not_callable)


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


def test_a_store_module_that_fails_to_load_is_not_left_half_loaded(tmp_path, monkeypatch):
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    source = ("import numpy as _np_\nbroken = _np_.float64(1.0) + undefined_name\n\n"
              "def kernel(t, x, u, p, out):\n    return out\n")
    path = store.module_file(source, "user")
    for _ in range(2):  # the second attempt fails the same way, not with AttributeError
        with pytest.raises(NameError, match="undefined_name"):
            store.import_module(path)
    assert f"controlkit_store_{path.stem}" not in sys.modules


def powered(t, x, u, params):
    """2 ** n in integers: past 2 ** 63 for n > 63 (compiled code wraps around, Python's
    integers grow)."""
    return [0.9 * x[0] + min(2 ** int(10 * x[0]) * 1e-21, 0.5)]


def multiplied(t, x, u, params):
    """n ** 4 written as a product: past 2 ** 63 for n > 55 108."""
    n = int(1e5 * x[0])
    return [0.9 * x[0] + min(float(n * n * n * n) * 1e-21, 0.5)]


@pytest.mark.parametrize("update, computes", [(powered, r"2 \*\* int\(10 \* x\[0\]\)"),
                                              (multiplied, r"n \* n \* n \* n")])
def test_integers_that_can_outgrow_64_bits_run_as_python_and_explain_says_so(update,
                                                                             computes):
    block = ct.nlsys(update, None, inputs=0, outputs="y", states=1, dt=TS, name="odd")
    loop = ct.interconnect([block], outputs="y")
    row = engine.explain(loop)[0]
    assert row.tier == "python"
    assert re.search(rf"it computes {computes} with integers, which can outgrow the 64 bits "
                     rf"of compiled code", row.reason), row.reason
    ref = both_engines_agree(loop, np.arange(5) * TS, [7.0], np.zeros((0, 5)))
    assert ref.outputs[0, 1] == pytest.approx(0.9 * 7.0 + 0.5)
    with pytest.warns(UserWarning, match=rf"running 'odd_loop' as Python: block 'odd': it "
                                         rf"computes {computes} with integers"):
        resp = simulate(ct.interconnect([block], outputs="y", name="odd_loop"),
                        np.arange(5) * TS, X0=[7.0], U=np.zeros((0, 5)), engine="fast",
                        compile=True)
    assert resp.engine_mode == "python"
    np.testing.assert_array_equal(np.ravel(resp.outputs), ref.outputs[0])


def stacked(t, x, u, params):  # np.concatenate of a list: numba takes a tuple
    return np.concatenate([x[:1] * -0.5, x[1:] + u[0]])


def switched(t, x, u, params):  # float of a comparison: numba's float takes numbers
    return [0.9 * x[0] + float(u[0] > 0.5) - 0.2 * float(not x[1] > 0.0), 0.5 * x[1] + u[0]]


@pytest.mark.parametrize("update", [stacked, switched])
def test_a_list_of_arrays_and_the_float_of_a_comparison_compile_with_python_s_numbers(update):
    # numba refused both after a compile (0.5-1 s): np.concatenate([a, b]) is written
    # np.concatenate((a, b)), float(u > 0.5) as 1.0 if u > 0.5 else 0.0
    block = ct.nlsys(update, None, inputs="u", outputs=["p", "q"], states=2, dt=TS,
                     name="odd")
    loop = ct.interconnect([block], inputs="u", outputs=["p", "q"])
    assert [row.tier for row in engine.explain(loop)] == ["compiled"]
    T = np.arange(40) * TS
    U = np.where(np.arange(40) % 7 < 3, 1.0, -0.5).reshape(1, -1)
    expected = ct.input_output_response(loop, T, U, [0.3, -0.2])
    for compile in (False, True):
        ours = controlkit.input_output_response(loop, T, U, [0.3, -0.2], compile=compile)
        assert ours.engine_mode == ("compiled" if compile else "python")
        assert ours.outputs.tobytes() == expected.outputs.tobytes()


def remainder(t, x, u, params):
    return [0.9 * x[0] + math.fmod(u[0], 0.3)]


def generated(t, x, u, params):
    return [0.9 * x[0] + sum(u[i] for i in range(1))]


def caught(t, x, u, params):
    try:
        root = math.sqrt(u[0])
    except ValueError:
        root = 0.0
    return [0.9 * x[0] + root]


@pytest.mark.parametrize("update, reason", [
    (remainder, "it calls math.fmod, which numba does not compile"),
    (generated, r"it uses a generator expression \(\(u\[i\] for i in range\(1\)\)\), which "
                r"numba does not compile \(a list comprehension compiles\)"),
    (caught, "it catches ValueError: compiled code \\(numba\\) catches every exception with "
             "'except Exception:', or none")])
def test_what_numba_refuses_runs_as_python_from_the_start_and_explain_says_why(update,
                                                                               reason):
    # explain said "compiled", and compile=True spent 0.4-1 s on numba's refusal first
    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="odd")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    row = engine.explain(loop)[0]
    assert row.tier == "python" and re.search(reason, row.reason), row.reason
    T = np.arange(20) * TS
    with pytest.warns(UserWarning, match=reason):
        ours = controlkit.input_output_response(loop, T, 0.7, 0.1, compile=True)
    assert ours.engine_mode == "python"
    assert np.array_equal(ours.outputs, ct.input_output_response(loop, T, 0.7, 0.1).outputs)


def halving(t, x, u, params):
    return [0.5 * x[0] + u[0]]


def halving_loop(name):
    block = ct.nlsys(halving, None, inputs="u", outputs="y", states=1, dt=TS, name="halving")
    return ct.interconnect([block], inputs="u", outputs="y", name=name)


@pytest.fixture
def compiles_after_a_piece(tmp_path, monkeypatch):
    """An engine that has compiled nothing (an empty store, nothing compiled in this
    process), whose rule compiles after the first piece of a run whatever the timings (a
    deterministic switch), and whose compiled code differs from Python where an input
    exceeds 1000 (its outputs 1e-6 off, relative): what the run-time check is there to
    catch, a difference that reading the functions did not find."""
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    for memory in ("_COMPILED", "_TWINS", "CHECKED", "DIFFERS"):  # of modules compiled here
        if hasattr(run, memory):
            monkeypatch.setattr(run, memory, type(getattr(run, memory))())
    monkeypatch.setattr(run, "PIECE_SECONDS", 0.0)
    monkeypatch.setattr(run, "PAYS", 0.0)
    monkeypatch.setattr(run, "PYTHON_CONTROL_SLOWER", 1e9)  # (any call may compile)
    decide = run.Runner.decide

    def after_the_first_piece(runner, elapsed, done):  # (the run's start its piece before)
        runner.last = runner.last or (0.0, 0.0)
        return decide(runner, elapsed, done)

    monkeypatch.setattr(run.Runner, "decide", after_the_first_piece)
    entry = run.Job.entry

    def differing_entry(job, name, args):
        compiled = entry(job, name, args)
        assert name == "run_discrete"

        def differing(T, X0, U, P, Y, X, status, k0, k1):
            x = compiled(T, X0, U, P, Y, X, status, k0, k1)
            Y[:, k0:k1] *= np.where(U[:, k0:k1].max(axis=0) > 1e3, 1.0 + 1e-6, 1.0)
            return x

        return differing

    monkeypatch.setattr(run.Job, "entry", differing_entry)


def test_a_compiled_module_whose_numbers_differ_from_python_is_left_for_python(
        compiles_after_a_piece):
    # the run's rule compiles a module and runs one piece both ways before it goes on
    # compiled: here they differ, and the run goes on as Python, saying so
    loop = halving_loop("differs")
    T = np.arange(300) * TS
    ref = ct.input_output_response(loop, T, 1e6, [0.0])
    with pytest.warns(UserWarning, match=r"'differs' runs as Python: its compiled numbers "
                                         r"differ from Python's between t = 3\.2 and"):
        resp = simulate(loop, T, X0=[0.0], U=1e6, engine="fast")
    assert resp.engine_mode == "python"
    np.testing.assert_array_equal(resp.outputs, ref.outputs)
    again = simulate(loop, T, X0=[0.0], U=1e6, engine="fast")  # no second compile or check
    assert again.engine_mode == "python"
    np.testing.assert_array_equal(again.outputs, ref.outputs)


def test_a_compiled_module_whose_numbers_agree_goes_on_compiled(compiles_after_a_piece):
    loop = halving_loop("agrees")
    T = np.arange(300) * TS
    resp = simulate(loop, T, X0=[0.0], U=1.0, engine="fast")
    assert resp.engine_mode == "compiled"
    np.testing.assert_array_equal(resp.outputs,
                                  ct.input_output_response(loop, T, 1.0, [0.0]).outputs)


PARTIAL_TANH = functools.partial(np.tanh)


@pytest.mark.parametrize("output, said", [
    (lambda t, x, u, p: scipy.special.erf(u[0]), "it reads 'erf', a ufunc, which numba"),
    (lambda t, x, u, p: math.log(1.0 + u[0] ** 2, 10),
     "it calls math.log(..., ...): its compiled form takes (x) only"),
    (lambda t, x, u, p: PARTIAL_TANH(u[0]),
     "it uses PARTIAL_TANH: it is a ufunc, not a Python function")],
    ids=["scipy's ufunc", "math.log with a base", "a partial of a ufunc"])
def test_a_block_s_reason_is_in_the_words_the_user_wrote(output, said):
    # a review read "it reads 'scipy_0'" (the frozen value's name), "math.log(1.0 +
    # _ck_power(u[0], 2), 10)" (the text as rewritten), and a reason naming nothing
    (row,) = controlkit.explain(ct.nlsys(None, output, inputs=1, outputs=1, name="shaper"))
    assert row.tier == "python" and row.reason.startswith(said), row.reason


def test_explain_says_a_transfer_function_alone_is_python_control_s():
    # python-control's input_output_response refuses one (explain said "compiled"); the
    # MIMO one's conversion needs slycot, and explain raised its error
    siso = ct.tf([1.0], [1.0, 2.0, 1.0], name="H")
    mimo = ct.tf([[[1.0], [2.0]], [[1.0, 1.0], [1.0]]],
                 [[[1.0, 1.0], [1.0, 3.0]], [[1.0, 2.0, 1.0], [1.0, 4.0]]], name="G")
    for system in (siso, mimo):
        (row,) = controlkit.explain(system)
        assert row.tier == "python-control" and "ct.ss(sys) runs" in row.reason, row


def test_explain_says_why_a_diagram_whose_compiled_numbers_differed_runs_as_python(
        compiles_after_a_piece):
    loop = halving_loop("differs")
    with pytest.warns(UserWarning, match="its compiled numbers differ"):
        simulate(loop, np.arange(300) * TS, X0=[0.0], U=1e6, engine="fast")
    assert any("compiled numbers differ" in row.reason for row in engine.explain(loop))


def test_compile_true_never_gives_a_number_python_would_not(compiles_after_a_piece):
    loop = halving_loop("differs")
    T = np.arange(300) * TS
    ref = ct.input_output_response(loop, T, 1e6, [0.0])
    with pytest.warns(UserWarning, match=r"'differs' runs as Python: its compiled numbers "
                                         r"differ from Python's"):
        resp = simulate(loop, T, X0=[0.0], U=1e6, engine="fast", compile=True)
    assert resp.engine_mode == "python"
    np.testing.assert_array_equal(resp.outputs, ref.outputs)


def test_a_module_compiled_on_one_run_is_not_trusted_blindly_on_the_next(
        compiles_after_a_piece):
    # inputs of 1: the check agrees and the module is kept compiled; the next process,
    # loading it, has inputs where compiled code differs (a process checks a module once:
    # its first compiled piece, here emptied as a new process has it)
    loop = halving_loop("differs")
    T = np.arange(300) * TS
    assert simulate(loop, T, X0=[0.0], U=1.0, engine="fast").engine_mode == "compiled"
    assert len(run.CHECKED) == 1
    run.CHECKED.clear()
    ref = ct.input_output_response(loop, T, 1e6, [0.0])
    with pytest.warns(UserWarning, match="its compiled numbers differ from Python's"):
        resp = simulate(loop, T, X0=[0.0], U=1e6, engine="fast")
    assert resp.engine_mode == "python"
    np.testing.assert_array_equal(resp.outputs, ref.outputs)


def test_a_module_the_rule_chose_at_a_chunk_s_end_is_checked_on_the_next_chunk(
        compiles_after_a_piece, monkeypatch):
    # a streamed run's rule chose the compiled module after a chunk's last piece: its check
    # ran on a piece of no steps there, compared nothing, and the module went on unchecked,
    # with other numbers than Python's and no warning (found by a review)
    from controlkit.engines.contract import recorded_indices
    from controlkit.engines.fast import discrete

    monkeypatch.setattr(discrete, "STREAM_CHUNK_STEPS", 64)  # (a chunk: the first piece)
    for memory in ("PYTHON_SECONDS", "PYTHON_POINTS"):  # (no earlier run: decided after it)
        monkeypatch.setattr(run, memory, {})
    loop = halving_loop("differs")
    T = np.arange(300) * TS
    ref = ct.input_output_response(loop, T, 1e6, [0.0])
    with pytest.warns(UserWarning, match=r"its compiled numbers differ from Python's between "
                                         r"t = 3\.2 and"):
        resp = simulate(loop, T, X0=[0.0], U=1e6, engine="fast", record_every=2)
    assert resp.engine_mode == "python"
    np.testing.assert_array_equal(np.ravel(resp.outputs),
                                  np.ravel(ref.outputs)[recorded_indices(300, 2)])


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
    for which, compile in (("python-control", None), ("fast", False), ("fast", True)):
        with pytest.raises(ZeroDivisionError, match="float division by zero"):
            simulate(loop, np.arange(3) * TS, X0=[0.0], U=np.zeros((0, 3)), engine=which,
                     compile=compile)


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


# --- the store is the user's own --------------------------------------------------------------

needs_root = pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() != 0,
                                reason="giving a file to another user needs root")


def _private(path):
    path.mkdir(parents=True, exist_ok=True)
    path.chmod(0o700)
    return path


def _shared(tmp_path):
    shared = _private(tmp_path / "shared")
    shared.chmod(0o777)  # anyone could drop a module there that the engine would import
    return shared


def _linked(tmp_path):
    link = tmp_path / "link"
    link.symlink_to(_private(tmp_path / "real"))
    return link


def _through_a_strangers_link(tmp_path):
    link = tmp_path / "theirs"
    link.symlink_to(_private(tmp_path / "real"))
    os.lchown(link, 4321, 4321)  # a link another user could point elsewhere
    return _private(link / "store")


def _under_a_strangers_folder(tmp_path):
    theirs = _private(tmp_path / "theirs")
    os.chown(theirs, 4321, 4321)  # who could rename the store away
    return _private(theirs / "store")


def _under_a_folder_others_can_write(tmp_path):
    open_to_all = _private(tmp_path / "open")
    open_to_all.chmod(0o777)
    return _private(open_to_all / "store")


def _a_file(tmp_path):
    (tmp_path / "file").write_text("")
    return tmp_path / "file"


@pytest.mark.parametrize("make, reason", [
    (_shared, r"shared can be written by others \(mode 777\)"),
    (_linked, r"link is a link \(give the folder itself\)"),
    pytest.param(_through_a_strangers_link, r"theirs is a link owned by another user "
                                            r"\(uid 4321\)", marks=needs_root),
    pytest.param(_under_a_strangers_folder, r"theirs is owned by another user \(uid 4321\)",
                 marks=needs_root),
    (_under_a_folder_others_can_write, r"open can be written by others \(mode 777\), who "
                                       r"could replace the folder"),
])
def test_a_store_that_is_not_the_users_own_is_refused(tmp_path, monkeypatch, make, reason):
    path = make(tmp_path)
    assert re.search(reason, store.not_own(path))
    monkeypatch.setattr(store, "CACHE_DIR", path)
    with pytest.raises(store.StoreRefused, match=r"controlkit compiles nothing: .*" + reason
                       + r".* \(set CONTROLKIT_CACHE_DIR to a folder of your own\)"):
        store.folder()


def _through_my_own_link(tmp_path):
    link = tmp_path / "mine"
    link.symlink_to(_private(tmp_path / "real"))  # as /home -> /data/home
    return _private(link / "store")


def _under_a_sticky_folder(tmp_path):
    shared_tmp = _private(tmp_path / "tmp")
    shared_tmp.chmod(0o1777)  # as /tmp: others write there but cannot rename what is mine
    return _private(shared_tmp / "store")


def _open_to_my_private_group(tmp_path):
    import grp

    group = grp.getgrgid(os.getgid())
    if group.gr_mem:
        pytest.skip(f"the group {group.gr_name} has other members")
    store_folder = _private(tmp_path / "store")
    store_folder.chmod(0o770)  # a umask of 002 with a group of one's own (user private groups)
    return store_folder


@pytest.mark.parametrize("make", [_private, _through_my_own_link, _under_a_sticky_folder,
                                  _open_to_my_private_group])
def test_a_store_of_the_users_own_is_used(tmp_path, monkeypatch, make):
    path = make(tmp_path / "store") if make is _private else make(tmp_path)
    assert store.not_own(path) is None
    monkeypatch.setattr(store, "CACHE_DIR", path)
    assert store.folder() == path


def test_a_store_open_to_a_shared_primary_group_is_refused(tmp_path, monkeypatch):
    # a course server's primary group "students" lists no members either (they have it
    # from /etc/passwd): it was taken for a private group, and a classmate could plant
    # the numba cache files that the next session unpickles
    import grp
    import types

    store_folder = _private(tmp_path / "store")
    store_folder.chmod(0o770)
    shared = types.SimpleNamespace(gr_name="students", gr_mem=[], gr_gid=os.getgid())
    monkeypatch.setattr(grp, "getgrgid", lambda gid: shared)
    assert store.not_own(store_folder).endswith("can be written by others (mode 770)")


def test_a_refused_store_runs_the_diagram_as_python_and_writes_nothing_there(
        tmp_path, monkeypatch):
    shared = _shared(tmp_path)
    monkeypatch.setattr(store, "CACHE_DIR", shared)
    loop = integrating(ct.nlsys(None, clipped_gain, inputs="u", outputs="v", dt=None,
                                name="gain"), name="refused")
    T = np.arange(20) * TS
    with pytest.warns(UserWarning, match=r"running 'refused' as Python: controlkit compiles "
                                         r"nothing: .*shared can be written by others"):
        resp = simulate(loop, T, X0=[0.0], U=1.0, engine="fast", compile=True)
    assert resp.engine_mode == "python"
    np.testing.assert_array_equal(resp.outputs,
                                  ct.input_output_response(loop, T, 1.0, [0.0]).outputs)
    assert not any(shared.iterdir())


def test_numbas_cache_folder_is_checked_as_the_store_is(tmp_path, monkeypatch):
    monkeypatch.setattr(store, "CACHE_DIR", _private(tmp_path / "store"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(_shared(tmp_path)))
    with pytest.raises(store.StoreRefused, match=r"numba's cache folder .*shared: .*can be "
                                                 r"written by others"):
        store.folder()
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(_private(tmp_path / "numba")))
    assert store.folder() == tmp_path / "store"
    # one not made yet is made now, the user's own (numba would make it after the check)
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "later" / "numba"))
    assert store.folder() == tmp_path / "store"
    assert (tmp_path / "later" / "numba").stat().st_mode & 0o777 == 0o700


def test_numbas_cache_folder_is_checked_as_numba_reads_it(tmp_path, monkeypatch):
    # a .numba_config.yaml in the current folder (a course's folder, a cloned assignment)
    # sets numba's cache folder where the variable says nothing, read again at each
    # compile: a review had another user's pickle there run at the next load
    numba = pytest.importorskip("numba")
    monkeypatch.setattr(store, "CACHE_DIR", _private(tmp_path / "store"))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    course = _private(tmp_path / "course")
    (course / ".numba_config.yaml").write_text(f"cache_dir: {_shared(tmp_path)}\n")
    monkeypatch.chdir(course)  # (after numba's import: its next compile reads it)
    try:
        with pytest.raises(store.StoreRefused, match=r"numba's cache folder .*shared: .*can "
                                                     r"be written by others"):
            store.numba_checked()
    finally:
        monkeypatch.undo()
        numba.config.reload_config()


def _acl(*entries):
    """A POSIX access control list as Linux keeps it in an extended attribute."""
    import struct

    return struct.pack("<I", 2) + b"".join(struct.pack("<HHI", *entry) for entry in entries)


_ANY = 0xFFFFFFFF
#: user::rwx, user:4321:<perm>, group::---, mask::rwx, other::---
_LETS_4321 = lambda perm: _acl((0x01, 7, _ANY), (0x02, perm, 4321), (0x04, 0, _ANY),  # noqa: E731
                               (0x10, 7, _ANY), (0x20, 0, _ANY))


@pytest.mark.parametrize("attribute, perm, reason", [
    ("system.posix_acl_access", 7, r"store can be written by others \(an access control list"),
    ("system.posix_acl_default", 7, r"store gives what is made in it to others to write"),
    ("system.posix_acl_access", 5, None),  # another user may read: the store is still mine
])
def test_a_store_an_access_control_list_opens_to_others_is_refused(tmp_path, attribute, perm,
                                                                   reason):
    # the mode shows only the list's mask (drwxrwx---): a course folder's default list
    # (setfacl -d -m u:ta:rwx) gave a review's other user the store, and numba's pickles
    folder = _private(tmp_path / "store")
    try:
        os.setxattr(folder, attribute, _LETS_4321(perm))
    except OSError as error:
        pytest.skip(f"no access control lists on this file system ({error})")
    if reason is None:
        assert store.not_own(folder) is None
    else:
        assert re.search(reason, store.not_own(folder))


def test_a_store_folder_is_made_private_and_one_that_cannot_be_made_is_refused(
        tmp_path, monkeypatch):
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "new" / "store")
    folder = store.folder()
    assert folder == tmp_path / "new" / "store" and folder.stat().st_mode & 0o777 == 0o700
    assert store.not_own(_a_file(tmp_path)).endswith("file is not a folder")
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "file")
    with pytest.raises(store.StoreRefused, match=r"the store .*file cannot be created "
                                                 r"\(File exists\)"):
        store.folder()
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "file" / "store")
    with pytest.raises(store.StoreRefused, match=r"the store .*file/store cannot be created "
                                                 r"\(Not a directory\)"):
        store.folder()


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
    ours = controlkit.input_output_response(loop, T, 1.0, [0.0], compile=False)
    ref = ct.input_output_response(loop, T, 1.0, [0.0])
    np.testing.assert_allclose(ours.outputs, ref.outputs, rtol=1e-9, atol=1e-12)
    assert engine.explain(loop)[1].tier == "python"


def test_an_imported_helper_s_frozen_globals_name_the_kernel(tmp_path, monkeypatch):
    # numba freezes what a compiled helper reads by global name (a tuple, a module's
    # attribute) into the code kept in its cache; the kernel that imports the helper names
    # those values, so that an edit of them is a new kernel, not the old code found again
    # (a new process once got the edited file's helper with the old tuple's numbers)
    import importlib

    from controlkit.engines.source.runs import runs as _runs

    monkeypatch.syspath_prepend(str(tmp_path))

    def forget_bytecode():  # a file rewritten within its second at the same size would
        shutil.rmtree(tmp_path / "__pycache__", ignore_errors=True)  # load its old bytecode
        importlib.invalidate_caches()

    def helper_digest(table, gain):
        (tmp_path / "frozen_consts.py").write_text(f"G = {gain!r}\n")
        (tmp_path / "frozen_helper.py").write_text(
            "import frozen_consts\n\n"
            f"TABLE = {table!r}\n\n"
            "def gain(e):\n"
            "    return TABLE[0][1] * frozen_consts.G * e\n")
        for name in ("frozen_consts", "frozen_helper"):
            sys.modules.pop(name, None)
        forget_bytecode()
        return _runs(importlib.import_module("frozen_helper").gain)

    first = helper_digest(((1.0, 2.0), 3), 2.0)
    assert helper_digest(((1.0, 2.0), 3), 2.0) == first
    assert helper_digest(((1.0, 2.5), 3), 2.0) != first  # a value in a nested tuple
    assert helper_digest(((1.0, 2.0), 3), 4.0) != first  # a module's attribute it reads

    def defaults_and_enum(k, boost):
        (tmp_path / "frozen_enum.py").write_text(
            "import enum\n\n"
            f"class Mode(enum.IntEnum):\n    BOOST = {boost}\n\n"
            f"def gain(e, k={k!r}):\n    return k * Mode.BOOST * e\n")
        sys.modules.pop("frozen_enum", None)
        forget_bytecode()
        return _runs(importlib.import_module("frozen_enum").gain)

    first = defaults_and_enum(2.0, 2)
    assert defaults_and_enum(2.0, 2) == first
    assert defaults_and_enum(3.0, 2) != first  # a default argument
    assert defaults_and_enum(2.0, 3) != first  # an enumeration's member
    sys.modules.pop("frozen_enum", None)
    for name in ("frozen_consts", "frozen_helper"):
        sys.modules.pop(name, None)


def test_a_numba_helper_compiled_before_leaves_its_block_to_python():
    # numba froze what the helper read (k = 2) when it was first called; its source, compiled
    # again into a kernel, read k as it is now (3): 6.0 against python-control's 4.0
    numba = pytest.importorskip("numba")
    k = 2.0

    @numba.njit
    def helper(t, x):
        return k * x if t >= 3.0 else x

    assert helper(4.0, 2.0) == 4.0
    k = 3.0  # noqa: F841 - read by the helper's closure, which numba froze at 2.0
    block = ct.nlsys(lambda t, x, u, p: [0.5 * x[0] + 1.0],
                     lambda t, x, u, p: [helper(t, x[0])], inputs="u", outputs="y",
                     states=1, dt=1.0, name="late")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    assert engine.explain(loop)[0].tier == "python"
    assert "numba froze then what it reads (k)" in engine.explain(loop)[0].reason
    T = np.arange(6.0)
    with pytest.warns(UserWarning, match="as Python: block .late.: it calls .helper."):
        ours = controlkit.input_output_response(loop, T, 0.0, [0.0], compile=True)
    np.testing.assert_array_equal(ours.outputs, ct.input_output_response(loop, T, 0.0,
                                                                         [0.0]).outputs)


@pytest.mark.parametrize("value", [np.array([10**6], dtype=np.int32),
                                   np.array([0.1], dtype=np.float32), np.float16(0.5)])
def test_a_value_numpy_keeps_under_64_bits_leaves_its_block_to_python(value):
    # numpy computes in an int32 or a float32 (a product wraps, or rounds to 24 bits),
    # compiled code in 64 bits: the numbers part ways, maybe only late in a run, where the
    # check piece does not look (an int32 product: 3.0e9 against numpy's -1.3e9 at the end)
    def output(t, x, u, params):
        return value[0] * 1000 * u[0] if np.ndim(value) else value * u[0]

    block = ct.nlsys(None, output, inputs="u", outputs="y", name="narrow", dt=1.0)
    loop = ct.interconnect([block], inputs="u", outputs="y")
    rows = engine.explain(loop)
    assert rows[0].tier == "python"
    assert re.search(r"of type (int32|float32|float16): numpy computes in it, compiled code "
                     r"in 64 bits", rows[0].reason)


def test_an_enumeration_s_member_read_by_a_user_function_compiles_as_its_number():
    import enum

    class Mode(enum.IntEnum):
        BOOST = 3

    boost = Mode.BOOST

    def output(t, x, u, params):
        return boost * u[0]

    # (a state kept: a diagram without states is python-control's own to run)
    block = ct.nlsys(lambda t, x, u, p: x, output, inputs="u", outputs="y", states=1,
                     name="boost", dt=1.0)
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.arange(5.0)
    ours = controlkit.input_output_response(loop, T, np.ones(5), compile=True)
    assert ours.engine_mode == "compiled"
    np.testing.assert_array_equal(ours.outputs,
                                  ct.input_output_response(loop, T, np.ones(5)).outputs)


@pytest.mark.parametrize("dt", [0, 1.0])
def test_a_function_writing_into_its_arguments_is_left_to_python_control(dt):
    # python-control hands a block views of its own arrays: what a function that writes
    # into them computes depends on those arrays (x += 1 gave 1.0 against 2.0, in Python
    # as compiled), so python-control runs such a diagram itself, with a warning
    def update(t, x, u, params):
        x += 0.1 * u[0]
        return 0.5 * x

    plant = ct.nlsys(update, None, inputs="u", outputs="y", states=1, name="mutating", dt=dt)
    loop = ct.interconnect([plant], inputs="u", outputs="y")
    T = np.arange(20.0) if dt else np.linspace(0.0, 2.0, 21)
    with pytest.warns(UserWarning, match="it writes into its argument 'x'; python-control "
                                         "runs the diagram"):
        ours = controlkit.input_output_response(loop, T, 1.0, [1.0], compile=False)
    assert ours.engine_mode == "python-control"
    np.testing.assert_array_equal(ours.outputs,
                                  ct.input_output_response(loop, T, 1.0, [1.0]).outputs)


_MEMORY = np.zeros(1)


def _remember(buffer, value):
    old = buffer[0]
    buffer[0] = value
    return old


def _through_a_view(t, x, u, params):
    xs = x[:]
    xs[0] = min(max(xs[0], -0.5), 0.5)
    return [xs[0] + 0.1 * u[0]]


def _through_a_name(t, x, u, params):
    dx = x
    dx[0] = 0.5 * x[0] + u[0]
    return dx


def _through_asarray(t, x, u, params):
    state = np.asarray(x).reshape(-1)
    state *= 0.5
    return state + u[0]


def _into_the_input(t, x, u, params):
    w = u
    w[0] = min(w[0], 0.2)
    return 0.9 * x + w[0]


def _through_out(t, x, u, params):
    np.clip(0.9 * x + u[0], -0.5, 0.5, out=x)
    return x


def _memory_by_alias(t, x, u, params):
    m = _MEMORY
    old = m[0]
    m[0] = u[0]
    return [0.5 * x[0] + u[0] - old]


def _memory_in_params(t, x, u, params):
    buffer = params["buffer"]
    old = buffer[0]
    buffer[0] = u[0]
    return [0.5 * x[0] + u[0] - old]


def _memory_by_helper(t, x, u, params):
    return [0.5 * x[0] + u[0] - _remember(_MEMORY, u[0])]


def _memory_by_copyto(t, x, u, params):
    old = _MEMORY[0]
    np.copyto(_MEMORY, u)
    return [0.5 * x[0] + u[0] - old]


@pytest.mark.parametrize("update", [_through_a_view, _through_a_name, _through_asarray,
                                    _into_the_input, _through_out, _memory_by_alias,
                                    _memory_in_params, _memory_by_helper, _memory_by_copyto])
@pytest.mark.parametrize("dt", [0, 0.1])
def test_writes_through_a_name_a_view_or_a_helper_are_seen(update, dt):
    # a review found writes that the check of `x[0] = ...` did not see: through a name
    # bound to the argument or to an outside array (xs = x[:], m = MEMORY), numpy's out=
    # and copyto, a helper writing into what it is given; explain said "compiled", and
    # every mode answered other numbers than python-control (98 of 100 outputs)
    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, name="b", dt=dt,
                     params={"buffer": _MEMORY})
    loop = ct.interconnect([block], inputs="u", outputs="y")
    (row,) = controlkit.explain(loop)
    assert row.tier == "python-control", row
    T = np.arange(60) * 0.1
    _MEMORY[:] = 0.0
    expected = ct.input_output_response(loop, T, np.sin(T), [0.3])
    for compile in (None, True, False):
        _MEMORY[:] = 0.0
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ours = controlkit.input_output_response(loop, T, np.sin(T), [0.3], compile=compile)
        np.testing.assert_array_equal(ours.outputs, expected.outputs)


def _copied_then_written(t, x, u, params):
    xs = x.copy()
    xs[0] = min(xs[0], 0.5)
    v = x[0]
    v += 0.1 * u[0]
    out = np.zeros_like(x)
    out[0] = 0.5 * xs[0] + v
    for row in GAIN_ROW:
        out[0] += 0.0 * row[0]
    return out


def _filled_from_the_state(t, x, u, params):  # (dx[0] = x[0] binds nothing to x)
    dx = np.zeros_like(x)
    dx[0] = x[0]
    dx[0] -= 0.1 * dx[0] - 0.1 * u[0]
    return dx


def _local_numbers_changed(t, x, u, params):
    k = params.get("k", 1.0)
    k *= 0.5
    t -= 1.0
    return [k * x[0] + 0.1 * u[0] + 0.0 * t]


def _wrapped(theta):
    theta -= 2 * math.pi if theta > math.pi else 0.0
    return theta


def _packed(a, b):
    out = np.empty(2)
    out[0], out[1] = a, b
    return out


def _helpers_on_elements(t, x, u, params):
    return [0.9 * _wrapped(x[0]) + 0.1 * _packed(u[0], x[0])[0]]


@pytest.mark.parametrize("update", [_copied_then_written, _filled_from_the_state,
                                    _local_numbers_changed, _helpers_on_elements])
def test_writes_into_the_function_s_own_arrays_compile(update):
    # what a function binds to copies or new arrays (x.copy(), np.zeros_like(x), an
    # element x[0]) is its own to write into; a number's `k *= 0.5` binds it anew (a
    # review found 21 of 76 such functions sent to python-control)
    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, name="own", dt=0.1,
                     params={"k": 2.0})
    loop = ct.interconnect([block], inputs="u", outputs="y")
    (row,) = controlkit.explain(loop)
    assert row.tier == "compiled", row


class _Counter:
    n = 0.0


_COUNTER, _HEAP = _Counter(), []


def _bump(v):
    v[0] += 0.01
    return 0.0


def _bump_deep(v, depth=3):
    return _bump(v) if depth == 0 else _bump_deep(v, depth - 1)


class _Clamped:
    def __init__(self):
        self.rng = np.random.default_rng(5)

    def _clamp(self, v):
        v[0] = min(v[0], 1.0)
        return v

    def clamped(self, t, x, u, params):
        return self._clamp(x)

    def noisy(self, t, x, u, params):
        return [x[0] + 0.01 * self.rng.normal()]


@pytest.mark.parametrize("output", [
    _Clamped().clamped, _Clamped().noisy,
    lambda t, x, u, p: [x[0] + 0.0 * setattr(_COUNTER, "n", _COUNTER.n + 1.0)],
    lambda t, x, u, p: [x[0] + 0.0 * len([heapq.heappush(_HEAP, float(t))])],
    lambda t, x, u, p: np.multiply(x, 1.01, x),
    lambda t, x, u, p: [x[0] + _bump_deep(x)],
    lambda t, x, u, p: [x[0] + 0.01 * _RNG.normal()],
], ids=["a method's helper", "a method's draw", "setattr", "heappush",
        "ufunc output by position", "helper four deep", "random draw"])
def test_an_output_function_acting_outside_itself_otherwise_is_seen(output):
    # python-control calls an output function several times a step: a review's output
    # functions that changed state or drew numbers there answered otherwise
    block = ct.nlsys(lambda t, x, u, p: [0.5 * x[0] + 0.1 * u[0] + 0.01 * _COUNTER.n],
                     output, inputs="u", outputs="y", states=1, name="b", dt=0.1)
    loop = ct.interconnect([block], inputs="u", outputs="y")
    (row,) = controlkit.explain(loop)
    assert row.tier == "python-control", row


class _Damper:
    def __init__(self):
        self.k, self.reads = 0.5, 0

    @property
    def counted(self):  # a getter that changes its object: each read gives a new value
        self.reads += 1
        return self.k + 1e-3 * self.reads

    @property
    def doubled(self):
        return 2.0 * self.k

    def counting(self, t, x, u, params):
        return -self.counted * x + u

    def plain(self, t, x, u, params):
        return -self.doubled * x + u


def test_a_property_whose_getter_changes_its_object_is_read_as_python_control_reads_it():
    # compile=True read such a getter at plan time and at each check, and compiled its
    # value once: another answer than python-control's, which runs it at each call
    T = np.linspace(0.0, 2.0, 41)
    answers = []
    for respond in (ct.input_output_response, functools.partial(
            controlkit.input_output_response, compile=True)):
        damper = _Damper()
        plant = ct.nlsys(damper.counting, None, inputs=1, outputs=1, states=1, name="p")
        with warnings.catch_warnings(record=True) as said:
            warnings.simplefilter("always")
            answers.append((respond(plant, T, np.ones_like(T), [0.0]).outputs, damper.reads))
    assert np.array_equal(answers[0][0], answers[1][0]) and answers[0][1] == answers[1][1]
    assert "whose getter changes self" in str(said[0].message)
    (row,) = controlkit.explain(plant)
    assert row.tier == "python-control"
    assert "it reads self.counted, whose getter changes self" in row.reason
    (row,) = controlkit.explain(ct.nlsys(_Damper().plain, None, inputs=1, outputs=1,
                                         states=1, name="p"))
    assert row.tier == "compiled", row


@pytest.mark.parametrize("output", [lambda t, x, u, p: round(10 * x[0]),
                                    lambda t, x, u, p: x[0] > 0.2,
                                    lambda t, x, u, p: np.float32(x[0]),
                                    lambda t, x, u, p: x[0] + 0j],
                         ids=["int", "bool", "float32", "complex"])
def test_a_system_alone_returning_other_numbers_than_floats_answers_as_python_control(output):
    # python-control makes a system alone's response of what its functions return: ints,
    # bools, float32 and complex numbers stay so (the engine's arrays held floats, and a
    # complex output lost its imaginary part)
    block = ct.nlsys(lambda t, x, u, p: [0.9 * x[0] + 0.1 * u[0]], output, inputs=1,
                     outputs=1, states=1, dt=0.1, name="lone")
    T = np.arange(50) * 0.1
    expected = ct.input_output_response(block, T, np.sin(T), [0.1])
    for compile in (True, False):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ours = controlkit.input_output_response(block, T, np.sin(T), [0.1],
                                                    compile=compile)
        assert ours.outputs.dtype == expected.outputs.dtype
        np.testing.assert_array_equal(ours.outputs, expected.outputs)


@pytest.mark.parametrize("lone", [True, False])
def test_a_float32_initial_state_of_a_discrete_run_answers_as_python_control(lone):
    # python-control's first step computes in X0's float32 (0.9 * x[0] stays float32),
    # the engine in 64 bits: 52 of 200 states apart, from the second
    plant = ct.nlsys(lambda t, x, u, p: [0.9 * x[0] + 0.2 * u[0]], lambda t, x, u, p: x[0],
                     dt=0.1, inputs="u", outputs="y", states=1, name="plant")
    error = ct.summing_junction(["r", "-y"], "u", dt=0.1, name="error")
    system = plant if lone else ct.interconnect([plant, error], inputs="r", outputs="y")
    T = np.arange(200) * 0.1
    X0 = np.array([0.1], dtype=np.float32)
    expected = ct.input_output_response(system, T, 1.0, X0)
    for compile in (True, False):
        with pytest.warns(UserWarning, match="X0 holds float32 numbers"):
            ours = controlkit.input_output_response(system, T, 1.0, X0, compile=compile)
        np.testing.assert_array_equal(ours.states, expected.states)


GAIN_ROW = np.array([[0.0596767275019363, -0.03379733760894157]])
_RNG = np.random.default_rng(3)


def appended_and_returned(t, x, u, params):
    values = []
    for key in ("a", "b"):
        values.append(params[key])
    a, b = values
    return np.array([x[0] + TS * (a * x[1] - b * x[0] ** 2), 1])  # an int among floats


def one_row_feedback(t, x, u, params):
    return -GAIN_ROW @ (u - np.array([20.5, 29.5])) + x[0]


def test_one_row_products_lists_and_returned_arrays_give_python_controls_numbers():
    # numba's own `K @ v` for a one-row K is BLAS's gemv, numpy's (python-control's) its
    # dot product: their last bits differ a third of the time; the list built by appends
    # and the returned array are tuples in the compiled kernel
    plant = ct.nlsys(appended_and_returned, None, inputs="v", outputs=["p", "one"],
                     states=2, dt=TS, name="plant", params={"a": 0.7, "b": 0.3})
    feedback = ct.nlsys(one_row_feedback, lambda t, x, u, params: x[0], inputs=["p", "one"],
                        outputs="v", states=1, dt=TS, name="feedback")
    loop = ct.interconnect([plant, feedback], inputs=[], outputs=["p", "v"])
    T = np.arange(400) * TS
    X0 = [20.0, 1.3, 0.1]
    ref = ct.input_output_response(loop, T, np.zeros((0, T.size)), X0)
    ours = controlkit.input_output_response(loop, T, np.zeros((0, T.size)), X0,
                                            compile=True)
    assert ours.engine_mode == "compiled"
    np.testing.assert_array_equal(ours.outputs, ref.outputs)
    np.testing.assert_array_equal(ours.states, ref.states)


def appended_then_set(t, x, u, params):
    values = []
    values.append(x[0])
    values.append(params["k"])
    values[0] += TS * u[0]  # set after the appends: stays a list
    growth, k = [], []
    growth.append(values[0])
    k.append(values[1])
    return [growth[0] * (1.0 - TS * k[0]), len(values)]


def test_a_list_built_by_appends_then_set_compiles_as_a_list():
    block = ct.nlsys(appended_then_set, None, inputs="u", outputs=["y", "n"], states=2,
                     dt=TS, name="block", params={"k": 0.4})
    loop = ct.interconnect([block], inputs="u", outputs=["y", "n"])
    T = np.arange(50) * TS
    ref = ct.input_output_response(loop, T, np.sin(T), [1.0, 0.0])
    ours = controlkit.input_output_response(loop, T, np.sin(T), [1.0, 0.0], compile=True)
    assert ours.engine_mode == "compiled"
    np.testing.assert_array_equal(ours.outputs, ref.outputs)


KEYS_READ = ["k1", "k2"]


def test_a_list_of_keys_changed_in_place_is_read_again():
    # the loop over KEYS_READ is written out one copy per key: after an append, the same
    # diagram run again in the process answered with the old keys (0.6 against 1.4)
    def output(t, x, u, p):
        total = 0.0
        for name in KEYS_READ:
            total += p[name]
        return total * u[0]

    block = ct.nlsys(lambda t, x, u, p: x, output, inputs="u", outputs="y", states=1,
                     dt=1.0, name="keyed", params={"k1": 0.1, "k2": 0.2, "k3": 0.4})
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.arange(4.0)
    try:
        for edit in (lambda: None, lambda: KEYS_READ.append("k3"),
                     lambda: KEYS_READ.__setitem__(0, "k3")):
            edit()
            ours = controlkit.input_output_response(loop, T, 2.0, compile=True)
            assert ours.engine_mode == "compiled"
            np.testing.assert_array_equal(ours.outputs,
                                          ct.input_output_response(loop, T, 2.0).outputs)
    finally:
        KEYS_READ[:] = ["k1", "k2"]


def single_precision(t, x, u, params):  # numpy 2 keeps a float32 (NEP 50), numba does not
    return [0.9 * x[0] + np.float32(u[0]) * 2.0 + 1.0]


def fixed_point(t, x, u, params):  # numpy wraps an int16 product, numba widens it
    return [0.5 * x[0] + float(np.int16(u[0] * 1000.0) * np.int16(30))]


def summed_over_an_axis(t, x, u, params):
    return [0.5 * x[0] + np.sum(np.outer(x, [0.1, 0.2]), axis=0)[1] + u[0]]


def taxicab(t, x, u, params):
    return [0.9 * x[0] + np.linalg.norm(np.array([x[0], u[0]]), 1)]


@pytest.mark.parametrize("update, reason", [
    (single_precision, "it uses numpy.float32: numpy computes in its 32 bits, compiled code "
                       "in 64"),
    (fixed_point, "it uses numpy.int16: numpy computes in its 16 bits"),
    (summed_over_an_axis, r"it calls np.sum\(np.outer\(x, \[0.1, 0.2\]\), axis=0\): its "
                          r"compiled form takes \(a\) only"),
    (taxicab, r"it calls np.linalg.norm\(np.array\(\[x\[0\], u\[0\]\]\), 1\): its compiled "
              r"form takes \(x\) only")])
def test_narrow_numpy_types_and_arguments_compiled_code_does_not_take_run_as_python(
        update, reason):
    # the narrow types compiled to other numbers (1.2e-7 for float32, 2.18 for int16),
    # unseen when they first differ after the piece compared; numba refused the axis and
    # the ord only after a compile
    test_what_numba_refuses_runs_as_python_from_the_start_and_explain_says_why(update,
                                                                                reason)


def sorted_and_appended(t, x, u, params):  # new arrays: nothing outside is changed
    v = np.append(np.sort(np.array([x[1], x[0], u[0]])), 0.25)
    return [0.5 * v[0] + 0.1 * v[3], 0.4 * v[2] + 0.1 * v[1]]


def hypotenuse(t, x, u, params):  # numpy's hypot is the C library's, as numba's
    return [0.5 * x[0] + 0.1 * np.hypot(x[1], u[0]), 0.3 * x[1] + u[0]]


@pytest.mark.parametrize("update", [sorted_and_appended, hypotenuse])
def test_np_sort_np_append_and_np_hypot_compile_with_python_s_numbers(update):
    # np.sort(x) and np.append(x, v) were read as list.sort and list.append, changing an
    # object from outside: the diagram went to python-control; np.hypot was compared with
    # math.hypot (CPython's own method), not with the C library's, and ran as Python
    test_a_list_of_arrays_and_the_float_of_a_comparison_compile_with_python_s_numbers(update)


def cubed(t, x, u, params):  # Python's pow of two arguments is a ** b: the C library's
    return [0.5 * x[0] + pow(u[0] + 0.1 * t, 3)]


def logistic(t, x, u, params):  # exp(2000) overflows, and 1 / (1 + inf) is a number again
    return [-x[0] + 1.0 / (1.0 + math.exp(-2000.0 * u[0]))]


def test_pow_compiles_as_python_computes_it_and_math_exp_overflows_as_python_raises():
    block = ct.nlsys(cubed, None, inputs="u", outputs="y", states=1, dt=TS, name="odd")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.arange(60) * TS
    U = np.linspace(0.0, 3.0, 60).reshape(1, -1)  # (numba's x * x * x differed from t = 3)
    ours = controlkit.input_output_response(loop, T, U, 0.1, compile=True)
    assert ours.engine_mode == "compiled"
    assert ours.outputs.tobytes() == ct.input_output_response(loop, T, U, 0.1).outputs.tobytes()
    block = ct.nlsys(logistic, None, inputs="u", outputs="y", states=1, name="squash")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.linspace(0.0, 6.0, 61)
    U = np.where(T > 3.0, -1.0, 1.0)
    with pytest.raises(OverflowError, match="math range error"):
        ct.input_output_response(loop, T, U, 0.0)
    for compile in (True, False):
        with pytest.raises(OverflowError, match="math range error"):
            controlkit.input_output_response(loop, T, U, 0.0, compile=compile)


def root_compared(t, x, u, params):  # a comparison loses the NaN of sqrt(-1)
    r = math.sqrt(u[0])
    return [0.5 * x[0] + (1.0 if r > 0.5 else 0.0)]


def log_unused(t, x, u, params):  # a result left unused: numba's NaN is lost
    math.log(u[0])
    return [0.5 * x[0] + u[0]]


def roots_and_logs(t, x, u, params):
    return [-x[0] + math.sqrt(u[0]) + math.log1p(u[0]) + math.atanh(0.5 * math.tanh(u[0]))]


@pytest.mark.parametrize("update", [root_compared, log_unused])
def test_math_s_domain_errors_raise_as_python_raises_them_where_numba_s_nan_is_lost(update):
    # compiled, a square root or a logarithm of a negative was numba's NaN, which a
    # comparison or an unused result drops: the run answered where python-control raises
    # (found by a review: past the first piece, which is compared with Python)
    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="domain")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.arange(4000) * TS
    U = np.where(T > 150.0, -1.0, 1.0)
    with pytest.raises(ValueError, match="math domain error"):
        ct.input_output_response(loop, T, U, 0.1)
    with pytest.raises(ValueError, match=r"math domain error \(in block 'domain', its update "
                                         r"function, at t = 150\.05 s\)"):
        controlkit.input_output_response(loop, T, U, 0.1, compile=True)
    if update is root_compared:  # within the domain: compiled, python-control's numbers
        U = np.ones_like(T)
        ours = controlkit.input_output_response(loop, T, U, 0.1, compile=True)
        assert ours.engine_mode == "compiled"
        assert np.array_equal(ours.outputs, ct.input_output_response(loop, T, U, 0.1).outputs)


def complex_power_compared(t, x, u, params):  # a Python float's complex power, compared
    s = float(1.5 - u[0])  # (a Python float: numpy's would make NaN, as compiled code)
    return [0.5 * x[0] + (1.0 if abs(s ** 1.5) > 0.2 else 0.0)]


def math_power_compared(t, x, u, params):  # math.pow's domain error, dropped by a comparison
    return [0.5 * x[0] + (1.0 if math.pow(u[0], 1.5) > 0.5 else 0.0)]


def overflowing_power(t, x, u, params):  # Python's float raises, C's pow gives inf
    return [0.5 * x[0] + (1.0 if 10.0 ** (200.0 * u[0]) > 1.0 else 0.0)]


@pytest.mark.parametrize("update", [complex_power_compared, math_power_compared,
                                    overflowing_power])
def test_a_power_python_s_float_makes_no_float_of_runs_as_python(update):
    # compiled, a negative Python float to a fractional power was NaN where Python makes
    # a complex number (a comparison of it took the other branch, 1.0 off python-control,
    # from t = 20 314 s of a review's run), math.pow's domain error and a power's overflow
    # were numbers where python-control raises
    block = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="power")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.arange(4000) * TS
    U = np.where(T > 150.0, -1.0 if update is math_power_compared else 2.0, 1.0)
    try:
        expected = ct.input_output_response(loop, T, U, 0.1).outputs
    except (ValueError, OverflowError) as error:
        with pytest.raises(type(error), match=re.escape(str(error))):
            controlkit.input_output_response(loop, T, U, 0.1, compile=True)
    else:
        ours = controlkit.input_output_response(loop, T, U, 0.1, compile=True)
        assert np.array_equal(ours.outputs, expected)
    within = controlkit.input_output_response(loop, T[:2000], 1.0, 0.1, compile=True)
    assert within.engine_mode == "compiled"  # (Python's float numbers: compiled)
    assert np.array_equal(within.outputs,
                          ct.input_output_response(loop, T[:2000], 1.0, 0.1).outputs)


def test_math_s_checked_functions_compile_with_numba_s_numbers_in_a_continuous_loop():
    block = ct.nlsys(roots_and_logs, None, inputs="u", outputs="y", states=1, name="logs")
    loop = ct.interconnect([block], inputs="u", outputs="y")
    T = np.linspace(0.0, 30.0, 301)
    U = np.where(T > 25.0, 2.0, 1.0)
    ours = controlkit.input_output_response(loop, T, U, 0.1, compile=True)
    assert ours.engine_mode == "compiled"
    assert np.array_equal(ours.outputs, ct.input_output_response(loop, T, U, 0.1).outputs)
    with pytest.raises(ValueError, match="math domain error"):
        controlkit.input_output_response(loop, T, np.where(T > 25.0, -1.0, 1.0), 0.1,
                                         compile=True)


def test_the_math_functions_sent_to_python_are_the_ones_numba_refuses():
    # the list is numba's (0.59-0.68): a numba that compiles one of them shows here
    from controlkit import _jit
    from controlkit.engines.fast.usercode.calls import Calls

    if not _jit.available():
        pytest.skip("numba not installed")
    numba = _jit.numba_module()

    def compiles(name, args):
        namespace = {"math": math}
        names = ", ".join(f"a{i}" for i in range(len(args)))
        exec(f"def f({names}):\n    return math.{name}({names})\n", namespace)
        try:
            numba.njit(namespace["f"])(*args)
        except numba.core.errors.TypingError:
            return False
        return True

    for function in Calls.NUMBA_LACKS:  # (one number, two, two integers)
        assert not any(compiles(function.__name__, args)
                       for args in ((1.5,), (2.5, 1.5), (3, 2))), function.__name__
    assert compiles("atan2", (1.0, 2.0)) and compiles("floor", (1.5,))


REFUSED_BY_NUMBA = '''
import warnings
import control as ct
import numpy as np
import controlkit

def step_up(t, x, u, params):  # numba has no np.heaviside
    return [0.5 * x[0] + np.heaviside(u[0], 0.5)]

block = ct.nlsys(step_up, None, inputs=1, states=1, outputs=1, dt=0.1, name="stepper")
T = np.arange(50) * 0.1
with warnings.catch_warnings(record=True) as said:
    warnings.simplefilter("always")
    ours = controlkit.input_output_response(block, T, np.sin(T), [0.0], compile=True)
theirs = ct.input_output_response(block, T, np.sin(T), [0.0])
print(ours.engine_mode, np.array_equal(ours.outputs, theirs.outputs))
print(" ".join(str(w.message) for w in said))
'''


def test_a_function_numba_refused_is_not_compiled_again_in_the_next_session(tmp_path):
    # numba's refusal came after a compile of 0.7-1.4 s, paid again in every session;
    # the store keeps it by the function's text and numba's version
    script = tmp_path / "refused.py"
    script.write_text(REFUSED_BY_NUMBA)
    environment = {**os.environ, "CONTROLKIT_CACHE_DIR": str(tmp_path / "store")}
    said = []
    for _ in ("refused", "remembered"):
        result = subprocess.run([sys.executable, str(script)], capture_output=True,
                                text=True, cwd=tmp_path, timeout=600, env=environment)
        assert result.returncode == 0, result.stderr[-1500:]
        mode, equal, *warned = result.stdout.split()
        assert (mode, equal) == ("python", "True"), result.stdout
        said.append((" ".join(warned), result.stderr))
    assert "numpy.heaviside" in said[0][0] and "controlkit: compiling" in said[0][1]
    assert "numpy.heaviside" in said[1][0] and "found by an earlier compile" in said[1][0]
    assert "controlkit: compiling" not in said[1][1]
