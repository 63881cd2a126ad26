"""Diagrams built the python-control way run compiled, with python-control's numbers."""

import numpy as np
import pytest
from idiom_diagrams import DIAGRAMS as IDIOM_DIAGRAMS
from idiom_diagrams import expected_tier
from user_diagrams import DIAGRAMS

from controlkit.engines import fast as engine
from controlkit.simulation import simulate


@pytest.mark.parametrize("name", list(DIAGRAMS))
def test_user_diagram_is_compiled_and_equals_python_control(name):
    loop, T, X0, U, params = DIAGRAMS[name]()
    tiers = engine.explain(loop, params=params)
    assert [row.tier for row in tiers] == ["compiled"] * len(loop.syslist), tiers
    ref = simulate(loop, T, X0=X0, U=U, params=params)
    fast = simulate(loop, T, X0=X0, U=U, params=params, engine="fast")
    assert list(fast.state_labels) == list(ref.state_labels)
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)
    np.testing.assert_allclose(fast.states, ref.states, rtol=0, atol=1e-9)
    assert np.abs(ref.outputs).max() > 0.1  # the loop does something


# --- what is refused, and how --------------------------------------------------------------

import control as ct  # noqa: E402
from user_diagrams import TS, lti_loop, sampled_lti_plant, tank_with_params  # noqa: E402

from controlkit.blocks import spacecraft as sc  # noqa: E402
from controlkit.blocks.contract import KernelBlock  # noqa: E402
from controlkit.blocks.sampling import SamplingError, sample_nlsys  # noqa: E402
from controlkit.kernels.common import saturation_output  # noqa: E402
from controlkit.simulation import initial_state  # noqa: E402
from controlkit.studies.spacecraft.diagrams import output_zeroing_loop  # noqa: E402
from controlkit.studies.spacecraft.scenario import initial_attitude  # noqa: E402

ENGINES = ["python-control", "fast"]


def test_block_declared_without_feedthrough_whose_output_moves_with_its_input_is_refused():
    limiter = KernelBlock(saturation_output, params=[1.0], feedthrough=False,
                           inputs="v", outputs="u", dt=None, name="limiter")
    loop, T, X0, U, _ = lti_loop(steps=10)
    loop = ct.interconnect([*[s for s in loop.syslist if s.name != "disturbance"], limiter,
                            ct.summing_junction(["u", "d"], "u_plant", name="disturbance")],
                           inputs=["r", "d"], outputs=["y"])
    with pytest.raises(ValueError, match=r"block 'limiter' is declared without feedthrough"):
        engine.simulate(loop, T, np.zeros(loop.nstates), U)


def test_a_blocks_declared_feedthrough_is_probed_in_python_without_loading_its_kernel():
    # the compiled kernel would be loaded from numba's cache for the probe (7 ms of a
    # first call); its Python function answers the same question
    import numba

    from controlkit.engines.fast.tiers import blocks_of

    @numba.njit
    def held(t, x, u, p, out):
        out[0] = x[0]
        return out

    @numba.njit
    def passed_on(t, x, u, p, out):
        out[0] = x[0] + u[0]
        return out

    for kernel, refused in ((held, False), (passed_on, True)):
        block = KernelBlock(kernel, lambda t, x, u, p, out: out, feedthrough=False,
                            inputs="v", outputs="y", states="z", name="store")
        loop = ct.interconnect([block], inputs="v", outputs="y")
        if refused:
            with pytest.raises(ValueError, match="'store' is declared without feedthrough"):
                blocks_of(loop)
        else:
            assert [b.tier for b in blocks_of(loop)] == ["compiled"]
        assert len(kernel.overloads) == 0  # never compiled nor loaded for it


@pytest.mark.parametrize("which", ENGINES)
def test_unknown_params_key_is_refused_on_both_engines(which):
    loop = output_zeroing_loop(controller=sc.outer_controller(0.5))
    X0 = initial_state(loop, plant=initial_attitude())
    with pytest.raises(ValueError, match=r"params \['F'\] are read by no block of 'fig2_loop'"):
        simulate(loop, [0.0, 0.1], X0=X0, params={"F": 10}, engine=which)


