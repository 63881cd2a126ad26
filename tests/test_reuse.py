"""A diagram called again reuses its prepared job only while nothing it depends on has
changed: each change a notebook makes between two calls gives python-control's new answer."""

import functools
import linecache
import sys
import types

import control as ct
import numpy as np
import pytest

import controlkit
from controlkit.engines.fast import reuse
from controlkit.engines.fast.run import prepare
from controlkit.engines.fast.tiers import NotCompiled

T = np.linspace(0.0, 4.0, 81)
GAIN = 2.0  # read by ``scaled`` below, from this module


def shaping(v):
    return GAIN * v


def scaled(t, x, u, params):
    return [shaping(u[0]) - params["a"] * x[0]]


def agrees(loop, U, X0, compile=False, **kwargs):
    """controlkit's response equals python-control's, to 1e-9 (the engine's, as Python
    unless ``compile`` says otherwise: the rule leaves a new diagram's short run to
    python-control)."""
    ours = controlkit.input_output_response(loop, T, U, X0, compile=compile, **kwargs)
    ref = ct.input_output_response(loop, T, U, X0, **kwargs)
    np.testing.assert_allclose(ours.outputs, ref.outputs, rtol=1e-9, atol=1e-12)
    return ours.outputs


def lag_loop(update, params=None, dt=0):
    block = ct.nlsys(update, None, inputs="u", outputs="y", states="y", dt=dt, name="lag",
                     params=params or {"a": 1.0})
    return ct.interconnect([block], inputs="u", outputs="y", name="lag_loop")


@pytest.mark.parametrize("compiled", [False, True])
def test_a_diagram_called_again_unchanged_reuses_its_job_and_a_new_value_does_not(compiled):
    # preparing a compiled job writes its module's text; nothing is compiled here
    loop = lag_loop(scaled)
    first = prepare(loop, {"a": 1.0}, compiled=compiled)
    assert first.compiled is compiled
    assert prepare(loop, {"a": 1.0}, compiled=compiled) is first
    assert prepare(loop, {"a": 1.0}, compiled=not compiled) is not first
    assert prepare(loop, {"a": 1.5}, compiled=compiled) is not first


def test_a_closure_array_changed_in_place_between_calls_is_read_again():
    gains = np.array([1.0, 0.5])

    def update(t, x, u, params):
        return [gains[0] * u[0] - gains[1] * x[0]]

    loop = lag_loop(update)
    before = agrees(loop, 1.0, [0.0])
    gains[1] = 3.0
    after = agrees(loop, 1.0, [0.0])
    assert after[-1] == pytest.approx(1.0 / 3.0, rel=1e-3) and before[-1] > 0.8


def test_a_name_imported_inside_a_function_is_read_again_at_each_call(monkeypatch):
    # `from gains import K` inside the function was read once, and the compiled run went
    # on with the old K after gains.K changed (0.86 for python-control's 4.28, no word)
    gains = types.ModuleType("controlkit_test_gains")
    monkeypatch.setitem(sys.modules, gains.__name__, gains)

    def update(t, x, u, params):
        from controlkit_test_gains import K
        return [K * u[0] - x[0]]

    loop = lag_loop(update, dt=0.05)
    outputs = []
    for gains.K in (0.1, 0.5):
        outputs.append(agrees(loop, 1.0, [0.0], compile=True)[-1])
    assert outputs[1] == pytest.approx(5 * outputs[0])


def test_a_closure_list_changed_in_place_between_calls_is_read_again():
    gains = [1.0, 0.5]

    def update(t, x, u, params):
        return [gains[0] * u[0] - gains[1] * x[0]]

    loop = lag_loop(update)
    agrees(loop, 1.0, [0.0])
    gains[0] = -1.0
    assert agrees(loop, 1.0, [0.0])[-1] < 0


def test_block_and_diagram_params_dicts_changed_in_place_are_read_again():
    loop = lag_loop(scaled)
    agrees(loop, 1.0, [0.0])
    del loop.params["a"]  # the diagram's own params (copied from its blocks) come last
    loop.syslist[0].params["a"] = 4.0
    assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(0.5, rel=1e-3)
    loop.params["a"] = 8.0
    assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(0.25, rel=1e-3)


