"""Many runs of one diagram in one compiled call: the numbers of runs of their own."""

import warnings

import control as ct
import numpy as np
import pytest
from continuous_diagrams import CONTINUOUS, MIXED
from idiom_diagrams import cruise

import controlkit
from controlkit.sweep import sweep_system


@pytest.mark.parametrize("compile", [None, True])
def test_runs_over_parameter_sets_equal_runs_of_their_own(compile):
    # compile=True: the module compiled once, its runs on threads over all cores
    loop, T, X0, U = CONTINUOUS["car_pi"]()
    sets = [{"kp": kp, "ki": ki} for kp in (0.3, 0.6) for ki in (0.05, 0.2)]
    runs = controlkit.input_output_response(loop, T, U, X0, params=sets, compile=compile)
    assert len(runs) == len(sets)
    for params, resp in zip(sets, runs, strict=True):
        alone = ct.input_output_response(loop, T, U, X0, params=params)
        np.testing.assert_allclose(resp.y, alone.y, rtol=1e-9, atol=1e-12)
        assert resp.params == params


@pytest.mark.parametrize("compile", [None, True])
@pytest.mark.parametrize("which", ["discrete", "sampled-data"])
def test_runs_over_initial_states_equal_runs_of_their_own(which, compile):
    if which == "discrete":
        loop, T, x0, U, params = cruise(steps=60)
        x0 = np.asarray(x0, dtype=float)
    else:
        loop, T, x0, U = MIXED["servo_pi_discrete"]()
        params = None
    states = np.array([x0, x0 * 0.5, x0 + 1.0])
    runs = controlkit.input_output_response(loop, T, U, states, params=params, compile=compile)
    for state, resp in zip(states, runs, strict=True):
        alone = controlkit.input_output_response(loop, T, U, state, params=params,
                                                 compile=compile)
        np.testing.assert_array_equal(resp.y, alone.y)
        if compile:
            assert alone.engine_mode == "compiled"


def test_many_runs_say_how_they_ran():
    loop, T, x0, U, params = cruise(steps=60)
    states = np.array([x0, np.asarray(x0, dtype=float) * 0.5])
    for compile, mode in ((True, "compiled"), (False, "python")):
        runs = controlkit.input_output_response(loop, T, U, states, params=params,
                                                compile=compile)
        assert [resp.engine_mode for resp in runs] == [mode, mode]


def test_a_count_mismatch_is_refused():
    loop, T, X0, U = CONTINUOUS["pi_first_order"]()
    with pytest.raises(ValueError, match=r"params \(2 sets\) and initial_state \(3 rows\) "
                                         r"must give the same number of runs"):
        controlkit.input_output_response(loop, T, U, np.zeros((3, loop.nstates)),
                                         params=[{}, {}])


def test_sweep_system_gives_one_row_per_run_with_its_metrics_and_errors():
    def decay(t, x, u, params):
        return -params["a"] * x + u

    plant = ct.nlsys(decay, None, inputs="u", outputs="y", states=1, params={"a": 1.0},
                     name="plant")
    T = np.linspace(0.0, 4.0, 41)

    def final(resp):
        if resp.outputs[-1] > 10:
            raise ValueError("ran away")
        return {"final": float(resp.outputs[-1])}

    table = sweep_system(plant, T, 1.0, 0.0, grid={"a": [1.0, 2.0, -2.0]}, metrics=final)
    assert table["a"].tolist() == [1.0, 2.0, -2.0]
    np.testing.assert_allclose(table["final"][:2], [1 - np.exp(-4.0), 0.5 * (1 - np.exp(-8.0))],
                               rtol=1e-3)
    assert table["error"].tolist()[:2] == ["", ""]
    assert "ValueError: ran away" in table["error"][2]


def _decay_plant():
    def decay(t, x, u, params):
        return -params["a"] * x + u

    return ct.nlsys(decay, None, inputs="u", outputs="y", states=1, params={"a": 1.0},
                    name="plant")


@pytest.mark.parametrize(("options", "message"), [
    ({"grid": {"bogus": [1.0, 2.0]}}, r"params \['bogus'\] are read by no block of 'plant' "
                                      r"\(they read \['a'\]\)"),
    ({"grid": {"a": [1.0]}, "progress": "no"}, r"progress must be True or False, got 'no'"),
    ({"grid": {"a": [1.0]}, "params": [1, 2]}, r"params must be a dict of the values every "
                                               r"run shares, got list"),
])
def test_sweep_system_refuses_what_would_change_nothing_or_is_not_what_it_takes(options,
                                                                                 message):
    with pytest.raises(ValueError, match=message):
        sweep_system(_decay_plant(), np.linspace(0.0, 1.0, 11), 1.0, 0.0,
                     metrics=lambda r: {"y": 0.0}, **options)


def test_sweep_system_rows_keep_their_own_columns_and_a_bad_value_fails_its_row():
    T = np.linspace(0.0, 1.0, 11)
    table = sweep_system(_decay_plant(), T, 1.0, 0.0, grid={"a": [1.0, 2.0]},
                         metrics=lambda r: {"run": 7, "a": 0.0, "final": 1.0})
    assert table["run"].tolist() == [0, 1] and table["a"].tolist() == [1.0, 2.0]
    assert table["error"].str.startswith("ValueError: metrics returned ['a', 'run']").all()
    # a value the diagram cannot take fails its own row, the others are made
    table = sweep_system(_decay_plant(), T, 1.0, 0.0, grid={"a": [1.0, "fast"]},
                         metrics=lambda r: {"final": float(r.outputs[-1])})
    assert table["error"][0] == "" and table["final"][0] == pytest.approx(1 - np.exp(-1.0),
                                                                          rel=1e-3)
    assert table["error"][1] != ""
    # the same bad argument for every run is the call's error, not a table of failures
    with pytest.raises(ValueError):
        sweep_system(_decay_plant(), T, np.ones((3, T.size)), 0.0, grid={"a": [1.0, 2.0]},
                     metrics=lambda r: {"final": 0.0})


