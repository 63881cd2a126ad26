"""Arguments python-control reads in its own way get python-control's own answer or error.

Each case was found by a review of the call's options (the twenty-first session's first
work): the drop-in raised another error, refused what python-control answers, or answered
what it refuses. Each test runs python-control first and asserts the same outcome from
``controlkit.input_output_response`` on every ``compile``.
"""

import warnings

import control as ct
import numpy as np
import pytest

import controlkit
import controlkit.engines.fast  # noqa: F401  (the engine started, as in a session)

T = np.linspace(0.0, 5.0, 51)


def _static():
    gain = ct.nlsys(None, lambda t, x, u, p: np.array([2.0 * u[0] + t]), inputs=1,
                    outputs=1, name="gain")
    sat = ct.nlsys(None, lambda t, x, u, p: np.clip(u, -1.0, 1.0), inputs=1, outputs=1,
                   name="sat")
    return ct.interconnect([gain, sat], connections=[["sat.u[0]", "gain.y[0]"]],
                           inplist="gain.u[0]", outlist="sat.y[0]", name="static_chain")


def _discrete():
    return ct.nlsys(lambda t, x, u, p: np.array([0.9 * x[0] + 0.1 * x[1],
                                                 -0.2 * x[0] + 0.8 * x[1] + u[0]]),
                    lambda t, x, u, p: np.array([x[0] + 0.5 * u[0]]), inputs=1, states=2,
                    outputs=1, name="d", dt=0.1)


def _discrete_loop():
    plant = ct.ss([[0.9, 0.1], [0.0, 0.8]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], dt=0.1,
                  name="Pd", inputs="u", outputs="y")
    pi = ct.ss([[1.0]], [[0.1]], [[1.0]], [[2.0]], dt=0.1, name="Cd", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="S", dt=0.1)
    return ct.interconnect([plant, pi, error], inputs="r", outputs="y", name="dloop")


def _continuous_loop():
    plant = ct.nlsys(lambda t, x, u, p: np.array([x[1], -x[0] - 0.3 * x[1] + u[0]]),
                     lambda t, x, u, p: x[:1], inputs="u", outputs="y", states=2,
                     name="plant")
    lag = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="lag", inputs="y", outputs="z")
    return ct.interconnect([plant, lag], inputs="u", outputs="z", name="loop")


def _with_nan(values, at):
    values = np.array(values, dtype=float)
    values[at] = np.nan
    return values


def _true_dt():
    return ct.nlsys(lambda t, x, u, p: np.array([0.5 * x[0] + np.sin(t) * u[0]]),
                    lambda t, x, u, p: x, inputs=1, states=1, outputs=1, dt=True, name="dd")


# (system, the call's arguments) python-control answers
_ANSWERED = {
    "stateless, evaluation times decreasing": (
        _static, dict(U=np.sin(T), X0=0, evaluation_times=T[::-1].copy())),
    "stateless, an evaluation time repeated": (
        _static, dict(U=np.sin(T), X0=0, evaluation_times=np.array([1.0, 1.0, 2.0]))),
    "dt=True, evaluation times decreasing": (
        _true_dt, dict(T=np.arange(20.0), U=1.0, X0=[0.5], evaluation_times=np.arange(
            19.0, -1.0, -1.0))),
    "discrete, NaN in X0": (_discrete, dict(T=np.arange(51) * 0.1, U=0.5, X0=[np.nan, 0.0])),
    "discrete, NaN in U": (_discrete, dict(T=np.arange(51) * 0.1, U=_with_nan(
        np.sin(T), 20), X0=[0.0, 0.0])),
}


@pytest.mark.parametrize("case", sorted(_ANSWERED))
def test_what_python_control_answers_is_answered_the_same(case):
    build, arguments = _ANSWERED[case]
    arguments = {"T": T, **arguments}
    expected = ct.input_output_response(build(), **arguments)
    for compile in (True, False, None):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (compile=True says why it is not used)
            ours = controlkit.input_output_response(build(), compile=compile, **arguments)
        assert np.array_equal(ours.time, expected.time)
        assert np.array_equal(ours.outputs, expected.outputs, equal_nan=True), compile


def _stateless_reading_x():
    # python-control hands a system alone without states x = [] (a list: no .shape)
    return ct.nlsys(None, lambda t, x, u, p: np.array([u[0] + x.shape[0]]), inputs=1,
                    outputs=1, dt=0.1, name="reads_x")


