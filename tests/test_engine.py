"""The fast engine: same numbers as python-control, on every scenario and on rewired diagrams."""

import os
import subprocess
import sys

import control as ct
import numpy as np
import pytest

from controlkit import _jit
from controlkit.blocks import cmg, mec
from controlkit.blocks import spacecraft as sc
from controlkit.blocks.sampling import sample_nlsys
from controlkit.engines import fast as engine
from controlkit.engines.contract import UnsupportedSystem
from controlkit.simulation import initial_state, simulate
from controlkit.studies.cmg import scenario as cmg_scenario
from controlkit.studies.spacecraft import scenario as scenario
from controlkit.studies.spacecraft.diagrams import mec_loop, output_zeroing_loop

Q0 = scenario.initial_attitude()
H0 = Q0[1:3]


def start(loop):
    names = {s.name for s in loop.syslist}
    return initial_state(loop, plant=Q0, **({"nominal": H0} if "nominal" in names else {}))


def assert_same(loop, T, X0, compile=None):
    ref = simulate(loop, T, X0=X0, engine="python-control")
    fast = simulate(loop, T, X0=X0, engine="fast", compile=compile)
    if compile is not None:
        assert fast.engine_mode == ("compiled" if compile else "python")
    assert list(fast.output_labels) == list(ref.output_labels)
    assert list(fast.state_labels) == list(ref.state_labels)
    assert fast.outputs.shape == ref.outputs.shape and fast.states.shape == ref.states.shape
    np.testing.assert_array_equal(fast.outputs, ref.outputs)
    np.testing.assert_array_equal(fast.states, ref.states)
    return ref, fast


@pytest.mark.parametrize("case", [
    "ideal", "without_mec", "mec_fixed", "proposed", "proposed_literal"])
def test_spacecraft_scenarios_match_python_control_over_500_s(case):
    # compiled (as the rule chooses for the papers' horizons), to the bit, over 500 s: the
    # slew and FRIT's first moves of K (|K| reaches 0.03 by then); python-control's path
    # takes about 1 ms a step on these blocks, so the test's time is mostly its
    loop = scenario.build_loop(case, h0=H0)
    assert_same(loop, np.arange(5001) * 0.1, start(loop), compile=True)


@pytest.mark.parametrize("case", list(cmg_scenario.CASES))
def test_cmg_scenarios_match_python_control_over_12_s(case):
    loop = cmg_scenario.build_loop(case)
    assert_same(loop, np.arange(12001) * 0.001, initial_state(loop, cmg=cmg_scenario.X0_THESIS),
                compile=True)


def test_rewired_mec_with_other_gain_and_controller_matches():
    # the tuner taken out for a non-diagonal constant gain, the outer loop made faster
    faster = sc.outer_controller(0.003, output="mu_n")
    loop = mec_loop(scenario.true_plant(True), controller=faster, K=[[0.2, 0.05], [0.0, 0.15]])
    assert_same(loop, np.arange(5001) * 0.1, start(loop))


def test_rewired_loop_with_saturation_and_reference_matches():
    # a wheel-speed saturation inserted between linearizer and plant, and a nonzero reference
    plant = scenario.true_plant(True)
    lin = sc.io_linearizer()
    limiter = cmg.torque_saturation(1.0, 1.0, name="wheel_limit")
    limiter.set_inputs(["u_cmd[0]", "u_cmd[1]"])
    limiter.set_outputs(["u[0]", "u[1]"])
    lin.set_outputs(["u_cmd[0]", "u_cmd[1]"])
    loop = ct.interconnect(
        [sample_nlsys(plant, 0.1), sc.attitude_output(), sc.outer_controller(0.002), lin, limiter],
        inputs=["r[0]", "r[1]"], outputs=["h[0]", "h[1]", "u[0]", "u[1]", "u_cmd[0]"])
    T = np.arange(3001) * 0.1
    U = np.vstack([0.01 * np.ones_like(T), -0.02 * np.ones_like(T)])
    X0 = initial_state(loop, plant=Q0)
    ref = ct.input_output_response(loop, T, U, X0)
    fast = engine.simulate(loop, T, X0, U)
    np.testing.assert_array_equal(fast.outputs, ref.outputs)
    assert np.abs(ref.outputs[2]).max() == pytest.approx(1.0)  # the limiter is active