def test_a_module_global_and_a_helper_reassigned_between_calls_are_read_again():
    global GAIN, shaping
    loop = lag_loop(scaled)
    saved = GAIN, shaping
    try:
        agrees(loop, 1.0, [0.0])
        GAIN = 3.0
        assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(3.0, rel=2e-2)
        shaping = lambda v: -v  # noqa: E731 - a helper replaced, as in a notebook cell
        assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(-1.0, rel=2e-2)
    finally:
        GAIN, shaping = saved


def proportional_loop():
    """A first-order LTI plant under a user's proportional controller (k = 2)."""
    plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs="u", outputs="y", name="plant")
    controller = ct.nlsys(None, lambda t, x, u, params: params["k"] * (u[0] - u[1]),
                          inputs=["r", "y"], outputs="u", params={"k": 2.0}, name="k")
    return ct.interconnect([plant, controller], inputs="r", outputs="y"), plant


def test_an_lti_matrix_changed_in_place_is_read_again():
    loop, plant = proportional_loop()
    before = agrees(loop, 1.0, [0.0])
    plant.A[0, 0] = -5.0
    after = agrees(loop, 1.0, [0.0])
    assert before[-1] == pytest.approx(2.0 / 3.0, rel=1e-3)
    assert after[-1] == pytest.approx(2.0 / 7.0, rel=1e-3)


def test_a_function_swapped_on_the_block_is_used():
    loop = lag_loop(scaled)
    agrees(loop, 1.0, [0.0])
    loop.syslist[0].updfcn = lambda t, x, u, params: [-x[0]]
    assert agrees(loop, 1.0, [1.0])[-1] == pytest.approx(np.exp(-4.0), rel=1e-2)


def test_an_array_bound_by_a_partial_changed_in_place_is_read_again():
    def update(t, x, u, params, gains):
        return [gains[0] * u[0] - gains[1] * x[0]]

    gains = np.array([1.0, 1.0])
    loop = lag_loop(functools.partial(update, gains=gains))
    agrees(loop, 1.0, [0.0])
    gains[0] = 2.0
    assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(2.0, rel=3e-2)


@pytest.mark.parametrize("compile", [None, True])
def test_a_discrete_diagram_called_again_after_a_change_gives_the_new_answer(compile):
    # compiled: the array's values are the module's data, read at each run (its text,
    # and the compiled code, stay the same)
    table = np.array([0.5])

    def update(t, x, u, params):
        return [table[0] * x[0] + u[0]]

    loop = lag_loop(update, dt=0.1)
    Td = np.arange(20) * 0.1
    first = controlkit.input_output_response(loop, Td, 1.0, [0.0], compile=compile)
    table[0] = 0.9
    second = controlkit.input_output_response(loop, Td, 1.0, [0.0], compile=compile)
    ref = ct.input_output_response(loop, Td, 1.0, [0.0]).outputs
    np.testing.assert_array_equal(second.outputs, ref)
    assert first.outputs[-1] == pytest.approx(2.0, rel=1e-3) and second.outputs[-1] > 8.0
    if compile:
        assert first.engine_mode == second.engine_mode == "compiled"


def test_a_compiled_diagram_reads_a_module_global_and_a_helper_again_at_each_run():
    global GAIN, shaping
    loop = lag_loop(scaled, dt=0.1)
    Td = np.arange(20) * 0.1
    saved = GAIN, shaping

    def agrees_compiled():
        ours = controlkit.input_output_response(loop, Td, 1.0, [0.0], compile=True)
        assert ours.engine_mode == "compiled"
        ref = ct.input_output_response(loop, Td, 1.0, [0.0])
        np.testing.assert_array_equal(ours.outputs, ref.outputs)
        return ours.outputs

    try:
        before = agrees_compiled()
        GAIN = 3.0
        assert agrees_compiled()[1] == 1.5 * before[1]
        shaping = lambda v: -v  # noqa: E731 - a helper replaced, as in a notebook cell
        assert agrees_compiled()[1] == -1.0
    finally:
        GAIN, shaping = saved


