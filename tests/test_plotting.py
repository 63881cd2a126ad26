"""controlkit.plot: the signals asked for, by label or pattern, on a shared time axis."""

import control as ct
import matplotlib.pyplot as plt
import numpy as np
import pytest

import controlkit
from controlkit.blocks import spacecraft as sc
from controlkit.plotting import MAX_POINTS, match_signals, plot
from controlkit.studies.spacecraft import scenario


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def lag_response(tau=60.0, horizon=600.0):
    """A first-order lag under a unit step, built the python-control way."""
    lag = ct.nlsys(lambda t, x, u, params: (u - x) / params["tau"],
                   lambda t, x, u, params: x, inputs="u", outputs="y", states="x",
                   params={"tau": tau}, name="lag")
    return ct.input_output_response(lag, np.linspace(0.0, horizon, 601), 1.0)


@pytest.fixture(scope="module")
def mec_run():
    return scenario.run("proposed", horizon=300.0)


LABELS = ["q[0]", "q[1]", "q[2]", "q[3]", "mu[0]", "mu[1]", "mu_n[0]", "mu_n[1]", "T1"]


@pytest.mark.parametrize("pattern, expected", [
    ("T1", ["T1"]),
    ("q", ["q[0]", "q[1]", "q[2]", "q[3]"]),
    ("q[*]", ["q[0]", "q[1]", "q[2]", "q[3]"]),
    ("q[1:3]", ["q[1]", "q[2]"]),
    ("q[2:]", ["q[2]", "q[3]"]),
    ("mu*", ["mu[0]", "mu[1]", "mu_n[0]", "mu_n[1]"]),
    ("mu_n[?]", ["mu_n[0]", "mu_n[1]"]),
    ("mu[1]", ["mu[1]"]),
])
def test_patterns_name_signals_as_python_control_does(pattern, expected):
    assert match_signals(pattern, LABELS) == expected


def test_a_pattern_that_names_nothing_lists_the_signals():
    with pytest.raises(ValueError, match=r"no signal matches 'w\*'; signals: \['q\[0\]'"):
        match_signals("w*", LABELS)
    with pytest.raises(ValueError, match="a signal must be a non-empty label or pattern"):
        match_signals("", LABELS)


def test_one_axes_per_entry_sharing_time_in_the_unit_asked_for(mec_run):
    shown = plot(mec_run, ["h", ["u[0]", "mu[0]"], "K"], time_unit="min",
                 units={"u": "rad/s", "K": "1/s"})
    assert shown.signals == [["h[0]", "h[1]"], ["u[0]", "mu[0]"],
                             ["K[0]", "K[1]", "K[2]", "K[3]"]]
    assert len(shown.axes) == 3 and len(shown.figure.axes) == 3
    top, middle, bottom = shown.axes
    assert top.get_shared_x_axes().joined(top, bottom)
    assert bottom.get_xlabel() == "time [min]" and top.get_xlabel() == ""
    # a whole vector by its name, an element by its label
    assert middle.get_ylabel() == "u[0], mu[0] [rad/s]" and bottom.get_ylabel() == "K [1/s]"
    # the data are the response's, the time divided by 60
    line = top.get_lines()[1]
    np.testing.assert_allclose(line.get_xdata(), mec_run.time / 60.0)
    np.testing.assert_array_equal(line.get_ydata(), mec_run.outputs[1])
    # each signal its colour, named in a legend to the right of the axes, outside the data
    colours = {tuple(c.get_color()) if not isinstance(c.get_color(), str) else c.get_color()
               for c in bottom.get_lines()}
    assert len(colours) == 4
    shown.figure.canvas.draw()
    legend = bottom.get_legend()
    assert [t.get_text() for t in legend.get_texts()] == ["K[0]", "K[1]", "K[2]", "K[3]"]
    assert legend.get_window_extent().x0 > bottom.get_window_extent().x1


def test_states_and_inputs_are_signals_too():
    resp = lag_response()
    shown = plot(resp, ["x", "u"])
    np.testing.assert_array_equal(shown.axes[1].get_lines()[0].get_ydata(), np.ones(601))