def test_the_drop_in_accepts_a_params_key_no_block_reads_as_python_control_does():
    """docs/fast-blocks.md: only ``simulate`` refuses such a key; the drop-in changes nothing."""
    import controlkit

    loop, T, X0, U, _ = tank_with_params(steps=50)
    misspelt = controlkit.input_output_response(loop, T, U, X0, params={"laek": 0.9},
                                                compile=False)  # (the engine's, short)
    reference = ct.input_output_response(loop, T, U, X0, params={"laek": 0.9})
    default = controlkit.input_output_response(loop, T, U, X0)
    np.testing.assert_allclose(misspelt.outputs, reference.outputs, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(misspelt.outputs, default.outputs)
    own = output_zeroing_loop(controller=sc.outer_controller(0.5))
    X0 = initial_state(own, plant=initial_attitude())
    T = np.array([0.0, 0.1, 0.2])  # (a list: python-control subtracts lists, TypeError)
    bound = controlkit.input_output_response(own, T, 0.0, X0, params={"F": 10},
                                             compile=False)
    np.testing.assert_array_equal(
        bound.outputs, controlkit.input_output_response(own, T, 0.0, X0).outputs)


@pytest.mark.parametrize("which", ENGINES)
def test_params_are_honoured_on_both_engines(which):
    loop, T, X0, U, params = tank_with_params(steps=50)
    default = simulate(loop, T, X0=X0, U=U, engine=which)
    changed = simulate(loop, T, X0=X0, U=U, params={"leak": 0.9}, engine=which)
    ref = ct.input_output_response(loop, T, U, X0, params={"leak": 0.9})
    np.testing.assert_allclose(changed.outputs, ref.outputs, rtol=0, atol=1e-12)
    assert np.abs(changed.outputs - default.outputs).max() > 1e-2


def stiff_loop():
    stiff = ct.nlsys(lambda t, x, u, params: -400.0 * x + u, None, inputs="u", outputs="y",
                     states=1, name="stiff")
    gain = ct.summing_junction(["r", "-y"], "u", name="error")
    return ct.interconnect([sample_nlsys(stiff, TS), gain], inputs="r", outputs="y")


@pytest.mark.parametrize("which", ["python-control", "fast"])
def test_sampled_block_that_blows_up_is_named_with_the_remedy(which):
    loop = stiff_loop()
    T = np.arange(400) * TS
    with pytest.raises(SamplingError, match=r"block 'stiff' blows up inside a sample at t = .*"
                                            r"more substeps .* method='solve_ivp'"):
        simulate(loop, T, X0=[1.0], U=1.0, engine=which)


def test_more_substeps_cure_the_blow_up():
    stiff = ct.nlsys(lambda t, x, u, params: -400.0 * x + u, None, inputs="u", outputs="y",
                     states=1, name="stiff")
    sampled = sample_nlsys(stiff, TS, substeps=20)
    assert sampled.dynamics(0.0, [1.0], [0.0])[0] == pytest.approx(np.exp(-20.0), abs=1e-6)


@pytest.mark.parametrize("make", [
    lambda: ct.ss([[0.0, 1.0], [-4.0, -0.4]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]],
                  name="msd", inputs="F", outputs="p", states=["p", "v"]),
    lambda: ct.tf([2.0, 1.0], [1.0, 3.0, 2.0], name="msd", inputs="F", outputs="p"),
])
def test_sample_nlsys_of_lti_is_exact_zoh_and_keeps_names(make):
    sys = make()
    ours = sample_nlsys(sys, TS)
    ref = ct.sample_system(sys, TS, method="zoh")
    assert ours.name == "msd" and "$" not in ours.name
    assert ours.input_labels == ["F"] and ours.output_labels == ["p"]
    a, b = ct.ss(ours), ct.ss(ref)
    for m in "ABCD":
        np.testing.assert_allclose(getattr(a, m), getattr(b, m), rtol=0, atol=1e-12)


def test_sampled_lti_connects_by_name_and_compiles():
    loop, T, X0, U, _ = sampled_lti_plant(steps=5)
    assert [s.name for s in loop.syslist] == ["msd", "feedback"]
    assert {r.tier for r in engine.explain(loop)} == {"compiled"}


