"""Functions made anew from the same ``def`` (a diagram's builder called again) share one
plan only while everything they read from outside is the same: each difference gives
python-control's own answer."""

import sys

import control as ct
import numpy as np
import pytest

import controlkit
from controlkit.engines.source import plan_function, sharing

T = np.linspace(0.0, 6.0, 121)


def agrees(loop, U=1.0, X0=0.0):
    """controlkit's response equals python-control's, to 1e-9."""
    times = T if not loop.dt else np.arange(0.0, 6.0 + 1e-9, loop.dt)
    ours = controlkit.input_output_response(loop, times, U, X0)
    ref = ct.input_output_response(loop, times, U, X0)
    np.testing.assert_allclose(ours.outputs, ref.outputs, rtol=1e-9, atol=1e-12)
    return ours.outputs


def limited_pi(limit, kaw=2.0, dt=0):
    """A PI with anti-windup whose rate calls its sibling closure ``output``."""

    def output(t, x, u, params):
        return np.clip(params["kp"] * u[0] + params["ki"] * x[0], -limit, limit)

    def rate(t, x, u, params):
        command = params["kp"] * u[0] + params["ki"] * x[0]
        return [u[0] + kaw / params["ki"] * (output(t, x, u, params) - command)]

    pi = ct.nlsys(rate, output, inputs="e", outputs="v", states="z", dt=dt, name="pi",
                  params={"kp": 0.8, "ki": 0.6})
    def lag(t, x, u, params):
        return [x[0] + dt * (u[0] - x[0])] if dt else [u[0] - x[0]]

    plant = ct.nlsys(lag, None, inputs="v", outputs="y", states="y", dt=dt, name="plant")
    error = ct.summing_junction(inputs=["r", "-y"], output="e", name="error", dt=dt)
    loop = ct.interconnect([error, pi, plant], inputs="r", outputs=["y", "v"],
                           name="limited_loop")
    return loop, rate, output


def test_a_builder_called_again_shares_the_plans_of_its_closures():
    loop, rate, output = limited_pi(0.5)
    first = agrees(loop)
    again, rate_again, output_again = limited_pi(0.5)
    assert agrees(again) == pytest.approx(first, abs=0.0)
    plan, plan_again = plan_function(rate), plan_function(rate_again)
    assert plan_again is not plan and plan_again.body is plan.body
    assert plan_again.function is rate_again
    # the sibling read from the closure is the new one, its plan shared in turn
    helper = plan_again.tree()[1]
    assert helper.function is output_again and helper.body is plan.tree()[1].body
    assert plan_again.valid() and plan.valid()


def test_a_closure_reading_another_value_is_planned_anew():
    loop, rate, _ = limited_pi(0.5)
    narrow = agrees(loop)
    wide_loop, wide_rate, _ = limited_pi(5.0)
    wide = agrees(wide_loop)
    assert plan_function(wide_rate).body is not plan_function(rate).body
    assert np.max(np.abs(narrow[1])) == pytest.approx(0.5)
    assert np.max(np.abs(wide[1])) > 0.6


def test_a_sibling_closure_reading_another_value_makes_its_caller_planned_anew():
    # rate reads the same kaw, output (its helper) another limit
    _, rate, _ = limited_pi(0.5, kaw=2.0)
    plan_function(rate)
    other_loop, other_rate, _ = limited_pi(0.25, kaw=2.0)
    assert plan_function(other_rate).body is not plan_function(rate).body
    assert np.max(np.abs(agrees(other_loop)[1])) == pytest.approx(0.25)


def test_a_discrete_builder_called_again_gives_python_controls_answer():
    loop, _, _ = limited_pi(0.5, dt=0.1)
    first = agrees(loop)
    again, _, _ = limited_pi(0.5, dt=0.1)
    assert agrees(again) == pytest.approx(first, abs=0.0)
    other, _, _ = limited_pi(0.3, dt=0.1)
    assert np.max(np.abs(agrees(other)[1])) == pytest.approx(0.3)