def test_log_axes_draw_magnitudes_and_derived_signals_and_reference_lines(mec_run):
    shown = plot(mec_run, ["h[0]", "pointing error"], log=["h[0]", "pointing error"],
                 derived={"pointing error": (sc.pointing_error_deg, "q")},
                 lines={"pointing error": (0.05, "requirement 0.05 deg")},
                 units={"pointing error": "deg"})
    h_axes, error_axes = shown.axes
    assert h_axes.get_yscale() == "log" == error_axes.get_yscale()
    q = np.vstack([mec_run.outputs[mec_run.output_labels.index(f"q[{i}]")] for i in range(4)])
    np.testing.assert_allclose(error_axes.get_lines()[0].get_ydata(), sc.pointing_error_deg(q))
    assert error_axes.get_lines()[1].get_ydata()[0] == 0.05
    assert [t.get_text() for t in error_axes.get_legend().get_texts()] == [
        "pointing error", "requirement 0.05 deg"]
    assert error_axes.get_ylabel() == "pointing error [deg]"


def test_a_signal_that_changes_sign_is_drawn_as_its_magnitude_on_a_log_axis():
    resp = lag_response()
    error = {"e": (lambda y: 0.5 - y[0], "y")}  # positive, then negative
    shown = plot(resp, [["e", "y"]], derived=error, log=["e"])
    magnitude = np.abs(0.5 - np.asarray(resp.outputs))
    np.testing.assert_allclose(shown.axes[0].get_lines()[0].get_ydata(), magnitude)
    assert [t.get_text() for t in shown.axes[0].get_legend().get_texts()] == ["|e|", "y"]


def test_several_runs_are_told_apart_by_colour_in_one_legend_below():
    runs = {"tau = 30 s": lag_response(30.0), "tau = 120 s": lag_response(120.0)}
    shown = plot(runs, ["y"], lines={"y": (1.0, "set point")})
    assert [t.get_text() for t in shown.figure.legends[0].get_texts()] == [
        "tau = 30 s", "tau = 120 s", "set point"]
    first, second = shown.axes[0].get_lines()[:2]
    assert first.get_color() != second.get_color()
    assert shown.axes[0].get_legend() is None  # one signal: the y label names it


def test_a_long_response_is_drawn_as_its_envelope():
    time = np.linspace(0.0, 1.0, 10 * MAX_POINTS)
    values = np.sin(2 * np.pi * 5 * time) + np.where(np.arange(time.size) == 12345, 3.0, 0.0)
    resp = ct.TimeResponseData(time, values[np.newaxis], output_labels=["s"], issiso=False)
    line = plot(resp, ["s"]).axes[0].get_lines()[0]
    assert line.get_ydata().size <= MAX_POINTS + 20
    assert line.get_ydata().max() == values.max() and line.get_ydata().min() == values.min()
    assert np.all(np.diff(line.get_xdata()) >= 0)  # still in time order


def test_a_curve_given_a_style_stays_visible_on_top_of_its_twin():
    runs = {"a": lag_response(60.0), "b": lag_response(60.0)}  # the same curve twice
    shown = plot(runs, ["y"], styles={"b": "--"})
    first, second = shown.axes[0].get_lines()[:2]
    assert second.get_linestyle() == "--" and second.get_zorder() > first.get_zorder()
    handles = shown.figure.legends[0].legend_handles
    assert [h.get_linestyle() for h in handles] == ["-", "--"]
    with pytest.raises(ValueError, match=r"styles names unknown responses \['c'\]; "
                       r"responses: \['a', 'b'\]"):
        plot(runs, ["y"], styles={"c": "--"})
    single = plot(lag_response(), [["y", "u"]], styles={"u": ":"})
    assert [line.get_linestyle() for line in single.axes[0].get_lines()] == ["-", ":"]


# --- every response python-control returns ------------------------------------------------

