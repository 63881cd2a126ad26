"""The diagram editor's Python side: round trips, wiring checks, edits and runs.

Round trip: an interconnect built in code -> the editor's model -> an interconnect (from
the model, from the code the editor writes, and from its saved JSON) must have the same
connection maps and labels, and simulate to the same numbers (1e-12), for the papers'
diagrams and for three diagrams written the way a python-control user writes them.
"""

from __future__ import annotations

import json
import subprocess
import sys
import warnings
from pathlib import Path

import control as ct
import numpy as np
import pytest

import controlkit
from controlkit.blocks import mec
from controlkit.blocks import spacecraft as sc
from controlkit.studies.cmg.diagrams import cmg_loop
from controlkit.studies.spacecraft import scenario as scenario
from controlkit.studies.spacecraft.diagrams import mec_loop, output_zeroing_loop
from controlkit.widget import (
    PALETTE,
    PROBLEM_KINDS,
    DiagramModel,
    _run,
    _sources,
    _view,
    passes_input,
)
from controlkit.widget._code import code_parameters

# ---------------------------------------------------------------------- diagrams


def speed_loop():
    """A continuous PI speed loop: transfer functions and a summing junction."""
    motor = ct.tf2ss(ct.tf([1.0], [0.5, 1.0]), name="motor", inputs="v", outputs="w")
    pi = ct.tf2ss(ct.tf([2.0, 1.0], [1.0, 0.0]), name="pi", inputs="e", outputs="v")
    error = ct.summing_junction(inputs=["w_ref", "-w"], output="e", name="error")
    return ct.interconnect([error, pi, motor], inputs="w_ref", outputs=["w", "v"],
                           name="speed_loop")


def tank_loop():
    """A discrete tank under a saturated valve: nlsys with a params dict, lambdas, np.clip."""
    Ts = 0.5

    def tank_update(t, x, u, params):
        area, leak = map(params.get, ("area", "leak"))
        return x + Ts * (u[0] - leak * np.sqrt(max(x[0], 0.0))) / area

    tank = ct.nlsys(tank_update, lambda t, x, u, params: x, inputs="q", outputs="level",
                    states="level", dt=Ts, params={"area": 1.5, "leak": 0.3}, name="tank")
    valve = ct.nlsys(None, lambda t, x, u, params: np.clip(2.0 * (u[0] - u[1]), 0.0, 1.0),
                     inputs=["level_ref", "level"], outputs="q", dt=None, name="valve")
    return ct.interconnect([tank, valve], inputs="level_ref", outputs=["level", "q"],
                           name="tank_loop")


def summed_loop():
    """Discrete, with an implicit sum (two drivers on one input, written in code with a
    minus sign), an external input feeding two blocks, a gain of 0.5 on a wire and an
    output taken from a block's input."""
    Ts = 0.1
    plant = ct.ss([[0.9, 0.1], [0.0, 0.8]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], dt=Ts,
                  name="plant", inputs="u", outputs="y")
    ctrl = ct.ss([[1.0]], [[Ts]], [[0.6]], [[1.5]], dt=Ts, name="ctrl", inputs="e",
                 outputs="c")
    ff = ct.tf(0.3, 1, dt=None, name="ff", inputs="r", outputs="f")
    return ct.interconnect(
        [plant, ctrl, ff],
        connections=[["ctrl.e", "-plant.y"], ["plant.u", "ctrl.c", ("ff", "f", 0.5)]],
        inplist=[["ctrl.e", "ff.r"]], inputs=["r"],
        outlist=["plant.y", "ctrl.e"], outputs=["y", "e"], name="summed_loop")


def motor_rhs(t, x, u, params):  # notebook 0's motor: tau w' = -w + k v
    tau, k = params["tau"], params["k"]
    return (-x[0] + k * u[0]) / tau


def first_loop_blocks(Ts=0.02):
    """Notebook 0's blocks: the continuous motor, its PI sampled at ``Ts``, the junction."""
    motor = ct.nlsys(motor_rhs, lambda t, x, u, params: x[0], inputs="v", outputs="w",
                     states="w", params={"tau": 0.5, "k": 2.0}, name="motor")
    pi = ct.tf2ss(ct.tf([2.5, 5.0], [1, 0]), inputs="e", outputs="v", name="pi")
    error = ct.summing_junction(["w_ref", "-w"], "e", name="error")
    return motor, ct.sample_system(pi, Ts, name="pi"), error


def sampled_speed_loop():
    """Notebook 0's sampled-data loop, built as the notebook builds it."""
    return controlkit.interconnect(list(first_loop_blocks()), inputs="w_ref",
                                   outputs=["w", "v"], name="sampled_loop")


def discrete_speed_loop():
    """Notebook 0's fully discrete loop: the motor sampled too."""
    motor, pi, error = first_loop_blocks()
    return ct.interconnect([controlkit.sample_nlsys(motor, 0.02), pi, error], inputs="w_ref",
                           outputs=["w", "v"], name="discrete_loop")


def fig3():
    return mec_loop(scenario.true_plant(model_error=True), K=0.1, name="fig3")


def fig4():
    return mec_loop(scenario.true_plant(model_error=True), K="frit",
                    h0=scenario.initial_attitude()[1:3], name="fig4")


Q0 = scenario.initial_attitude()
SPACECRAFT_X0 = {"plant": Q0, "nominal": Q0[1:3]}
DIAGRAMS = {  # builder, steps, initial states, constant inputs
    "fig2": (output_zeroing_loop, 300, {"plant": Q0}, 0.0),
    "fig3": (fig3, 300, SPACECRAFT_X0, 0.0),
    "fig4": (fig4, 300, SPACECRAFT_X0, 0.0),
    "cmg": (cmg_loop, 300, {}, 0.0),
    "speed_loop": (speed_loop, 400, {"motor": [0.2]}, 1.0),
    "tank_loop": (tank_loop, 200, {"tank": [0.1]}, 1.0),
    "summed_loop": (summed_loop, 200, {"plant": [1.0, -0.5]}, 1.0),
}


def response(sys, steps, initial, U):
    T = _run.time_points(steps * sys.dt if sys.dt else steps * 0.01, sys.dt)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a user block runs on python-control, with a warning
        resp = _run.simulate(sys, T, controlkit.initial_state(sys, **initial), U)
    return np.asarray(resp.outputs).reshape(sys.noutputs, -1)


def from_code(model, original=None, variable="edited", namespace=None):
    """The interconnect that the editor's code builds: its blocks the editor cannot write
    are taken from ``original`` (the opened diagram), its notebook variables from
    ``namespace``."""
    blocks = {s.name: s for s in original.syslist} if original is not None else {}
    arguments = {p: (namespace or {})[p] if model.blocks[name].recipe else blocks[name]
                 for p, name in code_parameters(model).items()}
    exported = {"__name__": "exported"}
    exec(compile(model.code(variable), "exported.py", "exec"), exported)  # noqa: S102
    return exported[f"build_{variable}"](**arguments)