def test_user_lambda_block_compiles_and_matches_python_control():
    user = ct.nlsys(None, lambda t, x, u, p: 0.0009 * (u[0:2] - u[2:4]),
                    inputs=["r[0]", "r[1]", "h[0]", "h[1]"], outputs=["mu[0]", "mu[1]"],
                    dt=None, name="my_controller")
    loop = output_zeroing_loop(controller=user)
    tiers = {row.name: row.tier for row in engine.explain(loop)}
    assert tiers["my_controller"] == "compiled"
    T = np.arange(11) * 0.1
    resp = simulate(loop, T, X0=start(loop), engine="fast")
    ref = simulate(loop, T, X0=start(loop))
    np.testing.assert_allclose(resp.outputs, ref.outputs, rtol=0, atol=1e-12)


def test_momentum_given_as_python_function_runs_in_python_inside_the_fast_loop():
    plant = sc.spacecraft_plant(H0=lambda t: [0.0, 0.0, 0.01])
    loop = output_zeroing_loop(plant)
    row = next(r for r in engine.explain(loop) if r.name == "plant")
    assert row.tier == "python"
    assert "H0 is a Python" in row.reason
    T = np.arange(21) * 0.1
    fast = engine.simulate(loop, T, start(loop))
    ref = simulate(loop, T, X0=start(loop))
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=0, atol=1e-12)


def test_singular_attitude_gives_the_same_message_on_the_fast_path():
    loop = scenario.build_loop("ideal")
    X0 = initial_state(loop, plant=[0.0, 0.6, 0.8, 0.0])
    with pytest.raises(sc.SingularDecouplingError, match=r"undefined at attitude q = \[0.0, 0.6"):
        engine.simulate(loop, np.arange(5) * 0.1, X0)


def test_continuous_diagram_of_controlkit_blocks_runs_compiled_as_python_control():
    loop = ct.interconnect([sc.spacecraft_plant(), sc.attitude_output(), sc.outer_controller(),
                            sc.io_linearizer()], inputs=["r[0]", "r[1]"], outputs=["h[0]"])
    T = np.linspace(0.0, 50.0, 11)
    fast = engine.simulate(loop, T, Q0)
    ref = ct.input_output_response(loop, T, 0.0, Q0)
    np.testing.assert_allclose(fast.outputs, ref.outputs, rtol=1e-9, atol=1e-12)


def test_algebraic_loop_is_named():
    a = sc.outer_controller(name="a")  # mu = F (r - h)
    a.set_inputs(["r[0]", "r[1]", "x[0]", "x[1]"])
    a.set_outputs(["y[0]", "y[1]"])
    b = sc.outer_controller(name="b")
    b.set_inputs(["r[0]", "r[1]", "y[0]", "y[1]"])
    b.set_outputs(["x[0]", "x[1]"])
    gain = mec.nominal_model(0.1)  # makes the diagram discrete
    loop = ct.interconnect([gain, a, b], inputs=["mu_n[0]", "mu_n[1]", "r[0]", "r[1]"],
                           outputs=["hn[0]", "y[0]"])
    with pytest.raises(UnsupportedSystem,
                       match=r"algebraic loop through blocks \['a', 'b'\]"):
        engine.simulate(loop, [0.0, 0.1], [0.0, 0.0])