#: A system with two inputs, two outputs and two states, as a lecture's first MIMO example
MIMO = ct.ss([[-1.0, 0.5], [0.0, -2.0]], [[1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [0.3, 1.0]],
             0.0, name="G")
SISO = ct.tf([1.0], [1.0, 2.0, 1.0], name="P")
T = np.linspace(0.0, 5.0, 101)


def drawn(ax):
    """The data curves of an axes (reference lines excluded), as arrays."""
    return [np.asarray(line.get_ydata(), dtype=float) for line in ax.get_lines()
            if line.get_linestyle() != ":"]


@pytest.mark.parametrize("kind, respond", [
    ("step", lambda: ct.step_response(MIMO, T)),
    ("impulse", lambda: ct.impulse_response(MIMO, T)),
])
def test_a_response_with_a_trace_per_input_has_an_axes_per_output(kind, respond):
    resp = respond()
    assert resp.ntraces == 2
    shown = plot(resp)
    assert shown.signals == [["y[0]"], ["y[1]"]]
    assert [ax.get_ylabel() for ax in shown.axes] == ["y[0]", "y[1]"]
    assert shown.axes[0].get_title() == f"{kind.capitalize()} response for G"
    for i, ax in enumerate(shown.axes):  # output i, one curve per input, in trace order
        curves = drawn(ax)
        assert len(curves) == 2
        for j, curve in enumerate(curves):
            np.testing.assert_array_equal(curve, resp.y[i, j, :])
    colours = [line.get_color() for line in shown.axes[0].get_lines()]
    assert colours[0] != colours[1]
    assert [t.get_text() for t in shown.figure.legends[0].get_texts()] == [
        "From u[0]", "From u[1]"]  # python-control's trace labels


def test_a_siso_step_response_is_one_curve_titled_as_python_control_titles_it():
    resp = ct.step_response(SISO, T)
    shown = plot(resp)
    assert shown.signals == [["y[0]"]] and shown.axes[0].get_ylabel() == "y"
    (curve,) = drawn(shown.axes[0])
    np.testing.assert_array_equal(curve, resp.outputs)
    assert shown.axes[0].get_title() == "Step response for P"
    assert not shown.figure.legends  # one curve: nothing to tell apart


@pytest.mark.parametrize("respond, states", [
    (lambda: ct.initial_response(MIMO, T, X0=[1.0, -0.5]), True),
    (lambda: ct.forced_response(MIMO, T, np.vstack([np.sin(T), np.ones_like(T)])), True),
    (lambda: ct.input_output_response(MIMO, T, np.vstack([np.sin(T), np.ones_like(T)])),
     True),
])
def test_initial_forced_and_input_output_responses_are_drawn_from_their_own_data(
        respond, states):
    resp = respond()
    shown = plot(resp, [["y[0]", "y[1]"], "x"])
    curves = drawn(shown.axes[0])
    for i in range(2):
        np.testing.assert_array_equal(curves[i], resp.y[i])
    for i, curve in enumerate(drawn(shown.axes[1])):
        np.testing.assert_array_equal(curve, resp.x[i])
    assert shown.axes[1].get_ylabel() == "x"


def test_the_initial_response_has_an_axes_per_output_and_no_input():
    resp = ct.initial_response(MIMO, T, X0=[1.0, -0.5])
    shown = plot(resp)
    assert shown.signals == [["y[0]"], ["y[1]"]]
    assert shown.axes[0].get_title() == "Initial response for G"
    with pytest.raises(ValueError, match=r"no signal matches 'u'; signals: \['y\[0\]', "
                       r"'y\[1\]', 'x\[0\]', 'x\[1\]'\]"):
        plot(resp, ["u"])  # an initial response has no input


def test_each_trace_keeps_its_own_inputs_and_states():
    resp = ct.step_response(MIMO, T)
    shown = plot(resp, ["y[1]", "u[0]", "x[1]"])
    u0 = drawn(shown.axes[1])
    np.testing.assert_array_equal(u0[0], np.ones_like(T))   # the step on u[0]
    np.testing.assert_array_equal(u0[1], np.zeros_like(T))  # ... and none while u[1] steps
    np.testing.assert_array_equal(drawn(shown.axes[2])[1], resp.x[1, 1, :])


def closed_loop(kp):
    return ct.feedback(SISO * ct.tf([kp, 1.0], [1.0, 0.0]), 1, name=f"PI kp={kp:g}")


def test_a_list_of_step_responses_is_compared_on_shared_axes_named_by_system():
    loops = [closed_loop(2.0), closed_loop(5.0)]
    for resp in (ct.step_response(loops, T), [ct.step_response(s, T) for s in loops]):
        shown = plot(resp, lines={"y": (1.0, "set point")})
        assert len(shown.axes) == 1 and shown.axes[0].get_title() == "Step responses"
        curves = drawn(shown.axes[0])
        for curve, one in zip(curves, resp, strict=True):
            np.testing.assert_array_equal(curve, one.outputs)
        assert [t.get_text() for t in shown.figure.legends[0].get_texts()] == [
            "PI kp=2", "PI kp=5", "set point"]
    twice = plot([ct.step_response(loops[0], T)] * 2)
    assert [t.get_text() for t in twice.figure.legends[0].get_texts()] == [
        "PI kp=2 (1)", "PI kp=2 (2)"]  # the same system twice: told apart by place


def test_a_dict_of_multi_input_responses_names_each_trace_after_its_response():
    runs = {"G": ct.step_response(MIMO, T), "2G": ct.step_response(2 * MIMO, T)}
    shown = plot(runs, styles={"2G": "--"})
    assert [t.get_text() for t in shown.figure.legends[0].get_texts()] == [
        "G, From u[0]", "G, From u[1]", "2G, From u[0]", "2G, From u[1]"]
    lines = shown.axes[1].get_lines()
    assert [line.get_linestyle() for line in lines] == ["-", "-", "--", "--"]
    np.testing.assert_allclose(lines[3].get_ydata(), 2 * runs["G"].y[1, 1, :])
    assert len({line.get_color() for line in lines}) == 4


@pytest.mark.parametrize("resp, message", [
    (lambda: ct.step_response(SISO, T)[1], r"resp must be a control.TimeResponseData \(the "
     r"result of step_response, input_output_response, ...\), or a non-empty list or dict "
     r"of them, got an array of shape \(101,\) \(resp\[0\], resp\[1\] are the "
     r"response unpacked as time and outputs: pass the response itself\)"),
    (lambda: [], r"resp must be a control.TimeResponseData .* got list"),
    (lambda: {}, r"resp must be a control.TimeResponseData .* got dict"),
    (lambda: {"a": ct.step_response(SISO, T), "b": "y"},
     r"resp\['b'\] must be a control.TimeResponseData, got str"),
    (lambda: {"a, From u[0]": ct.step_response(SISO, T), "a": ct.step_response(MIMO, T)},
     r"two responses are both named 'a, From u\[0\]': name them apart"),
])
def test_what_is_not_a_response_is_refused_with_what_is(resp, message):
    with pytest.raises(ValueError, match=message):
        plot(resp())


@pytest.mark.parametrize("kwargs, message", [
    ({"signals": ["z"]}, r"no signal matches 'z'; signals: \['y', 'x', 'u'\]"),
    ({"time_unit": "hours"}, r"time_unit must be one of \['ms', 's', 'min', 'h', 'd'\], "
                             r"got 'hours'"),
    ({"log": ["w"]}, r"no signal matches 'w'"),
    ({"units": "m"}, r"units must be a dict of signal pattern to value, got 'm'"),
    ({"derived": {"e": (np.mean, "y")}}, r"derived\['e'\] must give one value per time "
                                         r"point \(601\), got shape \(\)"),
    ({"derived": {"e": "y"}}, r"derived\['e'\] must be \(function, signals\)"),
    ({"max_points": 1}, r"max_points must be an integer >= 2, got 1"),
    ({"styles": "--"}, r"styles must be a dict of name to line style, got '--'"),
    ({"styles": {"w": "--"}}, r"no signal matches 'w'"),
])
def test_bad_arguments_say_what_is_allowed(kwargs, message):
    with pytest.raises(ValueError, match=message):
        plot(lag_response(), **kwargs)


def test_the_helper_is_controlkit_plot():
    assert controlkit.plot is plot
    assert "plot" in dir(controlkit)