def test_a_block_that_cannot_be_compiled_has_a_python_job_only_and_it_is_reused():
    # run as Python, a block's functions are called as they are: a job is reused while
    # the same functions and parameters are handed to it
    def valve(t, x, u, params):
        return [-x[0] + (u[0] if params["mode"] == "open" else 0.0)]

    loop = lag_loop(valve, params={"mode": "open"})
    first = prepare(loop)
    assert [b.tier for b in first.blocks] == ["python"]
    assert prepare(loop) is first
    with pytest.raises(NotCompiled, match=r"block 'lag': parameter 'mode' is a str \('open'\), "
                                          r"which compiled code cannot take"):
        prepare(loop, compiled=True)
    agrees(loop, 1.0, [0.0])
    assert agrees(loop, 1.0, [0.0], params={"mode": "shut"})[-1] == 0.0


@pytest.mark.parametrize("value", [object(), {"nested": 1.0}, np.array([None])])
def test_a_value_the_key_cannot_hold_exactly_gives_no_key(value):
    assert reuse.job_key(lag_loop(scaled), {"a": value}) is None


def test_minus_zero_is_a_new_parameter_value():
    loop = lag_loop(lambda t, x, u, params: [np.copysign(1.0, params["a"]) * u[0] - x[0]],
                    params={"a": 0.0})
    assert agrees(loop, 1.0, [0.0], params={"a": 0.0})[-1] > 0.9
    assert agrees(loop, 1.0, [0.0], params={"a": -0.0})[-1] < -0.9


SIGN = 0.0  # read by ``signed`` below


def signed(t, x, u, params):
    return [np.copysign(1.0, SIGN) * u[0] - x[0]]


def test_a_module_global_set_to_minus_zero_is_read_again():
    global SIGN
    loop = lag_loop(signed)
    try:
        assert agrees(loop, 1.0, [0.0])[-1] > 0.9
        SIGN = -0.0
        assert agrees(loop, 1.0, [0.0])[-1] < -0.9
    finally:
        SIGN = 0.0


def test_the_wiring_changed_through_python_controls_setters_is_read_again():
    loop, _ = proportional_loop()
    before = agrees(loop, 1.0, [0.0])
    loop.set_output_map(2.0 * loop.output_map)
    assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(2.0 * before[-1], rel=1e-9)
    loop.set_connect_map(np.zeros_like(loop.connect_map))  # the loop opened
    assert agrees(loop, 1.0, [0.0])[-1] == 0.0


def test_a_controlkit_blocks_parameters_changed_in_place_are_read_again():
    from controlkit.blocks.common import lowpass_filter

    block = lowpass_filter(tau=1.0, Ts=0.1)
    loop = ct.interconnect([block], inputs=block.input_labels, outputs=block.output_labels)
    Td = np.arange(30) * 0.1
    controlkit.input_output_response(loop, Td, 1.0, [0.0, 0.0], compile=False)
    block.kernels.params[:] = 0.3 * block.kernels.params
    ours = controlkit.input_output_response(loop, Td, 1.0, [0.0, 0.0], compile=False).outputs
    np.testing.assert_array_equal(ours, ct.input_output_response(loop, Td, 1.0,
                                                                 [0.0, 0.0]).outputs)


def gained(t, x, u, params, *, gain=1.0):
    return [gain * u[0] - x[0]]


def test_a_partials_keywords_and_keyword_defaults_changed_in_place_are_read_again():
    bound = functools.partial(gained, gain=1.0)
    loop = lag_loop(bound)
    agrees(loop, 1.0, [0.0])
    bound.keywords["gain"] = 3.0
    assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(3.0, rel=3e-2)

    def own(t, x, u, params, *, gain=1.0):
        return [gain * u[0] - x[0]]

    loop = lag_loop(own)
    agrees(loop, 1.0, [0.0])
    own.__kwdefaults__["gain"] = -2.0
    assert agrees(loop, 1.0, [0.0])[-1] == pytest.approx(-2.0, rel=3e-2)