# (system, the call's arguments) python-control refuses
_REFUSED = {
    "a system alone without states, reading x": (
        _stateless_reading_x, dict(T=np.arange(51) * 0.1)),
    "evaluation times empty": (_continuous_loop, dict(evaluation_times=np.array([]))),
    "evaluation times empty, LSODA": (_continuous_loop, dict(
        evaluation_times=np.array([]), solve_ivp_method="LSODA")),
    "evaluation times a number": (_continuous_loop, dict(evaluation_times=2.5)),
    "evaluation times 2-D": (_continuous_loop, dict(evaluation_times=T[None, ::10])),
    "evaluation times a string": (_continuous_loop, dict(evaluation_times="foo")),
    "T 2-D": (_continuous_loop, dict(T=T[None, :], U=np.cos(T))),
    "discrete, evaluation times not spaced by dt": (
        _discrete_loop, dict(T=np.arange(51) * 0.1, evaluation_times=np.arange(11) * 0.5)),
    "discrete, evaluation times not equally spaced": (
        _discrete_loop, dict(T=np.arange(51) * 0.1, evaluation_times=np.r_[0.0, 0.1, 0.3])),
    "discrete diagram, NaN in X0": (
        _discrete_loop, dict(T=np.arange(51) * 0.1, X0=[np.nan, 0.0, 0.0])),
    "continuous diagram, NaN in X0": (_continuous_loop, dict(X0=[np.nan, 0.0, 0.0])),
    "continuous diagram, NaN in U": (_continuous_loop, dict(U=_with_nan(np.sin(T), 20))),
    "solve_ivp_method=None": (_continuous_loop, dict(solve_ivp_method=None)),
    "method=''": (_continuous_loop, dict(method="")),
    "squeeze=1": (_continuous_loop, dict(squeeze=1)),
    "squeeze=np.True_": (_continuous_loop, dict(squeeze=np.True_)),
}


@pytest.mark.parametrize("case", sorted(_REFUSED))
def test_what_python_control_refuses_is_refused_in_its_words(case):
    build, arguments = _REFUSED[case]
    arguments = {"T": T, "U": 1.0, "X0": 0.0, **arguments}
    with pytest.raises(Exception) as expected:
        _ = ct.input_output_response(build(), **arguments).outputs  # (squeeze: raised here)
    for compile in (True, False, None):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # (compile=True says why it is not used)
            with pytest.raises(type(expected.value)) as ours:
                controlkit.input_output_response(build(), compile=compile, **arguments)
        assert str(ours.value) == str(expected.value), compile