def shown_labels(sys):
    """The display names a drawing of ``sys`` shows: the blocks' own, then its hints'."""
    labels = {s.name: s.display_name for s in sys.syslist
              if getattr(s, "display_name", None)}
    labels.update(getattr(sys, "drawing_hints", {}).get("labels", {}))
    return labels


def assert_same_diagram(a, b):
    assert [s.name for s in a.syslist] == [s.name for s in b.syslist]
    for field in ("connect_map", "input_map", "output_map"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)
    assert (a.input_labels, a.output_labels, a.state_labels) == (
        b.input_labels, b.output_labels, b.state_labels)
    assert a.dt == b.dt


# ---------------------------------------------------------------------- round trips


@pytest.mark.parametrize("key", DIAGRAMS)
def test_code_to_model_to_interconnect_is_the_same_diagram(key, tmp_path):
    build, steps, initial, U = DIAGRAMS[key]
    original = build()
    model = DiagramModel.from_interconnect(original, source_name="original")
    for block, x0 in initial.items():
        model.set_initial(block, x0)
    rebuilt = model.system()
    assert_same_diagram(original, rebuilt)
    # the code the editor writes builds the same interconnect
    written = from_code(model, original)
    assert_same_diagram(original, written)
    # and so does the saved JSON, loaded again
    model.to_json(tmp_path / "diagram.json")
    loaded = DiagramModel.from_dict(json.loads((tmp_path / "diagram.json").read_text()),
                                    systems=original).system()
    assert_same_diagram(original, loaded)
    # the display names (the builder's, and the blocks' own), frames and junction hints
    # travel along
    assert shown_labels(rebuilt) == shown_labels(original)
    assert getattr(written, "drawing_hints", {}) == rebuilt.drawing_hints
    expected = response(original, steps, initial, U)
    assert np.isfinite(expected).all()
    for other in (rebuilt, written, loaded):
        np.testing.assert_allclose(response(other, steps, initial, U), expected, rtol=0,
                                   atol=1e-12)


def fig3_without_mec():
    """The lecture's edit: the compensator deleted, the controller wired to the plant."""
    model = DiagramModel.from_interconnect(fig3())
    model.delete_block("mec")
    model.connect("controller", "mu_n", "linearizer", "mu")
    return model


def my_lag():
    return ct.tf([1.0], [0.2, 1.0], name="my_lag", inputs="a", outputs="b")


def speed_loop_limited():
    """Edited with a palette saturation and a notebook variable (my_lag)."""
    model = DiagramModel.from_interconnect(speed_loop())
    model.disconnect("pi", "v", "motor", "v")
    model.add_from_palette("saturation", limit=0.8)
    model.add_variable("my_lag", my_lag())
    model.connect("pi", "v", "saturation", "u")
    model.connect("saturation", "y", "my_lag", "a")
    model.connect("my_lag", "b", "motor", "v")
    return model


#: Every diagram the tests open, with the page's setup: the model, where blocks the editor
#: cannot write come from (a builder of this module), horizon, initial states, sources.
PAGES = {key: (lambda build=build: DiagramModel.from_interconnect(build()), build.__name__,
               steps * 0.1 if key in ("fig2", "fig3", "fig4", "summed_loop") else
               steps * (0.001 if key == "cmg" else 0.5 if key == "tank_loop" else 0.01),
               initial, {"kind": "constant", "value": U})
         for key, (build, steps, initial, U) in DIAGRAMS.items()}
PAGES.update({
    "fig3 without MEC": (fig3_without_mec, "fig3", 30.0, SPACECRAFT_X0, None),
    "notebook 0 sampled-data": (lambda: DiagramModel.from_interconnect(sampled_speed_loop()),
                                "sampled_speed_loop", 1.0, {},
                                {"kind": "step", "value": 1.0, "time": 0.2}),
    "notebook 0 discrete": (lambda: DiagramModel.from_interconnect(discrete_speed_loop()),
                            "discrete_speed_loop", 1.0, {"motor": [0.5]},
                            {"kind": "sine", "amplitude": 0.5, "frequency": 2.0}),
    "speed loop limited": (speed_loop_limited, "speed_loop", 3.0, {"motor": [0.2]},
                           {"kind": "step", "value": 1.0, "time": 0.5}),
})


def page(key):
    """The model of ``PAGES[key]`` with its setup, and the page's own run of it."""
    make, _, horizon, initial, src = PAGES[key]
    model = make()
    model.set_horizon(horizon)
    for block, x0 in initial.items():
        model.set_initial(block, x0)
    for name, _ in model.inputs if src else []:
        model.set_source(name, **src)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _, resp = _run.run_diagram(model, measures=[], scopes=[])
    return model, resp


DRIVER = """
import json, runpy, sys
import numpy as np

jobs = json.loads(sys.argv[1])
for job in jobs:
    if job["parameters"]:  # the blocks the editor cannot write: from the tests' builders
        sys.path.insert(0, job["tests"])
        import test_widget
        opened = {s.name: s for s in getattr(test_widget, job["builder"])().syslist}
        arguments = {p: getattr(test_widget, p)() if p == "my_lag" else opened[name]
                     for p, name in job["parameters"].items()}
        code = runpy.run_path(job["code"])
        response = code["simulate_diagram"](code["build_diagram"](**arguments))
    else:  # the code alone builds and runs the diagram
        response = runpy.run_path(job["code"])["response"]
    np.savez(job["out"], time=response.time, states=response.states,
             outputs=response.outputs, labels=response.output_labels)
"""