def test_engine_without_numba_gives_the_same_numbers(tmp_path):
    # CONTROLKIT_DISABLE_NUMBA=1: even compile=True runs as Python (with a warning), and
    # numba is never imported
    code = (
        "import sys, warnings; import numpy as np;"
        "from controlkit.studies.spacecraft import scenario as s;"
        "warnings.simplefilter('ignore');"
        "r = s.run('proposed', horizon=100.0, engine='fast', compile=True);"
        "assert r.engine_mode == 'python' and 'numba' not in sys.modules;"
        "np.save(r'%s', r.outputs)" % (tmp_path / "plain.npy")
    )
    env = {**os.environ, "CONTROLKIT_DISABLE_NUMBA": "1",
           "CONTROLKIT_CACHE_DIR": str(tmp_path / "cache")}
    subprocess.run([sys.executable, "-c", code], env=env, check=True)
    plain = np.load(tmp_path / "plain.npy")
    compiled = scenario.run("proposed", horizon=100.0, engine="fast", compile=True)
    assert compiled.engine_mode == "compiled"
    np.testing.assert_array_equal(plain, compiled.outputs)


def test_unknown_engine_is_refused():
    with pytest.raises(ValueError, match=r"engine must be one of \('fast', 'python-control'\)"):
        simulate(scenario.build_loop("ideal"), [0.0, 0.1], X0=Q0, engine="numba")


_COMPILE_ONE = """
import controlkit._jit
numba = controlkit._jit.numba_module()
f = numba.njit(lambda x: x + 1.0)
f(1.0)
print(next(iter(f.overloads.values())).fndesc.unique_name)
"""


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_two_processes_name_the_same_compiled_function_differently():
    # numba numbered compiled functions 1, 2, 3 in every process, so the same kernel
    # compiled by two processes (a loop's copy, the kernel's own cache) had one name and
    # the second loaded was bound to the first one's environment ('descr' is NULL)
    names = [subprocess.run([sys.executable, "-c", _COMPILE_ONE], capture_output=True,
                            text=True, check=True).stdout.strip() for _ in range(2)]
    assert all(names) and names[0] != names[1], names