class Lag:
    """A callable object as an update function."""

    def __call__(self, t, x, u, params):
        return [u[0] - x[0]]


def test_a_classs_call_replaced_is_what_runs():
    loop = lag_loop(Lag())
    agrees(loop, 1.0, [0.0])
    saved = Lag.__call__
    try:
        Lag.__call__ = lambda self, t, x, u, params: [-u[0] - x[0]]
        assert agrees(loop, 1.0, [0.0])[-1] < -0.9
    finally:
        Lag.__call__ = saved


def test_a_kept_job_lives_with_its_diagram_and_no_copy_or_pickle_carries_it():
    import copy
    import gc
    import pickle

    cloudpickle = pytest.importorskip("cloudpickle")
    import weakref

    loop = lag_loop(scaled)
    agrees(loop, 1.0, [0.0])
    for other in (copy.copy(loop), copy.deepcopy(loop),
                  pickle.loads(cloudpickle.dumps(loop))):  # as sweeps send it to workers
        assert reuse.reused(other, reuse.job_key(other, None)) is None
        agrees(other, 1.0, [0.0])
    for other in (copy.deepcopy(loop), pickle.loads(cloudpickle.dumps(loop))):
        assert other._controlkit_kept_job is None  # (loads without controlkit)
    gone = weakref.ref(loop)
    del loop
    gc.collect()
    assert gone() is None


def test_a_compiled_job_takes_the_python_jobs_text_only_when_its_kernels_are_the_same():
    # controlkit's blocks and LTI blocks: the same kernels both ways, written once
    from controlkit.studies.cmg.diagrams import cmg_loop

    python = prepare(cmg_loop())
    shared = prepare(python.sys, compiled=True, like=python)
    written = prepare(cmg_loop(), compiled=True)  # (a new diagram: written afresh)
    assert shared.compiled and not python.compiled
    assert shared.plan is python.plan and shared.source == written.source
    np.testing.assert_array_equal(shared.P, written.P)
    # a user's function: its compiled kernel is another, so its plan is its own
    loop = lag_loop(scaled)
    python = prepare(loop)
    compiled = prepare(loop, compiled=True, like=python)
    assert compiled.plan is not python.plan
    assert compiled.plan.kernels != python.plan.kernels


def test_a_diagram_built_again_from_unnamed_systems_and_functions_of_another_file_is_one_module():
    # python-control names a system it is not given a name 'sys[<count>]', and a notebook's
    # cell is a file named by its kernel's process: neither may make the same code a new
    # module, compiled again at each build or in each session
    text = "def decay(t, x, u, params):\n    return -params['a'] * x + u\n"

    def build(filename, text=text):
        namespace = {}  # (its source read as IPython keeps a cell's: in linecache)
        linecache.cache[filename] = (len(text), None, text.splitlines(True), filename)
        exec(compile(text, filename, "exec"), namespace)
        plant = ct.nlsys(namespace["decay"], None, inputs=1, outputs=1, states=1,
                         params={"a": 1.0})
        gain = ct.ss([], [], [], [[2.0]], inputs=1, outputs=1)
        return ct.interconnect([plant, gain], connections=[[(1, 0), (0, 0)]],
                               inplist=[(0, 0)], outlist=[(1, 0)])

    first, second = build("/tmp/ipykernel_101/1.py"), build("/tmp/ipykernel_202/1.py")
    assert first.syslist[0].name != second.syslist[0].name and first.name != second.name
    assert prepare(first, compiled=True).source == prepare(second, compiled=True).source
    # and as Python, whose text keys the rule's count of earlier runs: a diagram built
    # anew before each call, its blocks unnamed, never compiled (0.9 s calls, ten of them)
    assert prepare(first).source == prepare(second).source
    other = build("/tmp/ipykernel_303/1.py", text.replace("* x", "* x * x"))
    assert prepare(first).source != prepare(other).source  # (another function: another)
    U = np.ones_like(T)
    np.testing.assert_array_equal(
        controlkit.input_output_response(second, T, U, compile=True).outputs,
        ct.input_output_response(second, T, U).outputs)