@pytest.mark.parametrize("which", ENGINES)
@pytest.mark.parametrize("args, message", [
    (([], [0.0, 0.0, 0.0], 0.0), r"T must be a non-empty 1-D array"),
    (([0.0, 0.1], [0.0, 0.0, 0.0], 0.0), r"time steps of T must equal the sampling time 0.05"),
    (([0.0, TS], [0.0, 0.0], 0.0), r"X0 must have 3 values \(plant_x\[0\].*got 2"),
    (([0.0, TS], [0.0, 0.0, np.nan], 0.0), r"X0 must be finite"),
    (([0.0, TS], [0.0, 0.0, 0.0], np.ones((3, 2))), r"U must be a scalar, one value per input"),
    (([0.0, TS], [0.0, 0.0, 0.0], [np.inf, 0.0]), r"U must be finite"),
])
def test_bad_arguments_get_the_same_error_on_both_engines(which, args, message):
    loop, *_ = lti_loop(steps=2)
    with pytest.raises(ValueError, match=message):
        T, X0, U = args
        simulate(loop, T, X0=X0, U=U, engine=which)


def test_one_value_per_input_and_stateless_diagrams_work_on_both_engines():
    gain = ct.nlsys(None, lambda t, x, u, params: 2.0 * u[0] - u[1], inputs=["a", "b"],
                    outputs="c", dt=TS, name="gain")
    total = ct.summing_junction(["c", "a"], "s", name="total")
    loop = ct.interconnect([gain, total], inputs=["a", "b"], outputs=["s"])
    T = np.arange(4) * TS
    results = [simulate(loop, T, X0=[], U=[1.0, 0.5], engine=w).outputs for w in ENGINES]
    for outputs in results:
        np.testing.assert_array_equal(outputs, [[2.5, 2.5, 2.5, 2.5]])


def test_function_numba_cannot_compile_runs_in_python_inside_the_fast_loop():
    table = {0: 0.5, 1: 2.0}  # a dict looked up by a signal: numba cannot compile it

    def update(t, x, u, params):
        return x + TS * (table[int(u[0] > 0.5)] * u[0] - x[0])

    plant = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="plant")
    loop = ct.interconnect([plant, ct.summing_junction(["r", "-y"], "u", name="error")],
                           inputs="r", outputs="y")
    row = engine.explain(loop)[0]
    assert row.tier == "python" and "dict" in row.reason
    T = np.arange(50) * TS
    fast = simulate(loop, T, X0=[0.0], U=1.0, engine="fast")
    np.testing.assert_allclose(fast.outputs, simulate(loop, T, X0=[0.0], U=1.0).outputs,
                               rtol=0, atol=1e-12)


def test_continuous_diagram_runs_compiled_and_equals_python_control():
    plant = ct.nlsys(lambda t, x, u, params: -x + u, None, inputs="u", outputs="y", states=1,
                     name="plant")
    loop = ct.interconnect([plant, ct.summing_junction(["r", "-y"], "u", name="error")],
                           inputs="r", outputs="y")
    assert {r.tier for r in engine.explain(loop)} == {"compiled"}
    T = np.linspace(0.0, 1.0, 11)
    fast = simulate(loop, T, X0=[0.0], U=1.0, engine="fast")
    ref = ct.input_output_response(loop, T, 1.0, 0.0)
    np.testing.assert_array_equal(fast.outputs, ref.outputs)


def test_lti_blocks_with_feedthrough_in_a_chain_are_ordered_and_exact():
    # D != 0 in the lead filter, the gain and the junction: ordered after the plant
    lead = ct.sample_system(ct.tf([2.0, 1.0], [0.5, 1.0]), TS, name="lead", inputs="e",
                            outputs="v")
    gain = ct.tf(3.0, 1.0, name="gain", inputs="v", outputs="u")
    plant = ct.sample_system(ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]]), TS, name="plant",
                             inputs="u", outputs="y")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = ct.interconnect([error, gain, lead, plant], inputs="r", outputs=["y", "u"])
    assert {r.tier for r in engine.explain(loop)} == {"compiled"}
    T = np.arange(200) * TS
    fast = simulate(loop, T, X0=np.zeros(loop.nstates), U=1.0, engine="fast")
    ref = ct.input_output_response(loop, T, 1.0, np.zeros(loop.nstates))
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-9)