_LOOP_COMPILED = """
import sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from controlkit.engines import fast
from user_diagrams import lti_loop
loop, T, X0, U, _ = lti_loop(steps=10)
before = fast.prepare(loop, compiled=True).is_compiled()
resp = fast.simulate(loop, T, X0, U, compile=True)
print("RESULT", before, resp.engine_mode)
"""


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_a_compiled_module_is_kept_and_found_under_numba_cache_dir(tmp_path):
    # with NUMBA_CACHE_DIR set, numba keeps the compiled code there, not beside the store's
    # modules: a second process must find it there (else it compiles again)
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "numba"),
           "CONTROLKIT_CACHE_DIR": str(tmp_path / "store"), "NUMBA_DEBUG_CACHE": "1"}
    tests = os.path.dirname(__file__)
    outs = [subprocess.run([sys.executable, "-c", _LOOP_COMPILED, tests], env=env,
                           capture_output=True, text=True, check=True).stdout
            for _ in range(2)]
    results = [[line for line in out.splitlines() if line.startswith("RESULT")] for out in outs]
    assert results == [["RESULT False compiled"], ["RESULT True compiled"]]
    assert "data saved to" not in outs[1] and "data loaded from" in outs[1]
    assert not list((tmp_path / "store").glob("__pycache__/*.nbi"))  # it went there instead
    assert list((tmp_path / "numba").rglob("diagram_*.nbi"))


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_the_rule_counts_the_earlier_python_runs_of_a_module(monkeypatch):
    # a run of 4 s as Python does not pay for a compile; the same module after 100 s of
    # earlier runs as Python in this process does (a notebook cell run again and again)
    from controlkit.engines.fast import run

    loop = cmg_scenario.build_loop("thesis")
    monkeypatch.setattr(run, "compile_estimate", lambda job: 5.0)  # what the store says
    monkeypatch.setattr(run, "PYTHON_SECONDS", {})
    monkeypatch.setattr(run, "PYTHON_POINTS", {})
    monkeypatch.setattr(run, "_TWINS", {})  # as in a process that has not compiled it
    monkeypatch.setattr(run, "_COMPILED", {})
    monkeypatch.setattr(run.Job, "is_compiled", lambda job: False)  # nor kept in the store
    first = run.Runner(loop, None, None)
    assert first.decide(0.5, 1 / 8) is None  # (the rule reads two pieces' paces)
    assert first.decide(1.0, 1 / 4) is None  # 3 s to go, against 5 s to compile
    first.finished(4.0)
    assert run.PYTHON_SECONDS == {first.python.source: 4.0}
    run.PYTHON_SECONDS[first.python.source] = 100.0
    run.PYTHON_POINTS[first.python.source] = 1000  # short runs: not compiled from the start
    again = run.Runner(loop, None, None)
    assert again.compiled is None
    # paid for, but a short run: compiling in it would make the call slower than
    # python-control's (about twice the run as Python: 0.4 s, against 5 s to compile)
    short = run.Runner(loop, None, None)
    assert short.decide(0.05, 1 / 4) is None and short.decide(0.1, 1 / 2) is None
    assert again.decide(0.5, 1 / 8) is None
    chosen = again.decide(1.0, 1 / 4)
    assert chosen is not None and chosen.compiled
    # a first piece slowed by one-time costs does not foretell a long run: 0.13% in 0.14 s
    # (104 s at that pace), then 5% in 0.06 s more, a run of about 3 s
    slowed = run.Runner(loop, None, None)
    assert slowed.decide(0.14, 0.00134) is None and slowed.decide(0.2, 0.05) is None
    steady = run.Runner(loop, None, None)  # (the same pace throughout: it pays)
    assert steady.decide(0.14, 0.00134) is None and steady.decide(0.28, 0.00268) is not None
    forced = run.Runner(loop, None, False)  # compile=False runs are not counted
    forced.finished(50.0)
    assert run.PYTHON_SECONDS[first.python.source] == 100.0


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_a_run_compiles_from_its_start_when_earlier_runs_paid_and_the_call_stays_short(
        monkeypatch):
    # a run that ends in its first piece never reaches the rule's mid-run question: it
    # compiles from its start once the earlier runs of its module took longer than the
    # compile, unless the compile is longer than two of those runs (python-control's
    # call, about: the call that compiles would be slower than python-control's)
    from controlkit.engines.fast import run

    loop = cmg_scenario.build_loop("thesis")
    monkeypatch.setattr(run, "compiled_cost", lambda job: 1.5)  # numba's start and the compile
    monkeypatch.setattr(run, "NUMBA_START", ((0.15, lambda: True, None),))  # (started)
    source = run.prepare(loop).source
    for before, runs, compiled in ((1.2, 1, False),   # not paid yet
                                   (2.0, 2, True),    # paid; a run of 1 s: 1.5 <= 2 x 1
                                   (2.0, 20, False)):  # paid; runs of 0.1 s: too short
        monkeypatch.setattr(run, "PYTHON_SECONDS", {source: before})
        monkeypatch.setattr(run, "PYTHON_POINTS", {source: runs})
        monkeypatch.setattr(run, "_TWINS", {})  # as in a process that has not compiled it
        monkeypatch.setattr(run, "_COMPILED", {})
        runner = run.Runner(loop, None, None)
        assert (runner.compiled is not None) == compiled, (before, runs)
        assert runner.decided == compiled


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_a_diagram_built_anew_reads_its_module_s_compile_cost_without_translating_again(
        monkeypatch):
    # a loop over gains building the same diagram anew: once its earlier runs count, the
    # first asks what compiling would cost (its functions translated, 0.1-0.2 s for 40
    # blocks); the next ones read that answer, and run as Python at python-control's pace
    from controlkit.engines.fast import run

    made = []
    compiled_job = run.compiled_job
    monkeypatch.setattr(run, "compiled_job", lambda *a: made.append(a) or compiled_job(*a))
    monkeypatch.setattr(run, "compile_estimate", lambda job: 50.0)  # never pays here
    monkeypatch.setattr(run.Job, "is_compiled", lambda job: False)  # (nor kept compiled)
    monkeypatch.setattr(run, "_TWINS", {})
    monkeypatch.setattr(run, "_COMPILED", {})
    source = run.prepare(cmg_scenario.build_loop("thesis")).source
    monkeypatch.setattr(run, "PYTHON_SECONDS", {source: 10.0})
    monkeypatch.setattr(run, "PYTHON_POINTS", {source: 10})
    for _ in range(3):
        runner = run.Runner(cmg_scenario.build_loop("thesis"), None, None)
        assert runner.compiled is None and runner.python.source == source
    assert len(made) == 1


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_runs_as_python_make_numba_s_start_in_steps_when_start_and_compile_overflow_a_call(
        monkeypatch):
    # earlier runs paid for numba's start and the compile: runs as Python make the start
    # first, each the steps that fit in a run's time (python-control's call is two runs,
    # about), and a later run compiles; never the start and the compile in one call (the
    # continuous cruise cell: 0.4 s runs, a compile estimated at 0.53 s that took 0.8-1.55)
    from controlkit.engines.fast import run

    loop = cmg_scenario.build_loop("thesis")
    source = run.prepare(loop).source
    monkeypatch.setattr(run.Job, "is_compiled", lambda job: False)
    for typical, estimate, made_then_compiled in (
            (0.4, 0.75, [[0, 1], "compiled"]),
            (0.3, 0.53, [[0], [0, 1], "compiled"]),  # import, then first use
            (0.41, 0.53, [[0, 1], "compiled"]),
            # numba's start for nothing, so not made: first use's 0.25 s > a run's 0.2,
            (0.2, 0.3, [[], [], []]),
            (0.4, 0.9, [[], []])):  # or the compile would not fit in a call
        monkeypatch.setattr(run, "compile_estimate", lambda job, estimate=estimate: estimate)
        made, clock = [], [0.0]

        def make(step, seconds, made=made, clock=clock):  # (taking its time on the clock)
            made.append(step)
            clock[0] += seconds

        monkeypatch.setattr(run, "now", lambda clock=clock: clock[0])
        monkeypatch.setattr(run, "NUMBA_START", tuple(
            (seconds, lambda step=step, made=made: step in made,
             lambda step=step, seconds=seconds: make(step, seconds))
            for step, seconds in enumerate((0.15, 0.25))))
        for expected in made_then_compiled:
            monkeypatch.setattr(run, "PYTHON_SECONDS", {source: 8 * typical})
            monkeypatch.setattr(run, "PYTHON_POINTS", {source: 8})
            monkeypatch.setattr(run, "_TWINS", {})
            monkeypatch.setattr(run, "_COMPILED", {})
            runner = run.Runner(loop, None, None)
            assert (runner.compiled is not None) == (expected == "compiled"), typical
            if expected != "compiled":
                assert made == expected, typical