def test_a_closure_changed_after_its_plan_was_shared_is_planned_again():
    def build(gain):
        def update(t, x, u, params):
            return [gain * u[0] - x[0]]

        def retune(value):
            nonlocal gain
            gain = value

        block = ct.nlsys(update, None, inputs="u", outputs="y", states="y", name="lag")
        return ct.interconnect([block], inputs="u", outputs="y"), update, retune

    loop, update, _ = build(2.0)
    agrees(loop)
    again, update_again, retune = build(2.0)
    assert plan_function(update_again).body is plan_function(update).body
    retune(4.0)
    assert agrees(again)[-1] == pytest.approx(4.0, rel=1e-2)
    assert plan_function(update_again).body is not plan_function(update).body


def test_functions_made_with_other_defaults_are_planned_each():
    updates = [lambda t, x, u, params, k=k: [k * u[0] - x[0]] for k in (1.0, 3.0)]
    finals = []
    for update in updates:
        block = ct.nlsys(update, None, inputs="u", outputs="y", states="y", name="lag")
        finals.append(agrees(ct.interconnect([block], inputs="u", outputs="y"))[-1])
    assert finals == pytest.approx([1.0, 3.0], rel=1e-2)
    assert plan_function(updates[1]).body is not plan_function(updates[0]).body


FIRST_INNER = None  # the first builder's inner function, called by ``through_module``


def through_module(v):
    return FIRST_INNER(v)


def test_an_old_function_still_called_beside_its_new_twin_is_planned_anew():
    # the new top function calls its own new inner and, through a module function,
    # the first builder's inner: both in one kernel, so the shared names would clash
    global FIRST_INNER

    def build(scale):
        def inner(v):
            return scale * v

        def update(t, x, u, params):
            return [inner(u[0]) + through_module(u[0]) - x[0]]

        return inner, update

    inner, update = build(1.0)
    FIRST_INNER = inner
    try:
        plan = plan_function(update)
        _, update_again = build(1.0)
        plan_again = plan_function(update_again)
        assert plan_again.body is not plan.body
        names = [p.name for p in plan_again.tree()]
        assert len(names) == len(set(names))
        block = ct.nlsys(update_again, None, inputs="u", outputs="y", states="y",
                         name="twice")
        assert agrees(ct.interconnect([block], inputs="u", outputs="y"))[-1] == \
            pytest.approx(2.0, rel=1e-2)
    finally:
        FIRST_INNER = None


def test_only_a_bounded_number_of_plans_is_kept_for_sharing(tmp_path, monkeypatch):
    count = sharing._CODES_KEPT + 10
    (tmp_path / "many_defs.py").write_text("".join(
        f"def make_{k}(gain):\n    def update(t, x, u, params):\n"
        f"        return {k} * gain * x\n    return update\n\n" for k in range(count)))
    monkeypatch.syspath_prepend(str(tmp_path))
    import many_defs

    for k in range(count):
        for gain in range(sharing._PER_CODE + 2):  # more values than a code keeps
            plan_function(getattr(many_defs, f"make_{k}")(float(gain)))
    assert len(sharing._BY_CODE) == sharing._CODES_KEPT
    assert all(len(plans) == sharing._PER_CODE for plans in sharing._BY_CODE.values())


SCALE = 1.0  # read by ``scaled_input``, a module helper the closures below call


def scaled_input(v):
    return SCALE * v


def test_a_module_helper_reading_a_changed_global_is_planned_anew(monkeypatch):
    def build():
        def update(t, x, u, params):
            return [scaled_input(u[0]) - x[0]]

        block = ct.nlsys(update, None, inputs="u", outputs="y", states="y", name="lag")
        return ct.interconnect([block], inputs="u", outputs="y")

    assert agrees(build())[-1] == pytest.approx(1.0, rel=1e-2)
    monkeypatch.setattr(sys.modules[__name__], "SCALE", 3.0)
    assert agrees(build())[-1] == pytest.approx(3.0, rel=1e-2)