def test_values_read_by_a_user_function_are_taken_afresh_at_each_run():
    gain = np.array([0.5])

    def update(t, x, u, params):
        return [x[0] + TS * (gain[0] * u[0] - params.get("leak", 0.1) * x[0])]

    plant = ct.nlsys(update, None, inputs="u", outputs="y", states=1, dt=TS, name="plant")
    loop = ct.interconnect([plant, ct.summing_junction(["r", "-y"], "u", name="error")],
                           inputs="r", outputs="y")
    T = np.arange(30) * TS
    first = simulate(loop, T, X0=[0.0], U=1.0, engine="fast").outputs
    gain[0] = 2.0  # the user edits the array between runs
    second = simulate(loop, T, X0=[0.0], U=1.0, params={"leak": 0.3}, engine="fast").outputs
    ref = simulate(loop, T, X0=[0.0], U=1.0, params={"leak": 0.3}).outputs
    np.testing.assert_allclose(second, ref, rtol=0, atol=1e-12)
    assert np.abs(second - first).max() > 0.1


# --- the diagram's module compiled and run as Python: the same numbers ---------------------

def _large_blocks():
    """An LTI block too large to be written out term by term, and a sampled block with more
    states than are written out one line each (codegen's two loop forms)."""
    rng = np.random.default_rng(3)
    n = 14
    A = -np.eye(n) + 0.1 * rng.standard_normal((n, n))
    big = ct.sample_system(ct.ss(A, rng.standard_normal((n, 2)), rng.standard_normal((2, n)),
                                 np.zeros((2, 2)), inputs=["a", "b"], outputs=["p", "q"],
                                 name="big"), TS)
    def chain_rhs(t, x, u, params):
        dx = np.empty(10)
        dx[0] = u[0] - x[0]
        for i in range(1, 10):
            dx[i] = x[i - 1] - x[i]
        return dx

    chain = ct.nlsys(chain_rhs, lambda t, x, u, params: x[-1], inputs="p", outputs="c",
                     states=10, name="chain")
    loop = ct.interconnect([big, sample_nlsys(chain, TS, substeps=2)], inputs=["a", "b"],
                           outputs=["p", "q", "c"], name="large")
    T = np.arange(300) * TS
    return loop, T, np.zeros(loop.nstates), np.vstack([np.sin(T), np.cos(T)]), None


def _papers_cmg():
    from controlkit.studies.cmg.diagrams import cmg_loop

    loop = cmg_loop()
    T = np.arange(2000) * loop.dt
    return loop, T, np.zeros(loop.nstates), np.zeros((loop.ninputs, T.size)), None


#: Diagrams whose compiled numbers may differ from Python's in the last bits, and why: a
#: matrix product, which numba and numpy round differently (the others agree to the bit).
NOT_TO_THE_BIT = {"hares and lynx (state feedback)": "K @ (x - xe): numba's and numpy's "
                                                     "matrix products round differently"}


@pytest.mark.parametrize("name", [*DIAGRAMS, *IDIOM_DIAGRAMS, "large blocks", "cmg",
                                  "large blocks, states recorded in a loop"])
def test_the_diagrams_module_compiled_gives_its_numbers_run_as_python(name, monkeypatch):
    # one text, two ways of running it: LTI blocks and RK4 substeps written out term by
    # term or looped over, users' functions translated, a step's signals in locals or in
    # an array; compiled (numba) and as Python (the kernels' and users' own functions)
    from controlkit.engines.fast import codegen

    if name.endswith("in a loop"):  # a step of more states than it holds in locals
        monkeypatch.setattr(codegen, "STATES_HELD_IN_LOCALS", 4)
    make = {**DIAGRAMS, **IDIOM_DIAGRAMS, "large blocks": _large_blocks, "cmg": _papers_cmg,
            "large blocks, states recorded in a loop": _large_blocks}
    loop, T, X0, U, params = make[name]()
    X0 = np.asarray(X0, dtype=float)
    engine.simulate(loop, T, X0, U, params=params, compile=True)  # compiled, checked once
    runs = {mode: engine.simulate(loop, T, X0, U, params=params, compile=mode == "compiled")
            for mode in ("compiled", "python")}  # then compiled throughout
    # (a block calling numpy's tan, where numpy has its own: the module runs as Python)
    compiles = all(expected_tier(name, s.name) == "compiled" for s in loop.syslist)
    assert {mode: r.engine_mode for mode, r in runs.items()} == {
        "compiled": "compiled" if compiles else "python", "python": "python"}
    compiled, python = runs["compiled"], runs["python"]
    tolerance = 1e-12 if name in NOT_TO_THE_BIT else 0.0
    np.testing.assert_allclose(compiled.outputs, python.outputs, rtol=0, atol=tolerance)
    np.testing.assert_allclose(compiled.states, python.states, rtol=0, atol=tolerance)
    assert np.abs(python.outputs).max() > 0.01