def test_the_compile_estimate_reads_the_store_s_times_of_its_own_kind(monkeypatch, tmp_path):
    # a continuous module's functions and a discrete one's entry are estimated each from
    # the records of their own kind (records of an older engine's continuous entry,
    # "run_continuous", which compiled its loop with every diagram, are not read)
    from controlkit.engines.fast import run, store

    monkeypatch.setattr(store, "CACHE_DIR", tmp_path)
    monkeypatch.setattr(store, "_TIMES", {})
    for text, seconds, entry in (("A = 1\n", 2.0, "run_discrete"),
                                 ("A = 2\n", 40.0, "run_continuous"),
                                 ("A = 3\n", 6.0, "continuous")):
        store.write_record(store.module_file(text, "diagram"), seconds=seconds, blocks=4,
                           entry=entry)
    assert store.compile_times("run_discrete") == [0.5]
    assert store.compile_times("continuous") == [1.5]
    job = run.prepare(cmg_scenario.build_loop("thesis"))  # discrete, 4 blocks
    assert not job.plan.continuous.size and run.compile_estimate(job) == 2.0
    # a continuous one, in a store where the step machine and the loop are not compiled yet
    monkeypatch.setattr(store, "_MACHINE", [])
    monkeypatch.setattr(store, "_LOOPS", {})
    job = run.prepare(_lag_loop("lag"))  # 2 blocks
    assert run.compile_estimate(job) == 2 * 1.5 + store.MACHINE_COMPILE_SECONDS \
        + store.LOOP_COMPILE_SECONDS