def test_a_batch_with_an_argument_python_control_reads_its_own_way_runs_run_by_run():
    # a NaN in one of three initial states: python-control's answer for each run
    sys = _discrete()
    X0s = np.array([[0.0, 0.0], [np.nan, 0.0], [1.0, 0.0]])
    Td = np.arange(51) * 0.1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (the engine's refusal, said)
        runs = controlkit.input_output_response(sys, Td, 0.5, X0s, compile=True)
    for row, ours in zip(X0s, runs, strict=True):
        expected = ct.input_output_response(sys, Td, 0.5, row)
        assert np.array_equal(ours.outputs, expected.outputs, equal_nan=True)


def test_a_sampled_data_diagram_without_an_initial_state_is_refused_naming_it():
    plant = ct.nlsys(lambda t, x, u, p: np.array([x[1], -x[0] - 0.3 * x[1] + u[0]]),
                     lambda t, x, u, p: x[:1], inputs="u", outputs="y", states=2,
                     name="plant")
    pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi", inputs="e",
                          outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    mixed = controlkit.interconnect([plant, pi, error], inputs="r", outputs="y",
                                    name="mixed")
    for compile in (True, False):
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # (no fallback announced: nothing falls back)
            with pytest.raises(ValueError, match=r"cannot run the sampled-data diagram "
                                                 r"'mixed': an initial state of object"):
                controlkit.input_output_response(mixed, T, 1.0, None, compile=compile)


def test_a_response_without_inputs_plots_whichever_path_made_it():
    # python-control's response asks for an input panel without inputs (its .plot() then
    # raises): controlkit's asks for none, whether the engine or python-control ran it
    free = ct.nlsys(lambda t, x, u, p: -x, lambda t, x, u, p: x, inputs=0, states=1,
                    outputs=1, name="free")
    assert ct.input_output_response(free, T, 0.0, [1.0]).plot_inputs
    for compile in (True, False, None):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ours = controlkit.input_output_response(free, T, 0.0, [1.0], compile=compile)
        assert ours.plot_inputs is False, ours.engine_mode
        assert len(ours.plot().lines) == 1


def _accumulating(t, x, u, params):
    total = params["acc"]  # (the block's own array in python-control's run)
    total += u[0]
    return 0.5 * x + 0.01 * total[0]


def _accumulating_0d(t, x, u, params):
    total = params["acc"]  # (a 0-d array: `+=` changes it in place too)
    total += u[0]
    return 0.5 * x + 0.01 * total


def _bump(values, by):
    values += by  # (in place on the array it is handed)


def _accumulating_output(t, x, u, params):
    _bump(params["acc"], u[0])  # (python-control calls an output function twice a step)
    return params["acc"][:1] + u[0]


def _scaled(t, x, u, params):
    gain = params["gains"][0]  # (an element: `*=` binds a new number)
    gain *= 2.0
    return 0.5 * x + 0.01 * gain * u[0]


def _block(update, output, params):
    return ct.nlsys(update, output, inputs="u", outputs="y", states=1, dt=1, params=params,
                    name="s")


_IN_PLACE = {
    "an update through a name": (lambda: _block(_accumulating, None, {"acc": np.zeros(1)}),
                                 "in place (total += u[0])"),
    "an output through a helper": (lambda: _block(lambda t, x, u, p: 0.5 * x,
                                                  _accumulating_output, {"acc": np.zeros(1)}),
                                   "in place (_bump(params['acc'], u[0]))"),
    "a 0-d array": (lambda: _block(_accumulating_0d, None, {"acc": np.zeros(())}),
                    "in place (total += u[0])"),
}


@pytest.mark.parametrize("case", sorted(_IN_PLACE))
def test_a_params_array_changed_in_place_is_python_control_s_run(case):
    # python-control hands the functions a shallow copy of the block's params: an operator
    # on a value read from it changes the block's own array, across calls and diagrams,
    # as often as python-control calls the function (an output: more than once a step)
    build, said = _IN_PLACE[case]
    Td = np.arange(40.0)
    runs = []
    for compile in ("python-control", True, False, None):
        block = build()
        for _ in range(2):
            diagram = ct.interconnect([block], inputs="u", outputs="y")
            if compile == "python-control":
                last = ct.input_output_response(diagram, Td, 1.0, 0.0)
            else:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")  # (python-control runs it, and says so)
                    last = controlkit.input_output_response(diagram, Td, 1.0, 0.0,
                                                            compile=compile)
        runs.append((last.outputs.tolist(), np.ravel(block.params["acc"]).tolist()))
    assert runs[1:] == runs[:1] * 3
    assert said in controlkit.explain(ct.interconnect([build()], inputs="u",
                                                      outputs="y"))[0].reason


def _by_a_key_held_in_a_name(t, x, u, params):
    for key in ("acc",):
        total = params[key]
        total += u[0]
    return 0.5 * x + 0.01 * params["acc"][0]


def _rows_unpacked(t, x, u, params):
    first, _ = params["M"]  # (rows of a 2-D array: views)
    first += u[0]
    return 0.5 * x + 0.01 * first[0]


def _bound_twice(t, x, u, params):
    total = params["k"]
    total = params["acc"]  # (any binding counts, wherever it is)
    total += u[0]
    return 0.5 * x + 0.01 * total[0]


def _over_items(t, x, u, params):
    for _, value in params.items():
        value += u[0]
    return 0.5 * x + 0.01 * params["acc"][0]


@pytest.mark.parametrize("update", [_by_a_key_held_in_a_name, _rows_unpacked, _bound_twice,
                                    _over_items])
def test_other_routes_to_a_params_array_changed_in_place_are_python_control_s(update):
    def build():
        return _block(update, None, {"acc": np.zeros(1), "k": 2.0, "M": np.zeros((2, 2))})

    Td = np.arange(20.0)
    block = build()
    expected = ct.input_output_response(ct.interconnect([block], inputs="u", outputs="y"),
                                        Td, 1.0, 0.0)
    ours_block = build()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # (python-control runs it, and says so)
        ours = controlkit.input_output_response(
            ct.interconnect([ours_block], inputs="u", outputs="y"), Td, 1.0, 0.0,
            compile=True)
    assert ours.engine_mode == "python-control"
    assert np.array_equal(ours.outputs, expected.outputs)
    for key in ("acc", "M"):
        assert np.array_equal(ours_block.params[key], block.params[key])


_TABLE = np.array([1.0, 2.0])


def _scaled_by_table(v):
    gain = _TABLE[0]  # (an element of a module's table: `*=` binds a new number)
    gain *= v
    return gain


def _with_a_helper_scaling(t, x, u, params):
    return 0.5 * x + _scaled_by_table(u[0]) * params["k"][0]


def test_a_helper_scaling_an_element_of_an_outside_table_compiles_beside_array_params():
    # a helper's `*=` on a name bound to an outside value was read as a params value's
    # whose key is not known, and any array among the block's params sent it away
    block = _block(_with_a_helper_scaling, None, {"k": np.array([1.0])})
    assert controlkit.explain(ct.interconnect([block], inputs="u",
                                              outputs="y"))[0].tier == "compiled"


def test_an_element_of_a_params_array_changed_by_an_operator_compiles():
    block = _block(_scaled, None, {"gains": np.array([2.0, 3.0])})
    assert controlkit.explain(ct.interconnect([block], inputs="u",
                                              outputs="y"))[0].tier == "compiled"