def test_a_nan_is_named_at_its_block_and_never_reaches_a_later_user_function(monkeypatch):
    # the module checks our own blocks' outputs for NaN together, before the next user
    # function: the NaN of 'bad' passes through an LTI gain, and 'watch' never sees it
    from controlkit.engines.fast import discrete

    stops = []

    def watch(t, x, u, params):  # raises rather than records: a recording block is Python's
        if np.isnan(u[0]):
            raise AssertionError("watch saw a NaN")
        return u[0]

    def stopped(job, t, x, u, block_index, k=0):  # before python-control looks
        stops.append((float(t), job.blocks[int(block_index)].system.name))
        raise FloatingPointError("stopped")

    monkeypatch.setattr(discrete, "explain_failure", stopped)
    bad = ct.nlsys(None, lambda t, x, u, params: np.log(u[0] - 2.0), inputs="u", outputs="w",
                   dt=TS, name="bad")
    gain = ct.ss([], [], [], [[3.0]], dt=TS, inputs="w", outputs="g", name="gain")
    # a state (held) makes it a dynamic diagram: a static one is python-control's to answer
    watcher = ct.nlsys(lambda t, x, u, params: x, watch, inputs="g", outputs="y", states=1,
                       dt=TS, name="watch", params={"label": "python tier"})  # a str: Python
    loop = ct.interconnect([bad, gain, watcher], inputs="u", outputs="y")
    T = np.arange(10) * TS
    U = np.where(np.arange(10) < 5, 4.0, 1.0)  # log of a negative number from step 5
    with pytest.raises(FloatingPointError, match="stopped"):
        simulate(loop, T, X0=[0.0], U=U, engine="fast")
    assert stops == [(T[5], "bad")]


def test_a_module_compiled_in_one_process_is_loaded_not_compiled_by_another(tmp_path):
    # a diagram of user functions compiled by one script is kept in the store: the next
    # script (a fresh interpreter, another student's notebook on the same account) finds
    # it compiled before it runs, and numba loads its entry and its user kernels from the
    # cache (NUMBA_DEBUG_CACHE: numba's documented log of its cache) without compiling.
    # An empty store of its own, so that nothing compiled earlier answers for it.
    import os
    import subprocess
    import sys
    import textwrap

    script = textwrap.dedent("""
        import numpy as np
        from user_diagrams import tank_with_params
        from controlkit.engines import fast
        loop, T, X0, U, params = tank_with_params()
        job = fast.prepare(loop, params, compiled=True)
        before = job.is_compiled()
        resp = fast.simulate(loop, T, np.asarray(X0, float), U, params=params, compile=True)
        print("RESULT", before, resp.engine_mode, job.is_compiled(),
              float(resp.outputs[0, -1]).hex())
    """)
    env = dict(os.environ, CONTROLKIT_CACHE_DIR=str(tmp_path / "store"),
               NUMBA_DEBUG_CACHE="1",
               PYTHONPATH=os.pathsep.join([os.path.dirname(__file__),
                                           os.environ.get("PYTHONPATH", "")]))
    env.pop("NUMBA_CACHE_DIR", None)
    runs = []
    for _ in range(2):
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                              env=env, timeout=600)
        assert done.returncode == 0, done.stderr
        runs.append(done)
    first, second = ([line.split()[1:] for line in run.stdout.splitlines()
                      if line.startswith("RESULT")][0] for run in runs)
    assert first[:3] == ["False", "compiled", "True"]
    assert second[:3] == ["True", "compiled", "True"]
    assert second[3] == first[3]  # the same numbers, to the bit
    assert "data saved to" in runs[0].stdout and "data saved to" not in runs[1].stdout
    assert "data loaded from" in runs[1].stdout
    assert "controlkit: compiling" not in runs[1].stderr
    kept = {p.name.split("_")[0] for p in (tmp_path / "store").glob("*.py")}
    assert kept == {"diagram", "user"}  # the tank's and the valve's functions: user modules
    assert len(list((tmp_path / "store").glob("diagram_*.json"))) == 1  # its record