def _lag_loop(name, pole=-1.0):
    """A continuous loop of two blocks: a first-order lag closed by a gain."""
    lag = ct.ss([[pole]], [[1.0]], [[1.0]], [[0.0]], name=name, inputs="e", outputs="y")
    gain = ct.ss([], [], [], [[2.0, -2.0]], name="k", inputs=["r", "y"], outputs="e")
    return ct.interconnect([lag, gain], inputs="r", outputs="y")


@pytest.mark.skipif(not _jit.available(), reason="numba not installed")
def test_continuous_diagrams_share_one_compiled_loop_and_compile_only_their_functions():
    # the instants' loop is compiled once for every diagram (numba's first-class
    # functions): a new wiring compiles its four functions, kept with their own record
    import controlkit
    from controlkit.engines.fast import run, store

    T = np.linspace(0.0, 5.0, 51)
    loops = []
    for name, pole in (("lag_a", -1.0), ("lag_b", -3.0)):
        loop = _lag_loop(name, pole)
        compiled = controlkit.input_output_response(loop, T, np.ones(T.size), compile=True)
        python = controlkit.input_output_response(loop, T, np.ones(T.size), compile=False)
        assert compiled.engine_mode == "compiled" and python.engine_mode == "python"
        np.testing.assert_array_equal(compiled.outputs, python.outputs)
        loops.append(dict(store._LOOPS))
        source = run.prepare(loop, compiled=True).source
        assert store.record(store.module_file(source, "diagram"))["entry"] == "continuous"
    assert loops[0] == loops[1] and len(loops[0]) >= 1  # the second compiled no loop



_FRESH_SETUP = """
import sys, time
import control as ct
import numpy as np
import controlkit

def loop():
    plant = ct.tf([1.0], [2.0, 1.0], name="plant", inputs="u", outputs="y")
    pi = ct.tf([1.5, 0.8], [1.0, 0.0], name="pi", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    return ct.interconnect([plant, pi, error], inputs="r", outputs=["y", "u"])

def slow(t, x, u, params):  # few points, but long in python-control
    deadline = time.perf_counter() + 0.002
    while time.perf_counter() < deadline:
        pass
    return -x + u

def run(sys_, points, **options):
    T = np.linspace(0.0, 10.0, points)
    mine = controlkit.input_output_response(sys_, T, 1.0, **options)
    theirs = ct.input_output_response(sys_, T, 1.0)
    assert np.array_equal(mine.outputs, theirs.outputs)
    return f"{mine.engine_mode}:{'controlkit.engines.fast' in sys.modules}"

decay = ct.interconnect([ct.nlsys(slow, None, inputs=1, states=1, outputs=1, name="decay")],
                       inputs="u[0]", outputs="y[0]")
"""


def _fresh_script(last_line):
    """The RESULT line a fresh interpreter prints after :data:`_FRESH_SETUP`."""
    done = subprocess.run([sys.executable, "-c", _FRESH_SETUP + last_line],
                          capture_output=True, text=True, check=True)
    return [line.split()[1:] for line in done.stdout.splitlines()
            if line.startswith("RESULT")]