def _gained(t, x, u, params):
    return np.array([0.9 * x[0] + params["k"] * u[0]])


def _maybe_fed_through(t, x, u, params):
    return x[0] + params.get("d", 0.0) * u[0]  # (reads u: a loop through it, as read)


def _halved_into_zeros(t, x, u, params):
    dx = np.zeros_like(x)  # (integers in python-control's first step from integer X0)
    dx[0] = 0.5 * x[0] + params["k"] * u[0]
    return dx


def _loop(update, output):
    plant = ct.nlsys(update, output, inputs="u", outputs="y", states=1, params={"k": 0.5},
                     dt=0.1, name="P")
    error = ct.summing_junction(["r", "-y"], "u", name="E", dt=0.1)
    return ct.interconnect([plant, error], inputs="r", outputs="y", name="L")


@pytest.mark.parametrize("compile", [None, True, False])
def test_a_batch_answers_as_its_runs_alone_do(compile):
    # a review's batches: a loop the engine hands to python-control raised
    # UnsupportedSystem ("run 0: ..."); integer initial states were made floats (other
    # numbers than the runs alone, which python-control runs); t_eval spaced twice the
    # period answered consecutive steps where a run alone raises; a list t_eval answered
    T = np.linspace(0.0, 2.0, 21)
    for loop, X0s in ((_loop(_gained, _maybe_fed_through), np.array([[0.0], [1.0]])),
                      (_loop(_halved_into_zeros, lambda t, x, u, p: x[0]), [[1], [3]])):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            batch = controlkit.input_output_response(loop, T, 1.0, X0s, compile=compile)
        for r, mine in enumerate(batch):
            theirs = ct.input_output_response(loop, T, 1.0, X0s[r])
            np.testing.assert_array_equal(mine.outputs, theirs.outputs)
    loop = _loop(_gained, lambda t, x, u, p: x[0])
    controlkit.input_output_response(loop, T, 1.0, np.array([[0.0], [1.0]]), compile=compile)
    with pytest.raises(ValueError, match="sampling time"):
        controlkit.input_output_response(loop, T, 1.0, np.array([[0.0], [1.0]]),
                                         t_eval=T[::2], compile=compile)
    with pytest.raises(TypeError):
        ct.input_output_response(loop, T, 1.0, [0.0], t_eval=list(T))
    with pytest.raises(TypeError):
        controlkit.input_output_response(loop, T, 1.0, [0.0], t_eval=list(T), compile=compile)


def _halved_into_zeros_like(t, x, u, params):
    y = np.zeros_like(x)  # integers while x is (python-control's first step keeps them)
    y[0] = params.get("a", 0.5) * x[0] + u[0]
    return y


@pytest.mark.parametrize("compile", [None, True, False])
@pytest.mark.parametrize("X0", [[1], np.array([1.1], dtype=np.float32), [[1], [2.5]]],
                         ids=["one integer state", "one float32 state", "rows as written"])
def test_a_batch_s_runs_start_from_the_state_each_alone_is_given(compile, X0):
    # a review's batch: one initial state of integers (or float32) for every run, or a
    # list whose rows numpy would make floats, ran from floats: 0.9 and 4.8e-8 off the
    # runs alone, which python-control makes in the state's own type, without a word
    T = np.linspace(0.0, 2.0, 21)
    loop = _loop(_halved_into_zeros_like, lambda t, x, u, p: x[0])
    sets = [{"a": 0.5}, {"a": 0.25}]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        batch = controlkit.input_output_response(loop, T, 1.0, X0, params=sets,
                                                 compile=compile)
    for r, mine in enumerate(batch):
        alone = X0[r] if isinstance(X0, list) and len(X0) == len(sets) else X0
        theirs = ct.input_output_response(loop, T, 1.0, alone, params=sets[r])
        np.testing.assert_array_equal(mine.states, theirs.states)


class _Saturated(ValueError):
    def __init__(self, block, value):  # (not one message, as Exception's own)
        super().__init__(f"{block} saturated at {value}")


def _saturating(t, x, u, params):
    if x[0] > params["limit"]:
        raise _Saturated("P", x[0])
    return [0.9 * x[0] + u[0]]


@pytest.mark.parametrize("compile", [True, False])
@pytest.mark.parametrize("X0", [0.0, [[0], [0]]], ids=["in one call", "run by run"])
def test_a_run_s_error_in_a_batch_is_its_own_whatever_its_class_takes(compile, X0):
    # the batch made a new error of the class from one message: a TypeError where
    # python-control raised the user's own (integer rows of a discrete diagram: each run
    # alone, as python-control makes it)
    loop = _loop(_saturating, lambda t, x, u, p: x[0])
    T = np.linspace(0.0, 3.0, 31)
    with pytest.raises(_Saturated, match="P saturated at") as raised:
        controlkit.input_output_response(loop, T, 10.0, X0, params=[{"limit": 100.0},
                                                                    {"limit": 2.0}],
                                         compile=compile)
    assert "(in run 1 of 2)" in raised.value.__notes__