@pytest.fixture(scope="module")
def fresh_runs(tmp_path_factory):
    """Each page's ``.code()`` run in one fresh interpreter (``python -I``), and the page."""
    folder = tmp_path_factory.mktemp("exported")
    pages, jobs = {}, []
    for k, key in enumerate(PAGES):
        model, resp = pages[key] = page(key)
        (folder / f"page{k}.py").write_text(model.code("diagram"), encoding="utf-8")
        jobs.append({"code": str(folder / f"page{k}.py"), "out": str(folder / f"page{k}.npz"),
                     "builder": PAGES[key][1], "parameters": code_parameters(model),
                     "tests": str(Path(__file__).parent)})
    (folder / "driver.py").write_text(DRIVER, encoding="utf-8")
    done = subprocess.run([sys.executable, "-I", str(folder / "driver.py"), json.dumps(jobs)],
                          cwd=folder, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    return {key: (*pages[key], np.load(job["out"])) for key, job in zip(PAGES, jobs,
                                                                        strict=True)}


@pytest.mark.parametrize("key", PAGES)
def test_the_code_alone_gives_the_pages_result(fresh_runs, key):
    """``.code()`` in a fresh interpreter: the page's time points, states and outputs."""
    model, resp, alone = fresh_runs[key]
    np.testing.assert_array_equal(alone["time"], resp.time)
    assert np.isfinite(resp.states).all() and resp.states.shape[1] == resp.time.size
    np.testing.assert_allclose(alone["states"], resp.states, rtol=0, atol=1e-12)
    recorded = {label: k for k, label in enumerate(resp.output_labels)}
    compared = 0
    for row, (name, sources) in enumerate(model.outputs):
        if len(sources) == 1 and sources[0][0] == "out" and sources[0][3] == 1.0:
            block, signal = sources[0][1:3]
            assert str(alone["labels"][row]) == name
            np.testing.assert_allclose(alone["outputs"][row],
                                       resp.outputs[recorded[f"{block}.{signal}"]],
                                       rtol=0, atol=1e-12)
            compared += 1
    assert compared >= 1


def test_an_interconnect_built_from_the_editors_code_opens_identically():
    original = fig3()
    model = DiagramModel.from_interconnect(original, source_name="original")
    for block, x0 in SPACECRAFT_X0.items():
        model.set_initial(block, x0)
    again = DiagramModel.from_interconnect(from_code(model), source_name="original")
    assert again.to_dict()["wires"] == model.to_dict()["wires"]
    assert again.to_dict()["inputs"] == model.to_dict()["inputs"]
    assert again.to_dict()["outputs"] == model.to_dict()["outputs"]
    assert {n: b.label for n, b in again.blocks.items()} == {
        n: b.label for n, b in model.blocks.items()}
    assert again.hints == model.hints


def test_code_reads_like_a_students_interconnect_call():
    code = DiagramModel.from_interconnect(fig3(), source_name="fig3").code()
    # blocks whose factory call rebuilds them exactly are written as that call
    assert "controller = sc.outer_controller(F=0.0009, output='mu_n', name='controller')" in code
    assert "gain = mec.constant_gain(K=0.1, name='gain')" in code
    assert ("plant = controlkit.sample_nlsys(scenario.true_plant(model_error=True, "
            "name='plant'), 0.1)") in code
    # a block named like an imported module gets a variable of its own
    assert "mec_block = mec.mec_compensator(name='mec')" in code
    # vectors are connected as python-control ranges
    assert "['linearizer.mu[0:2]', 'mec.mu[0:2]']," in code
    assert "inplist=['controller.r[0:2]']," in code


def test_implicit_sums_written_in_code_are_kept_and_not_reported():
    model = DiagramModel.from_interconnect(summed_loop())
    assert ("plant", "u") in model.summed and ("ctrl", "e") in model.summed
    assert not [p for p in model.problems() if p.kind == "two drivers"]
    code = model.code()
    assert "['plant.u', 'ctrl.c', ('ff', 'f', 0.5)]," in code
    assert "['ctrl.e', '-plant.y']," in code
    assert "inplist=[['ctrl.e', 'ff.r']]," in code


# ---------------------------------------------------------------------- wrong wiring


def without_mec():
    model = DiagramModel.from_interconnect(fig3())
    model.delete_block("mec")
    return model


def test_deleting_a_block_leaves_its_inputs_unconnected_named():
    model = without_mec()
    messages = [p.message for p in model.problems() if p.kind == "unconnected input"]
    assert messages == ["unconnected input: linearizer.mu of block 'linearizer' has no driver "
                        "(python-control reads it as 0)"]
    assert PROBLEM_KINDS["unconnected input"] == "warning"
    model.system()  # a warning does not stop the build


def test_two_drivers_on_one_signal_name_both():
    model = without_mec()
    model.connect("controller", "mu_n", "linearizer", "mu")
    model.connect("nominal", "hn", "linearizer", "mu")
    problems = [p for p in model.problems() if p.kind == "two drivers"]
    assert [p.message for p in problems] == [
        "two drivers on one signal: linearizer.mu[0] is driven by controller.mu_n[0] and "
        "nominal.hn[0]; remove one wire, or add them in a summing junction",
        "two drivers on one signal: linearizer.mu[1] is driven by controller.mu_n[1] and "
        "nominal.hn[1]; remove one wire, or add them in a summing junction"]
    assert problems[0].blocks == ["linearizer", "controller", "nominal"]
    with pytest.raises(ValueError, match=r"cannot be built: two drivers on one signal: "
                                         r"linearizer\.mu\[0\]"):
        model.system()
    model.disconnect("nominal", "hn", "linearizer", "mu")
    assert not [p for p in model.problems() if p.severity == "error"]


def test_an_algebraic_loop_names_its_blocks_in_order():
    model = DiagramModel.from_interconnect(speed_loop())
    model.add_from_palette("gain", k=0.5)  # static: passes its input on at once
    model.disconnect("motor", "w", "error", "w")
    model.connect("error", "e", "gain", "u")
    model.connect("gain", "y", "error", "w")
    (loop,) = [p for p in model.problems() if p.kind == "algebraic loop"]
    assert loop.message == (
        "algebraic loop through blocks 'error' -> 'gain' -> 'error': each passes its input "
        "straight to its output, so no order of computing them exists; put a block with a "
        "state (a delay, a plant, a filter) in the loop")
    with pytest.raises(ValueError, match="algebraic loop through blocks 'error' -> 'gain'"):
        model.system()


def test_a_loop_through_a_block_with_state_is_no_algebraic_loop():
    for build in (output_zeroing_loop, fig3, fig4, cmg_loop, speed_loop, tank_loop):
        model = DiagramModel.from_interconnect(build())
        assert not [p for p in model.problems() if p.kind == "algebraic loop"], build


def test_timebases_are_refused_only_where_the_engine_refuses_them():
    """Continuous, discrete and several periods together run as a sampled-data diagram
    (controlkit.interconnect); what it refuses is reported with its reason."""
    model = without_mec()
    model.add_from_palette("pi")  # continuous design, sampled at the diagram's 0.1 s
    assert model.blocks["pi"].system.dt == 0.1
    model.add_block(ct.tf([1.0], [1.0, 1.0], name="lag", inputs="u", outputs="y"))
    model.add_block(mec.nominal_model(0.2, name="slow"))
    assert model.is_mixed() and not [p for p in model.problems() if p.severity == "error"]
    model.add_block(mec.nominal_model(0.25, name="odd"))
    (problem,) = [p for p in model.problems() if p.kind == "mismatched timebases"]
    assert problem.message == (
        "mismatched timebases: the sampling periods must be integer multiples of the "
        "shortest (0.1 s of 'plant'); got 'odd' at 0.25 s")
    assert problem.blocks == ["plant", "odd"]
    model.delete_block("odd")
    model.add_block(ct.tf([1.0], [1.0, 1.0], True, name="someday", inputs="u", outputs="y"))
    (problem,) = [p for p in model.problems() if p.kind == "mismatched timebases"]
    assert problem.message.startswith("mismatched timebases: blocks ['someday'] are "
                                      "discrete with no sampling period (dt=True)")
    with pytest.raises(ValueError, match="the diagram cannot be built: mismatched timebases"):
        model.system()


def test_notebook_0s_sampled_data_loop_opens_and_runs_as_the_engine_runs_it():
    """python-control refuses the loop (a continuous motor, a PI sampled at 20 ms);
    controlkit.interconnect builds it, and the editor opens, shows and runs it."""
    loop = sampled_speed_loop()
    model = DiagramModel.from_interconnect(loop)
    assert not [p for p in model.problems() if p.severity != "note"]
    assert model.is_mixed() and model.period() is None and model.run_period() == 0
    _view.place(model)
    blocks = {b["name"]: b for b in _view.view(model)["blocks"]}
    # each block's rate as draw_block_diagram writes it under the block
    assert {n: b["sub"] for n, b in blocks.items()} == {
        "motor": "continuous", "pi": "dt = 0.02", "error": "static"}
    assert [n for n, b in blocks.items() if b["discrete"]] == ["pi"]
    assert _view.view(model)["mixed"] is True
    model.set_horizon(1.0)
    model.set_source("w_ref", "step", value=1.0, time=0.0)
    _, resp = _run.run_diagram(model, measures=[], scopes=[])
    T = np.linspace(0.0, 1.0, 2001)
    reference = controlkit.input_output_response(loop, T, 1.0)
    np.testing.assert_allclose(resp.outputs[resp.output_labels.index("motor.w")],
                               reference.outputs[0], rtol=0, atol=1e-12)
    assert 1.0005 < reference.outputs[0].max() < 1.002  # the notebook's 0.1 % overshoot


def test_a_discrete_block_joins_a_continuous_diagram():
    model = DiagramModel.from_interconnect(speed_loop())
    model.delete_block("pi")
    pi = ct.sample_system(ct.tf2ss(ct.tf([2.0, 1.0], [1.0, 0.0])), 0.05, name="pi",
                          inputs="e", outputs="v")
    model.add_variable("pi_digital", pi)
    model.connect("error", "e", "pi", "e")
    model.connect("pi", "v", "motor", "v")
    assert not [p for p in model.problems() if p.severity != "note"]
    assert type(model.system()).__name__ == "SampledDataSystem"
    model.set_source("w_ref", "constant", value=1.0)
    model.set_horizon(4.0)
    result, resp = _run.run_diagram(model, measures=[], scopes=["motor.w"])
    direct = controlkit.interconnect(model.systems(), inputs="w_ref", outputs="w")
    expected = controlkit.input_output_response(direct, resp.time, 1.0)
    np.testing.assert_allclose(resp.outputs[resp.output_labels.index("motor.w")],
                               expected.outputs, rtol=0, atol=1e-12)
    assert 0.9 < result["traces"][0]["y"][-1] < 1.0  # on its way to w_ref = 1


def test_unused_outputs_are_notes():
    model = without_mec()
    assert not [p for p in model.problems() if p.kind == "unused output"]  # loop outputs
    model.add_from_palette("gain")
    notes = [p.message for p in model.problems() if p.kind == "unused output"]
    assert notes == ["unused output: gain2.y of block 'gain2' goes nowhere"]
    assert PROBLEM_KINDS["unused output"] == "note"


@pytest.mark.parametrize("call, message", [
    (lambda m: m.connect("controller", "mu_n", "linearizer", "q"),
     r"cannot connect controller\.mu_n \(2 signals\) to linearizer\.q \(4 signals\): the "
     r"ports must be equally wide"),
    (lambda m: m.connect("controller", "nope", "linearizer", "mu"),
     r"block 'controller' has no output port 'nope'; its outputs: \['mu_n'\]"),
    (lambda m: m.connect("ghost", "y", "linearizer", "mu"),
     r"no block named 'ghost' in the diagram"),
    (lambda m: m.disconnect("controller", "mu_n", "linearizer", "mu"),
     r"no wire runs from controller\.mu_n to linearizer\.mu"),
    (lambda m: m.delete_block("ghost"), r"no block named 'ghost'"),
    (lambda m: m.add_block(sc.attitude_output()),
     r"a block named 'output' is already in the diagram"),
    (lambda m: m.add_block(np.eye(2)), r"a block must be a python-control I/O system"),
    (lambda m: m.add_from_palette("lqr"), r"palette entry must be one of"),
    (lambda m: m.set_parameter("controller", "G", 1.0),
     r"block 'controller' has no parameter 'G'; its parameters: \['F'\]"),
    (lambda m: m.set_parameter("controller", "F", float("nan")),
     r"parameter 'F' of 'controller' must be finite"),
])
def test_every_refused_edit_says_why(call, message):
    with pytest.raises(ValueError, match=message):
        call(without_mec())


def test_from_interconnect_refuses_a_single_block():
    with pytest.raises(ValueError, match="sys must be a control.InterconnectedSystem"):
        DiagramModel.from_interconnect(sc.attitude_output())


def test_loading_json_needs_the_blocks_it_cannot_rebuild(tmp_path):
    model = DiagramModel.from_interconnect(fig4())  # its FRIT tuner keeps no factory call
    assert [n for n, b in model.blocks.items() if b.recipe is None] == ["tuner"]
    data = model.to_dict()
    with pytest.raises(ValueError, match=r"blocks\[3\]: block 'tuner' was taken from an "
                                         r"opened diagram and cannot be rebuilt"):
        DiagramModel.from_dict(data)
    with pytest.raises(ValueError, match="format: not a saved diagram"):
        DiagramModel.from_dict({"format": "other"})
    other = {"tuner": sc.outer_controller(name="tuner")}
    with pytest.raises(ValueError, match=r"block 'tuner' has inputs \['r\[0\]'"):
        DiagramModel.from_dict(data, systems=other)
    loaded = DiagramModel.from_dict(data, systems={"tuner": fig4().syslist[3]})
    assert_same_diagram(loaded.system(), model.system())


# ---------------------------------------------------------------------- the lecture's edit


def test_fig3_without_mec_misses_the_pointing_requirement():
    """The browser test's edit, from Python: delete MEC, wire the controller to the
    linearized plant; the pointing error then misses 0.05 deg (the paper's claim)."""
    model = DiagramModel.from_interconnect(fig3())
    model.set_horizon(20000.0)
    for block, x0 in SPACECRAFT_X0.items():
        model.set_initial(block, x0)
    measure = _run.Measure("pointing error", [f"plant.q[{i}]" for i in range(4)],
                           sc.pointing_error_deg, "deg", 0.05)
    kwargs = dict(measures=[measure], scopes=["output.h[0]"])
    before = _run.run_diagram(model, **kwargs)[0]["measures"][0]
    assert before["met"] and before["worst"] < 0.01
    model.delete_block("mec")
    model.connect("controller", "mu_n", "linearizer", "mu")
    after, _ = _run.run_diagram(model, **kwargs)
    summary = after["measures"][0]
    assert summary["met"] is False and 0.5 < summary["worst"] < 0.8
    assert summary["text"].endswith("> 0.05 deg: requirement missed")
    assert after["steps"] == 200_000 and len(after["time"]) == 1500
    assert len(after["traces"][0]["y"]) == 1500


def test_scoped_signals_are_the_blocks_outputs():
    model = DiagramModel.from_interconnect(speed_loop())
    model.set_horizon(2.0)
    model.set_source("w_ref", "constant", value=1.0)
    result, resp = _run.run_diagram(model, measures=[],
                                    scopes=["motor.w", "pi.v", "nothing.x"])
    assert [t["name"] for t in result["traces"]] == ["motor.w", "pi.v"]
    w = result["traces"][0]["y"]
    assert w[0] == 0.0 and 0.5 < w[-1] < 1.1  # the PI drives w towards w_ref = 1
    assert resp.output_labels == ["error.e", "pi.v", "motor.w"]
    with pytest.raises(ValueError, match=r"the diagram has no external input 'u'; its "
                                         r"inputs: \['w_ref'\]"):
        model.set_source("u", "constant", value=1.0)


def test_time_points_and_initial_state_checks():
    with pytest.raises(ValueError, match="horizon must be a positive number of seconds"):
        _run.time_points(-1.0, 0.1)
    with pytest.raises(ValueError, match=r"horizon must be at least one sample \(0.1 s\)"):
        _run.time_points(0.01, 0.1)
    with pytest.raises(ValueError, match=r"initial state of block 'plant' must have 4 values"):
        DiagramModel.from_interconnect(output_zeroing_loop()).set_initial("plant", [1.0])
    with pytest.raises(ValueError, match=r"horizon must be at most 2,000,000 samples of 0.1 s"):
        _run.time_points(1e9, 0.1)


# ---------------------------------------------------------------------- sources and inputs


@pytest.mark.parametrize("kind, fields", [
    ("constant", {"value": -0.7}),
    ("step", {"value": 2.0, "time": 0.35, "initial": -1.0}),
    ("ramp", {"slope": 0.3, "time": 1.1, "initial": 0.2}),
    ("sine", {"amplitude": 0.5, "frequency": 1.7, "phase": 0.3, "offset": 0.1}),
    ("sine", {"amplitude": 0.5, "frequency": 1.7}),
    ("sine", {"amplitude": 0.5, "frequency": 1.7, "offset": -0.2}),
    ("sine", {"amplitude": 0.5, "frequency": 1.7, "phase": 1.0}),
    ("ramp", {"slope": -2.0, "time": 0.5}),
    ("pulse", {"value": 1.5, "time": 0.4, "width": 0.25}),
    ("pulse", {"value": 1.5, "time": 0.4, "width": 0.25, "period": 0.6, "initial": 0.1}),
])
def test_a_sources_values_are_its_written_expression(kind, fields):
    """The page's U row and the exported code's numpy expression agree bit for bit."""
    import ast as python_ast

    src = _sources.source(kind, **fields)
    T = np.linspace(0.0, 3.0, 3001)
    written = eval(compile(python_ast.Expression(_sources.expression(src)), "source", "eval"),
                   {"np": np, "T": T})  # our own template, numbers as constants
    np.testing.assert_array_equal(written, _sources.values(src, T))
    assert np.ptp(written) > 0 or kind == "constant"


@pytest.mark.parametrize("kind, fields, message", [
    ("square", {}, r"source of 'w_ref'\.kind: must be one of \['constant', 'step', 'ramp', "
                   r"'sine', 'pulse'\], got 'square'"),
    ("step", {"when": 1.0}, r"source of 'w_ref': unknown field 'when'; allowed: \['initial', "
                            r"'kind', 'time', 'value'\]"),
    ("step", {"time": -1.0}, r"source of 'w_ref'\.time: must be a finite number in \[0, 1e"
                             r"\+12\], got -1\.0"),
    ("pulse", {"width": 0.0}, r"source of 'w_ref'\.width: must be a finite number > 0"),
    ("pulse", {"width": 2.0, "period": 1.0}, r"source of 'w_ref'\.period: must be 0 \(one "
                                             r"pulse\) or at least the width 2"),
    ("sine", {"amplitude": float("nan")}, r"source of 'w_ref'\.amplitude: must be a finite "
                                          r"number"),
])
def test_a_bad_source_names_its_field(kind, fields, message):
    model = DiagramModel.from_interconnect(speed_loop())
    with pytest.raises(ValueError, match=message):
        model.set_source("w_ref", kind, **fields)


def test_deleting_the_junction_keeps_the_input_and_its_source():
    """Deleting the err junction left no way to drive the loop again; now w_ref waits,
    unattached, with its source, and is wired to a new junction."""
    original = speed_loop()
    model = DiagramModel.from_interconnect(original)
    model.set_horizon(3.0)
    model.set_source("w_ref", "step", value=1.0, time=0.5)
    model.delete_block("error")
    assert model.inputs[0] == ("w_ref", [])
    assert model.source_of("w_ref")["kind"] == "step"
    (note,) = [p.message for p in model.problems() if p.kind == "unused input"]
    assert note == ("unused input: the external input w_ref drives nothing; it joins the "
                    "interconnect when it is wired to a block")
    assert model.system().ninputs == 0 and _run.run_arguments(model)["U"] == 0.0
    model.add_from_palette("summing_junction", signs="+-")
    model.connect_input("w_ref", "sum", "u1")
    model.connect("motor", "w", "sum", "u2")
    model.connect("sum", "y", "pi", "e")
    assert not [p for p in model.problems() if p.severity != "note"]
    _, resp = _run.run_diagram(model, measures=[], scopes=[])
    T = resp.time
    expected = controlkit.input_output_response(original, T, np.where(T >= 0.5, 1.0, 0.0))
    np.testing.assert_allclose(resp.outputs[resp.output_labels.index("motor.w")],
                               expected.outputs[0], rtol=0, atol=1e-12)


def test_inputs_are_added_wired_unwired_and_removed():
    model = DiagramModel.from_interconnect(fig3())
    model.delete_block("controller")
    assert [n for n, t in model.inputs] == ["r[0]", "r[1]"]
    assert model.input_groups() == [("r", ["r[0]", "r[1]"])]
    model.add_from_palette("outer_controller", output="mu_n")
    with pytest.raises(ValueError, match=r"cannot connect the external input r \(2 signals\) "
                                         r"to controller\.h\[0\] \(1 signal\)"):
        model.connect_input("r", "controller", "h[0]")
    model.connect_input("r", "controller", "r")
    assert model.inputs == [("r[0]", [("controller", "r[0]", 1.0)]),
                            ("r[1]", [("controller", "r[1]", 1.0)])]
    assert model.add_input("d", "plant", "u") == ["d[0]", "d[1]"]  # a vector port
    with pytest.raises(ValueError, match=r"the diagram already has an external input 'd\[0\]'"):
        model.add_input("d", "plant", "u")
    model.disconnect_input("d", "plant", "u")
    assert dict(model.inputs)["d[0]"] == []
    with pytest.raises(ValueError, match=r"the external input d does not drive plant\.u"):
        model.disconnect_input("d", "plant", "u")
    model.set_source("d[1]", "sine", amplitude=0.1)
    model.remove_input("d")
    assert [n for n, _ in model.inputs] == ["r[0]", "r[1]"] and "d[1]" not in model.sources
    with pytest.raises(ValueError, match=r"the diagram has no external input 'd'; its inputs: "
                                         r"\['r'\]"):
        model.remove_input("d")
    with pytest.raises(ValueError, match=r"the input's name: must be a name of 1 to 100"):
        model.add_input("a.b")


def test_the_page_builds_python_controls_arguments():
    """T, U, X0 of the page given to control.input_output_response itself: the same run."""
    model = DiagramModel.from_interconnect(speed_loop())
    model.set_horizon(2.0)
    model.set_source("w_ref", "pulse", value=1.0, time=0.2, width=0.5)
    model.set_initial("motor", [0.3])
    sys = model.system()
    arguments = _run.run_arguments(model, sys)
    assert set(arguments) >= {"T", "U", "X0", "params"}
    assert arguments["U"].shape == (1, 2001) and arguments["X0"].tolist() == [0.0, 0.3]
    reference = ct.input_output_response(sys, arguments["T"], arguments["U"], arguments["X0"],
                                         params=arguments["params"])
    _, page_run = _run.run_diagram(model, measures=[], scopes=[])
    np.testing.assert_allclose(page_run.states, reference.states, rtol=0, atol=1e-9)


def test_the_setup_is_saved_with_the_diagram():
    model = DiagramModel.from_interconnect(speed_loop())
    model.set_horizon(4.0)
    model.set_source("w_ref", "ramp", slope=0.5, time=1.0)
    model.set_initial("motor", [0.25])
    again = DiagramModel.from_json(model.to_json())
    assert (again.horizon, again.sources, again.initial) == (
        4.0, {"w_ref": {"kind": "ramp", "slope": 0.5, "time": 1.0, "initial": 0.0}},
        {"motor": [0.25]})


# ---------------------------------------------------------------------- palette and sliders


@pytest.mark.parametrize("key", [key for key, entry in PALETTE.items() if entry.shown])
def test_every_palette_block_builds_and_its_code_builds_the_same(key):
    model = DiagramModel.from_interconnect(output_zeroing_loop(), source_name="original")
    name = model.add_from_palette(key)
    block = model.blocks[name].system
    assert block.name == name
    namespace = {}
    source = model.code("edited")
    line = next(line for line in source.splitlines() if f"name={name!r}" in line).strip()
    for head in source.splitlines():
        if head.startswith(("import ", "from ")):
            exec(head, namespace)
    exec(line, namespace)
    again = namespace[line.split(" = ")[0]]
    assert (again.input_labels, again.output_labels, again.nstates, again.dt) == (
        block.input_labels, block.output_labels, block.nstates, block.dt)
    if block.nstates == 0 and block.ninputs:
        u = np.linspace(0.3, 0.9, block.ninputs)
        np.testing.assert_array_equal(again.output(0.0, [], u), block.output(0.0, [], u))


def test_a_slider_rebuilds_the_block_from_its_recipe():
    model = DiagramModel.from_interconnect(speed_loop())
    model.add_from_palette("pi", kp=1.0, ki=0.5)
    model.connect("error", "e", "pi2", "u")
    assert model.parameters("pi2") == {"kp": 1.0, "ki": 0.5}
    model.set_parameter("pi2", "kp", 3.0)
    assert model.blocks["pi2"].system.num[0][0].tolist() == [3.0, 0.5]
    assert [(w.src, w.dst) for w in model.wires if w.dst[0] == "pi2"] == [
        (("error", "e"), ("pi2", "u"))]
    assert "pi2 = ct.tf([3.0, 0.5], [1.0, 0.0], inputs='u', outputs='y', name='pi2')" in (
        model.code())


def test_a_slider_on_an_opened_block_of_ours_changes_its_factory_argument():
    model = DiagramModel.from_interconnect(fig3())
    assert model.parameters("controller") == {"F": 0.0009}
    model.set_parameter("controller", "F", 0.003)
    assert np.array_equal(model.blocks["controller"].system.F, [0.003, 0.003])
    assert model.blocks["controller"].system.output_labels == ["mu_n[0]", "mu_n[1]"]
    assert len([w for w in model.wires if "controller" in (w.src[0], w.dst[0])]) == 6
    assert model.inputs == [("r[0]", [("controller", "r[0]", 1.0)]),
                            ("r[1]", [("controller", "r[1]", 1.0)])]


def test_a_slider_on_a_params_dict_copies_the_block():
    original = tank_loop()
    model = DiagramModel.from_interconnect(original)
    assert model.parameters("tank") == {"area": 1.5, "leak": 0.3}
    model.set_parameter("tank", "leak", 0.6)
    assert model.blocks["tank"].system.params == {"area": 1.5, "leak": 0.6}
    assert original.syslist[0].params == {"area": 1.5, "leak": 0.3}  # the user's is untouched
    assert model.system().params["leak"] == 0.6


def test_a_notebook_variable_joins_by_name_and_is_written_by_name():
    my_filter = ct.tf([1.0], [2.0, 1.0], name="my_filter", inputs="x", outputs="xf")
    model = DiagramModel.from_interconnect(speed_loop(), source_name="loop")
    model.add_variable("my_filter", my_filter)
    model.add_variable("my_filter", my_filter)  # twice: a renamed copy
    assert list(model.blocks)[-2:] == ["my_filter", "my_filter2"]
    code = model.code()
    assert "    my_filter2 = my_filter.copy(name='my_filter2')" in code
    assert "my_filter = " not in code  # the variable itself is used as it is
    assert code_parameters(model) == {"my_filter": "my_filter"}  # the rest is rebuilt
    with pytest.raises(ValueError, match="variable 'x' holds a int, not a python-control"):
        model.add_variable("x", 3)


@pytest.mark.parametrize("system, expected", [
    (ct.tf([1.0], [1.0, 1.0]), False),
    (ct.tf([1.0, 0.0], [1.0, 1.0]), True),
    (sc.attitude_output(), True),          # declared by the controlkit block
    (mec.nominal_model(0.1), False),
    (ct.nlsys(lambda t, x, u, p: -x + u, lambda t, x, u, p: x, states=1, inputs=1,
              outputs=1), False),           # probed: the output reads the state only
    (ct.nlsys(None, lambda t, x, u, p: np.clip(u, -1, 1), inputs=1, outputs=1), True),
])
def test_feedthrough_is_read_or_probed(system, expected):
    assert passes_input(system) is expected


# ---------------------------------------------------------------------- the widget


@pytest.fixture
def editor():
    pytest.importorskip("anywidget", reason="the widget extra (anywidget) is not installed")
    from controlkit.widget import DiagramEditor

    fig = fig3()
    widget = DiagramEditor(fig, horizon=20000.0, initial=SPACECRAFT_X0,
                           namespace={"fig": fig, "lag": ct.tf([1], [1, 1], name="lag"),
                                      "number": 3})
    widget.add_measure("pointing error", [f"plant.q[{i}]" for i in range(4)],
                       sc.pointing_error_deg, unit="deg", limit=0.05, log=True)
    return widget


def test_the_widget_opens_where_the_drawing_places_the_blocks(editor):
    from controlkit.drawing._layout import layout

    L = layout(fig3())
    blocks = {b["name"]: b for b in editor.diagram["blocks"]}
    assert set(blocks) == {"plant", "output", "nominal", "gain", "controller", "mec",
                           "linearizer"}
    for name, b in blocks.items():  # 80 pixels per inch, y downwards
        assert (b["x"], b["y"]) == pytest.approx((80 * L.nodes[name]["x"],
                                                  -80 * L.nodes[name]["y"]))
    assert blocks["linearizer"]["label"] == r"$\beta(q)\,\mu - \alpha(q)$"
    assert blocks["plant"]["sub"] == "dt = 0.1"
    # the junction F (r - h): signs on the controller's ports r and h
    ports = {p["port"]: p for p in blocks["controller"]["inputs"]}
    assert (ports["r"]["sign"], ports["h"]["sign"], ports["h"]["junction"]) == (1.0, -1.0, True)
    assert editor.diagram["groups"] == [{"label": "$L_a$: linearized plant (Fig. 2)",
                                         "members": ["linearizer", "plant", "output"]}]
    assert editor.diagram["inputs"][0]["label"] == "r"
    assert editor.variables == ["fig", "lag"]
    assert editor.scopes == ["output.h[0]", "output.h[1]"]


def test_the_widget_applies_the_front_ends_messages(editor):
    editor._on_message(editor, {"op": "delete", "blocks": ["mec"]}, [])
    assert "mec" not in editor.model.blocks
    assert [p["kind"] for p in editor.problems if p["severity"] == "warning"] == [
        "unconnected input"]
    editor._on_message(editor, {"op": "connect", "source": ["controller", "mu_n"],
                                "target": ["linearizer", "mu"]}, [])
    assert not [p for p in editor.problems if p["severity"] != "note"]
    editor._on_message(editor, {"op": "connect", "source": ["controller", "mu_n"],
                                "target": ["linearizer", "q"]}, [])
    assert editor.status.startswith("ValueError: cannot connect controller.mu_n (2 signals)")
    editor._on_message(editor, {"op": "move", "positions": {"plant": [10, 20]}}, [])
    assert editor.model.blocks["plant"].position == (10.0, 20.0)
    editor._on_message(editor, {"op": "add", "key": "var:lag", "position": [0, 300]}, [])
    editor._on_message(editor, {"op": "add", "key": "pi", "position": [0, 400]}, [])
    assert list(editor.model.blocks)[-2:] == ["lag", "pi"]
    assert editor.model.blocks["pi"].position == (0.0, 400.0)
    editor._on_message(editor, {"op": "set_parameter", "block": "pi", "name": "kp",
                                "value": 2.0}, [])
    assert editor.model.parameters("pi") == {"kp": 2.0, "ki": 0.1}
    editor._on_message(editor, {"op": "disconnect",
                                "edges": [["controller", "mu_n", "linearizer", "mu"]]}, [])
    assert "unconnected input: linearizer.mu" in editor.problems[0]["message"]
    editor._on_message(editor, {"op": "scopes", "signals": ["plant.q[1]"]}, [])
    assert editor.scopes == ["plant.q[1]"]
    editor._on_message(editor, {"op": "wiggle"}, [])
    assert editor.status == "ValueError: unknown operation 'wiggle'"


def test_the_page_sets_inputs_sources_initial_states_and_the_horizon(editor):
    send = lambda **content: editor._on_message(editor, content, [])  # noqa: E731
    send(op="delete", blocks=["controller"])
    assert editor.diagram["inputs"][-1] == {
        "id": "in:free:r", "names": ["r[0]", "r[1]"], "target": None, "port": None,
        "sign": 1.0, "groups": ["r"], "label": "r", "source": "0"}
    send(op="add", key="outer_controller", position=[0, 0])
    send(op="connect_input", input="r", target=["controller", "r"])
    send(op="set_source", input="r", kind="step", fields={"value": 0.01, "time": 100})
    assert editor.diagram["inputs"][0]["source"] == "step 0.01 at 100 s"
    assert editor.diagram["setup"]["sources"]["r[1]"]["text"] == (
        "step from 0 to 0.01 at t = 100 s")
    send(op="set_source", input="r", kind="step", fields={"value": 0.01, "time": -1})
    assert editor.status == ("ValueError: source of 'r[0]'.time: must be a finite number in "
                             "[0, 1e+12], got -1.0")
    send(op="add_input", name="d", target=["plant", "u"])
    send(op="remove_input", input="d")
    assert [g for g, _ in editor.model.input_groups()] == ["r"]
    send(op="set_initial", block="nominal", values=[0.1, 0.2])
    assert editor.diagram["setup"]["initial"]["nominal"] == {
        "values": [0.1, 0.2], "set": True, "states": ["hn[0]", "hn[1]"]}
    send(op="set_initial", block="nominal", values=[0.1])
    assert editor.status.startswith("ValueError: initial state of block 'nominal' must have "
                                    "2 values (hn[0], hn[1]), got 1")
    send(op="horizon", value=200.0)
    assert editor.model.horizon == editor.horizon == 200.0
    assert "np.where(T >= 100.0, 0.01, 0.0),  # 'r[0]': step from 0 to 0.01 at t = 100 s" in (
        editor.code_text)


def state(editor):
    """What an edit changes, as the saved file has it (positions included)."""
    return json.loads(editor.model.to_json())


@pytest.mark.parametrize("op", [
    {"op": "move", "positions": {"plant": [10, 20]}},
    {"op": "delete", "blocks": ["mec"]},
    {"op": "disconnect", "edges": [["mec", "mu", "linearizer", "mu"]]},
    {"op": "connect", "source": ["nominal", "hn"], "target": ["controller", "r"]},
    {"op": "add", "key": "pi", "position": [0, 400]},
    {"op": "add", "key": "var:lag", "position": [0, 400]},
    {"op": "set_parameter", "block": "gain", "name": "K", "value": 0.02},
    {"op": "add_input", "name": "d", "target": ["plant", "u"]},
    {"op": "disconnect_input", "input": "r", "target": ["controller", "r"]},
    {"op": "remove_input", "input": "r"},
    {"op": "set_source", "input": "r", "kind": "sine", "fields": {"amplitude": 0.01}},
    {"op": "set_initial", "block": "nominal", "values": [0.1, 0.2]},
    {"op": "horizon", "value": 500.0},
    {"op": "paste", "blocks": ["controller", "mec"]},
    {"op": "relayout"},
], ids=lambda op: op["op"])
def test_every_edit_of_the_page_is_undone_and_redone(editor, op):
    editor._on_message(editor, {"op": "move", "positions": {"gain": [5, 5]}}, [])
    before = state(editor)
    editor._on_message(editor, op, [])
    assert editor.status == "" and editor.can_undo
    after = state(editor)
    assert after != before
    editor._on_message(editor, {"op": "undo"}, [])
    assert state(editor) == before and editor.can_redo
    editor._on_message(editor, {"op": "redo"}, [])
    assert state(editor) == after and not editor.can_redo
    assert editor.horizon == editor.model.horizon


def test_a_refused_edit_leaves_nothing_to_undo(editor):
    before = state(editor)
    editor._on_message(editor, {"op": "connect", "source": ["controller", "mu_n"],
                                "target": ["linearizer", "q"]}, [])
    assert editor.status.startswith("ValueError: cannot connect controller.mu_n (2 signals)")
    assert state(editor) == before and not editor.can_undo
    editor._on_message(editor, {"op": "undo"}, [])
    assert editor.status == "nothing to undo" and state(editor) == before


def rectangles(editor):
    return {b["name"]: (b["x"] - b["w"] / 2, b["y"] - b["h"] / 2, b["x"] + b["w"] / 2,
                        b["y"] + b["h"] / 2) for b in editor.diagram["blocks"]}


def overlapping(editor, name):
    mine = rectangles(editor)[name]
    return [n for n, r in rectangles(editor).items() if n != name and mine[0] < r[2]
            and r[0] < mine[2] and mine[1] < r[3] and r[1] < mine[3]]


def test_new_and_pasted_blocks_overlap_no_block(editor):
    plant = next(b for b in editor.diagram["blocks"] if b["name"] == "plant")
    dropped = editor.add_block("pid", position=(plant["x"], plant["y"]))  # onto the plant
    placed = editor.add_block("pi")  # no position: where the drawing would put it
    assert overlapping(editor, dropped) == [] and overlapping(editor, placed) == []
    assert editor.paste(["controller", "mec"]) == ["controller2", "mec2"]
    assert overlapping(editor, "controller2") == [] and overlapping(editor, "mec2") == []
    wires = [(w.src, w.dst) for w in editor.model.wires if w.src[0] == "controller2"]
    assert wires == [(("controller2", f"mu_n[{i}]"), ("mec2", f"mu_n[{i}]")) for i in (0, 1)]
    assert editor.model.blocks["controller2"].recipe == editor.model.blocks["controller"].recipe


def test_relayout_places_the_blocks_as_on_opening(editor):
    opened = {n: b.position for n, b in editor.model.blocks.items()}
    editor._on_message(editor, {"op": "move", "positions": {"plant": [900, 900],
                                                            "mec": [-500, 0]}}, [])
    editor.relayout()
    assert {n: b.position for n, b in editor.model.blocks.items()} == opened
    editor.add_block("pi")  # wired to nothing: under the diagram
    editor.relayout()
    lowest = max(b.position[1] for n, b in editor.model.blocks.items() if n != "pi")
    assert editor.model.blocks["pi"].position[1] > lowest + 100 and overlapping(editor, "pi") == []


def test_save_and_load_in_the_page(editor):
    editor._on_message(editor, {"op": "set_source", "input": "r", "kind": "step",
                                "fields": {"value": 0.01, "time": 50.0}}, [])
    editor._on_message(editor, {"op": "save"}, [])
    saved = editor.download
    assert saved["name"] == "fig3.json" and saved["serial"] == 1
    assert editor.status == "saved fig3.json"
    editor.delete_block("mec")
    edited = state(editor)
    editor._on_message(editor, {"op": "load", "text": saved["text"]}, [])
    assert editor.status == "" and state(editor) == json.loads(saved["text"])
    assert editor.model.source_of("r[0]")["time"] == 50.0
    editor._on_message(editor, {"op": "undo"}, [])
    assert state(editor) == edited
    hostile = json.loads(saved["text"])
    hostile["blocks"][0]["recipe"]["kwargs"]["__import__('os')"] = 1
    editor._on_message(editor, {"op": "load", "text": json.dumps(hostile)}, [])
    assert editor.status.startswith("ValueError: blocks[0].recipe.kwargs: 'true_plant' takes "
                                    "no keyword argument")
    assert state(editor) == edited


def test_the_run_button_reports_the_requirement(editor):
    editor.delete_block("mec")
    editor.connect("controller", "mu_n", "linearizer", "mu")
    editor._on_message(editor, {"op": "run", "horizon": 20000.0}, [])
    assert editor.status.startswith("ran 200,000 steps in ")
    (measure,) = editor.results["measures"]
    assert measure["met"] is False
    assert "requirement missed" in measure["text"]
    assert editor.system.syslist[-1].name == "linearizer"
    assert "['linearizer.mu[0:2]', 'controller.mu_n[0:2]']," in editor.code()


def test_a_rewired_diagram_loses_the_builders_title_but_keeps_its_blocks_symbols():
    model = DiagramModel.from_interconnect(mec_loop(K=0.1))
    assert model.system().drawing_hints["title"] == "Fig. 3: MEC with a constant gain K"
    model.set_parameter("gain", "K", 0.01)  # another K: still Fig. 3
    assert model.system().drawing_hints["title"] == "Fig. 3: MEC with a constant gain K"
    model.delete_block("mec")
    model.connect("controller", "mu_n", "linearizer", "mu")
    rewired = model.system()
    assert "title" not in rewired.drawing_hints  # drawn under its name, mec_loop
    assert rewired.drawing_hints["labels"]["controller"] == "$F$"


def test_without_a_kernel_the_page_shows_the_drawing(editor, tmp_path):
    data, _ = editor._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in data
    svg = data["image/svg+xml"]
    # titled by the diagram's name (fig3() names it), the blocks by the paper's symbols
    assert svg.startswith("<?xml") and ">fig3</text>" in svg and "<!-- $F$ -->" in svg
    editor.save(tmp_path / "fig3.json")
    from controlkit.widget import DiagramEditor

    again = DiagramEditor.load(tmp_path / "fig3.json", systems=fig3(), namespace={})
    assert again.diagram["blocks"] == editor.diagram["blocks"]


def test_the_bundle_is_committed_and_small():
    from controlkit.widget._editor import STATIC

    js, css = STATIC / "editor.js", STATIC / "editor.css"
    assert 100_000 < js.stat().st_size < 600_000
    assert css.stat().st_size < 40_000
    assert "react-flow" in css.read_text()


def test_code_of_a_diagram_edited_with_palette_blocks_and_variables_builds_it():
    """Built in the editor, then rebuilt from its code: same diagram, same numbers."""
    original = speed_loop()
    my_lag = ct.tf([1.0], [0.2, 1.0], name="my_lag", inputs="a", outputs="b")
    model = DiagramModel.from_interconnect(original, source_name="original")
    model.disconnect("pi", "v", "motor", "v")
    model.add_from_palette("saturation", limit=0.8)
    model.add_variable("my_lag", my_lag)
    model.connect("pi", "v", "saturation", "u")
    model.connect("saturation", "y", "my_lag", "a")
    model.connect("my_lag", "b", "motor", "v")
    assert not [p for p in model.problems() if p.severity != "note"]
    built = model.system()
    edited = from_code(model, original, namespace={"my_lag": my_lag})
    assert_same_diagram(built, edited)
    np.testing.assert_allclose(response(edited, 300, {}, 1.0),
                               response(built, 300, {}, 1.0), rtol=0, atol=1e-12)
    v = response(built, 300, {}, 1.0)[1]  # the PI's output, before the limiter
    assert v.max() > 0.8  # the limiter has something to do