def test_a_fresh_script_s_short_runs_are_python_control_s_own_until_the_engine_pays():
    # a fresh process: a 101-point PI loop (about 20 ms in python-control) is left to
    # python-control, engine unimported (its start, about 16 ms, would make the call
    # slower); a 11-point run python-control took over 50 ms on starts it on the next
    # call, and from then on that diagram's runs are the engine's; a new diagram's short
    # run is python-control's still. compile=False starts it at once.
    # (The rule reads python-control's pace on the system itself: the PI loop's, however
    # long on a busy machine, does not start the engine for another diagram.)
    (result,) = _fresh_script(
        'from controlkit import engines, simulation\n'
        'first = run(loop(), 101)\n'
        'pays = engines.fast_start_pays(decay, 11, (engines._kept_on(decay, simulation._PACE)'
        ' or 0.0) * 11)\n'
        'print("RESULT", first, pays, run(decay, 11), run(decay, 11), run(loop(), 101))')
    assert result[0] == "python-control:False"
    # (the PI loop built again is a new diagram: its short run is python-control's still)
    assert result[2:] == ["python:True" if result[1] == "True" else "python-control:False",
                          "python:True", "python-control:True"], result
    assert _fresh_script('print("RESULT", run(loop(), 101, compile=False))') == [
        ["python:True"]]


def test_a_new_diagram_s_short_run_is_python_control_s_and_one_run_before_the_engine_s():
    # a notebook cell run again builds its diagram anew: preparing it (about half a
    # millisecond a block) made a 10-point run slower than python-control's whole call
    # (0.4-0.8x); the same diagram called again keeps its prepared job
    def build():
        lag = ct.nlsys(lambda t, x, u, p: 0.9 * x + 0.1 * u, lambda t, x, u, p: x,
                       inputs="u", outputs="y", states=1, dt=0.1, name="lag")
        return ct.interconnect([lag], inputs="u", outputs="y")

    import controlkit
    from controlkit import engines

    T = np.arange(10) * 0.1
    loop = build()
    modes = [controlkit.input_output_response(loop, T, 1.0, compile=compile).engine_mode
             for compile in (None, False, None)]
    assert modes == ["python-control", "python", "python"]
    assert controlkit.input_output_response(build(), T, 1.0).engine_mode == "python-control"
    assert engines.fast_start_pays(build(), 20_000)  # (about 0.2 s in python-control)
    # a batch of a lone system's short runs: run by run, python-control's
    batch = controlkit.input_output_response(loop.syslist[0], T, 1.0, [[0.0], [1.0]])
    assert [r.engine_mode for r in batch] == ["python-control"] * 2


def test_a_lone_system_is_python_control_s_unless_its_run_would_be_long():
    # python-control calls a lone system's own functions, as the engine's Python run
    # does: only a compiled run gains, after numba's start and a compile (1-2 s)
    import controlkit
    from controlkit import engines

    block = ct.nlsys(lambda t, x, u, p: -x + u, None, inputs=1, outputs=1, states=1,
                     name="lag")
    T = np.linspace(0.0, 10.0, 1500)
    expected = ct.input_output_response(block, T, 1.0)
    for compile, mode in ((None, "python-control"), (False, "python")):
        ours = controlkit.input_output_response(block, T, 1.0, compile=compile)
        assert ours.engine_mode == mode
        assert np.array_equal(ours.outputs, expected.outputs)
    # 16 us a point at least, against 3 s
    assert not engines.fast_start_pays(block, 180_000)
    assert engines.fast_start_pays(block, 200_000) and engines.fast_start_pays(block, 10, 3.5)
    if _jit.available():  # once compiled when asked, its later runs stay compiled
        modes = [controlkit.input_output_response(block, T, 1.0, compile=compile).engine_mode
                 for compile in (True, None, None)]
        assert modes == ["compiled"] * 3
        other = ct.nlsys(lambda t, x, u, p: -x + u, None, inputs=1, outputs=1, states=1,
                         name="lag")  # (the same functions, another system: its own rule)
        assert controlkit.input_output_response(other, T, 1.0).engine_mode == "python-control"

    class Plant(ct.NonlinearIOSystem):  # (one that defines __eq__: not hashable)
        def __eq__(self, other):
            return self is other

    plant = Plant(lambda t, x, u, p: -x + u, None, inputs=1, outputs=1, states=1,
                  name="plant")
    ours = controlkit.input_output_response(plant, T, 1.0)
    assert ours.engine_mode == "python-control"
    assert np.array_equal(ours.outputs, expected.outputs)


def test_a_lone_system_s_one_block_diagram_is_kept_while_its_labels_hold():
    # a lone system runs as a one-block diagram, kept on it with its prepared jobs: a short
    # run made them anew each call (2 ms, 4.7x python-control's 20-point run), and a copy
    # carries none of it
    import copy

    import controlkit
    from controlkit.engines.fast.tiers import as_interconnect

    lone = ct.nlsys(lambda t, x, u, p: 0.9 * x + u, lambda t, x, u, p: x, inputs=1,
                    outputs=1, states=1, name="lone", dt=0.1)
    diagram = as_interconnect(lone)
    assert as_interconnect(lone) is diagram and diagram.syslist == [lone]
    T = np.arange(20) * 0.1
    first = controlkit.input_output_response(lone, T, 1.0, 1.0, compile=False)
    assert first.engine_mode == "python"
    assert np.array_equal(first.outputs, ct.input_output_response(lone, T, 1.0, 1.0).outputs)
    for copied in (copy.copy(lone), copy.deepcopy(lone)):  # (a diagram of its own)
        assert as_interconnect(copied).syslist == [copied]
    lone.set_outputs(["speed"])  # relabelled: a new diagram, with the new label
    relabelled = as_interconnect(lone)
    assert relabelled is not diagram and relabelled.output_labels == ["speed"]
    again = controlkit.input_output_response(lone, T, 1.0, 1.0, compile=False)
    assert again.output_labels == ["speed"] and np.array_equal(again.outputs, first.outputs)


def test_a_lone_system_s_kept_diagram_reads_its_parameters_and_rate_as_they_are_now():
    # the one-block diagram copied the system's params when it was built, and its copy
    # went over their later values (found by a review of the change); dt True, then 1,
    # compared equal
    import controlkit

    lone = ct.nlsys(lambda t, x, u, p: -p["a"] * x + u, lambda t, x, u, p: p["c"] * x,
                    inputs=1, outputs=1, states=1, name="lone", params={"a": 1.0, "c": 2.0})
    T = np.linspace(0.0, 2.0, 21)
    for change in ({}, {"a": 5.0}, {"c": -1.0}):
        lone.params.update(change)
        expected = ct.input_output_response(lone, T, 1.0, 0.5)
        for compile in (False, True):
            ours = controlkit.input_output_response(lone, T, 1.0, 0.5, compile=compile)
            assert ours.states.tobytes() == expected.states.tobytes(), (change, compile)
            assert ours.outputs.tobytes() == expected.outputs.tobytes(), (change, compile)
    stepper = ct.nlsys(lambda t, x, u, p: 0.5 * x + u, None, inputs=1, outputs=1, states=1,
                       dt=True, name="stepper")
    T = np.arange(5) * 0.5
    controlkit.input_output_response(stepper, T, 1.0, 0.0, compile=False)
    stepper.dt = 1  # (T spaced 0.5: python-control refuses it now)
    with pytest.raises(ValueError):
        ct.input_output_response(stepper, T, 1.0, 0.0)
    with pytest.raises(ValueError):
        controlkit.input_output_response(stepper, T, 1.0, 0.0, compile=False)


def test_the_engine_s_start_pays_by_the_run_s_size_or_python_control_s_longest_run():
    import control as ct

    from controlkit import engines

    loop = ct.interconnect([ct.tf([1], [1, 1], name="p", inputs="u", outputs="y"),
                            ct.tf([2], [1], name="k", inputs="y", outputs="z")],
                           inputs="u", outputs="z")
    # 35 us a point and block at least, against 50 ms (25 ms of start, twice): 715 points
    assert engines.fast_start_pays(loop, 800) and engines.fast_start_pays(loop, 10, 0.06)
    if "controlkit.engines.fast" not in sys.modules:  # (this process started it already)
        assert not engines.fast_start_pays(loop, 700)
        assert not engines.fast_start_pays(loop, 10, 0.04)
