"""A user's functions compiled one by one, each a step a run as Python can pay for.

A diagram of user functions compiles its kernels first, each timed and recorded in the
store: the rule estimates a kernel not compiled yet by its lines, and runs as Python
compile them in steps that fit in what each run saves against python-control, so that no
call pays for a whole compile it has no room for (the continuous cruise cell after
``controlkit warmup``: one call of 1.19 s against python-control's 0.73 s before).
"""

import importlib.util
import sys
import uuid

import control as ct
import numpy as np
import pytest

import controlkit
from controlkit import _jit
from controlkit.engines.fast import run, store, usercode
from controlkit.engines.fast.usercode.compiling import KERNEL_LINE_SECONDS, KERNEL_MORE_LINES
from controlkit.studies.cmg import scenario as cmg_scenario

pytestmark = pytest.mark.skipif(not _jit.available(), reason="numba not installed")


def _user_loop(folder, gain, rate="[-{gain!r} * x[0] + u[0]]", helper=""):
    """A loop of one user block whose functions (in a file of ``folder``) hold ``gain``: a
    new ``gain``, new kernel texts (a text names no file), none compiled in any store or
    process before; ``rate`` is what its update function returns, ``helper`` a function it
    may call."""
    path = folder / f"user_block_{abs(hash((folder, rate))) % 10**8}.py"
    path.write_text(f"import numpy as np\n\n\n{helper}\n\ndef rate(t, x, u, params):\n"
                    f"    return {rate.format(gain=gain)}\n\n\n"
                    f"def out(t, x, u, params):\n    return [x[0] if {gain!r} else 0.0]\n")
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[path.stem] = module  # (inspect reads the functions' source through it)
    spec.loader.exec_module(module)
    block = ct.nlsys(module.rate, module.out, inputs="u", outputs="y", states="x",
                     name="lag")
    return ct.interconnect([block], inputs="u", outputs="y", name=path.stem)


def _path_of(kernel):
    """The store file of a user's compiled kernel."""
    return store.folder() / f"{kernel.__module__.removeprefix('controlkit_store_')}.py"


def _new_gain():
    """A gain no earlier run of the suite wrote into a kernel."""
    return 1.0 + uuid.uuid4().int % 10**9 / 10**9


def test_each_kernel_is_a_step_estimated_by_its_lines_then_timed_and_recorded(
        monkeypatch, tmp_path):
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    monkeypatch.setattr(store, "_TIMES", {})
    job = run.compiled_job(_user_loop(tmp_path, _new_gain()), None)
    steps = usercode.kernels_to_compile(job.plan.kernels)
    # two kernels of 4 lines each (the user's function, the kernel that stores its result),
    # each counted KERNEL_MORE_LINES longer (numba's work per function)
    each = (4 + KERNEL_MORE_LINES) * KERNEL_LINE_SECONDS
    assert [seconds for seconds, _ in steps] == pytest.approx([each] * 2)
    before = run.compile_estimate(job)
    for _, make in steps:
        make()
    assert usercode.kernels_to_compile(job.plan.kernels) == []
    assert run.compile_estimate(job) == pytest.approx(before - 2 * each)
    records = [store.record(_path_of(fn)) for fn in job.plan.kernels]
    assert [(r["entry"], r["lines"]) for r in records] == [("kernel", 4)] * 2
    per_line = sorted(r["seconds"] / 4 for r in records)
    assert all(seconds > 0 for seconds in per_line)
    assert sorted(store.compile_times("kernel")) == pytest.approx(per_line, abs=1e-3)
    # the next kernel's estimate: its lines and KERNEL_MORE_LINES at their median pace
    paces = sorted(r["seconds"] / (4 + KERNEL_MORE_LINES) for r in records)
    assert sorted(store.compile_times("kernel", more=KERNEL_MORE_LINES)) == pytest.approx(
        paces, abs=1e-3)
    (tmp_path / "again").mkdir()  # (a file of its own: Python's cache of a file's lines)
    again = usercode.kernels_to_compile(run.compiled_job(
        _user_loop(tmp_path / "again", _new_gain()), None).plan.kernels)
    assert again and [seconds for seconds, _ in again] == pytest.approx(
        [float(np.median(paces)) * (4 + KERNEL_MORE_LINES)] * len(again), abs=1e-3)


def test_a_module_compiled_at_once_records_its_kernels_too(tmp_path):
    import controlkit

    loop = _user_loop(tmp_path, _new_gain())
    T = np.linspace(0.0, 1.0, 11)
    response = controlkit.input_output_response(loop, T, np.ones(T.size), compile=True)
    assert response.engine_mode == "compiled"
    kernels = run.compiled_job(loop, None).plan.kernels
    assert usercode.kernels_to_compile(kernels) == []


def _earlier_runs(monkeypatch, source, seconds, twins=None):
    """A process where numba has started, no module is kept compiled, and the module of
    text ``source`` ran 10 times as Python for ``seconds`` in all (``twins``: the compiled
    jobs made for it so far)."""
    monkeypatch.setattr(run.Job, "is_compiled", lambda job: False)
    monkeypatch.setattr(run, "NUMBA_START", ())
    monkeypatch.setattr(run, "PYTHON_SECONDS", {source: seconds})
    monkeypatch.setattr(run, "PYTHON_POINTS", {source: 10})
    monkeypatch.setattr(run, "_TWINS", dict(twins or {}))
    monkeypatch.setattr(run, "_COMPILED", {})


@pytest.mark.parametrize(("typical", "kernels", "made_then_compiled"), [
    (0.4, (0.3, 0.3, 0.1), [[0], [0, 1, 2], "compiled"]),  # what fits in each call
    (0.4, (0.1, 0.1), [[0, 1], "compiled"]),
    # a kernel that never fits in a call (0.5 s against the 0.4 s a call saves): no step
    # is made at all, the others would be for nothing
    (0.4, (0.1, 0.5), [[], []]),
])
def test_runs_as_python_compile_the_kernels_in_steps_before_the_module(
        monkeypatch, typical, kernels, made_then_compiled):
    loop = cmg_scenario.build_loop("thesis")
    source = run.prepare(loop).source
    made, clock = [], [0.0]

    def make(i):  # (each takes what it was estimated to, on the rule's clock)
        made.append(i)
        clock[0] += kernels[i]

    monkeypatch.setattr(run, "now", lambda: clock[0])
    monkeypatch.setattr(run.usercode, "kernels_to_compile", lambda _: [
        (seconds, lambda i=i: make(i)) for i, seconds in enumerate(kernels) if i not in made])
    # the module 0.5 s (fits in python-control's call, two runs), and the kernels to come
    monkeypatch.setattr(run, "compile_estimate", lambda job: 0.5 + sum(
        seconds for i, seconds in enumerate(kernels) if i not in made))
    for expected in made_then_compiled:
        _earlier_runs(monkeypatch, source, 10 * typical)
        runner = run.Runner(loop, None, None)
        assert (runner.compiled is not None) == (expected == "compiled"), made
        if expected != "compiled":
            assert made == expected


def test_the_steps_count_what_they_took_and_the_call_s_compile_counts_them(monkeypatch):
    # two kernels estimated at 0.1 s each, in calls whose run takes 0.4 s as Python
    # (python-control's about 0.8 s): the first takes 0.35 s, which leaves no room for the
    # second in the same call, and a compile mid-run that would fit in a call without
    # steps (0.5 s) does not fit in this one
    loop = cmg_scenario.build_loop("thesis")
    source = run.prepare(loop).source
    made, clock, took = [], [0.0], (0.35, 0.1)

    def make(i):
        made.append(i)
        clock[0] += took[i]

    monkeypatch.setattr(run, "now", lambda: clock[0])
    monkeypatch.setattr(run.usercode, "kernels_to_compile", lambda _: [
        (0.1, lambda i=i: make(i)) for i in range(2) if i not in made])
    monkeypatch.setattr(run, "compile_estimate", lambda job: 0.5)
    monkeypatch.setattr(run, "LOAD_SECONDS", 0.0)
    _earlier_runs(monkeypatch, source, 4.0)
    runner = run.Runner(loop, None, None)
    assert made == [0] and runner.spent == pytest.approx(0.35)
    # 0.1 s run of 0.4: room 2 * 0.4 - 0.1 - 0.35 = 0.35 s, against 0.5 s to compile
    assert runner.compiled is None and runner.decide(0.1, 1 / 4) is None
    fresh = run.Runner(loop, None, None)  # the next call makes the second step
    assert made == [0, 1] and fresh.spent == pytest.approx(0.1)
    monkeypatch.setattr(run.usercode, "kernels_to_compile", lambda _: [])
    later = run.Runner(loop, None, None)  # no step left: the whole room for the compile
    chosen = later.compiled or later.decide(0.1, 1 / 4)
    assert later.spent == 0.0 and chosen is not None and chosen.compiled


def test_a_short_call_after_long_runs_makes_no_step_its_own_run_cannot_hold(monkeypatch):
    # the room for a step is this call's run, at the earlier runs' pace: ten runs of 1 000
    # points took 4 s as Python; a 10-point call (about 4 ms) made a 0.1-s step, 25 times
    # its python-control's time, when the room was the earlier runs' average (0.4 s)
    loop = cmg_scenario.build_loop("thesis")
    source = run.prepare(loop).source
    made = []
    monkeypatch.setattr(run.usercode, "kernels_to_compile", lambda _: [
        (0.1, lambda: made.append(0))] if not made else [])
    monkeypatch.setattr(run, "compile_estimate", lambda job: 0.5)
    _earlier_runs(monkeypatch, source, 4.0)
    monkeypatch.setattr(run, "PYTHON_POINTS", {source: 10_000})
    assert run.Runner(loop, None, None, points=10).compiled is None and made == []
    run.Runner(loop, None, None, points=1_000)
    assert made == [0]


@pytest.mark.parametrize(("numba_started", "twin_seconds", "twin_made"), [
    (True, 0.001, True),
    # numba's start (0.15 s) does not fit in a 0.1-s room: no twin, as no step could follow
    (False, 0.001, False),
    # a twin of 0.05 s fits in the room python-control's call leaves at twice this run's
    # time (0.1 s), not beside its quickest (1.2 times: 0.02 s), where its call was 0.75x
    (True, 0.05, False),
])
def test_a_compiled_twin_is_made_only_where_it_fits_beside_python_control_s_quickest_call(
        monkeypatch, numba_started, twin_seconds, twin_made):
    loop = cmg_scenario.build_loop("thesis")
    source = run.prepare(loop).source
    _earlier_runs(monkeypatch, source, 1.0)  # ten runs of 0.1 s as Python
    monkeypatch.setattr(run, "compile_estimate", lambda job: 5.0)  # (never in a call)
    started = []
    if not numba_started:
        monkeypatch.setattr(run, "NUMBA_START", ((0.15, lambda: False,
                                                  lambda: started.append(1)),))
    monkeypatch.setattr(run, "TWIN_SECONDS", twin_seconds / len(loop.syslist))
    runner = run.Runner(loop, None, None)
    assert (source in run._TWINS) == twin_made
    assert runner.compiled is None and started == []


def test_a_kernel_numba_cannot_compile_ends_the_steps_not_the_call(monkeypatch):
    # a step's compile that fails does not fail the user's call: the rule makes no more
    # steps for the diagram in this process (a long run may still compile it, whose
    # compile then says what numba refused)
    loop = cmg_scenario.build_loop("thesis")
    source = run.prepare(loop).source
    tried = []

    def fails():
        tried.append(1)
        raise TypeError("No implementation of function")

    monkeypatch.setattr(run.usercode, "kernels_to_compile", lambda _: [(0.1, fails)])
    monkeypatch.setattr(run, "compile_estimate", lambda job: 0.3)
    _earlier_runs(monkeypatch, source, 4.0)
    for _ in range(3):
        assert run.Runner(loop, None, None).compiled is None
    assert tried == [1]
    assert run._TWINS[source] == ("numba could not compile a function (TypeError: No "
                                  "implementation of function)")


def test_numba_s_refusal_of_a_block_s_function_names_the_block(monkeypatch, tmp_path):
    # a diagram's user functions compile one by one before its module: the first numba
    # refuses names its block, and the module is not compiled for nothing (a review saw
    # the warning name the diagram, 'sys[4]', after the module's compile failed again)
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    coefficients = np.array([0.2, -0.1, 1.0])
    first = ct.nlsys(lambda t, x, u, p: x + 0.1 * (u - x), lambda t, x, u, p: x, states=1,
                     inputs="r", outputs="ya", dt=0.1, name="first")
    shaper = ct.nlsys(None, lambda t, x, u, p: np.polyval(coefficients, u[0]), inputs="ya",
                      outputs="yb", dt=0.1, name="shaper")
    loop = ct.interconnect([first, shaper], inputs="r", outputs="yb")
    modules = []
    monkeypatch.setattr(store, "compile_entry", lambda *args, **kw: modules.append(args))
    T = np.arange(100) * 0.1
    with pytest.warns(UserWarning, match=r"numba could not compile block 'shaper' \(Typing"):
        ours = controlkit.input_output_response(loop, T, 1.0, compile=True)
    assert ours.engine_mode == "python" and modules == []
    assert np.array_equal(ours.outputs, ct.input_output_response(loop, T, 1.0).outputs)


def test_a_kernel_recorded_by_another_process_keeps_its_record(monkeypatch, tmp_path):
    # two processes on one store: the second finds the first's record and neither
    # compiles nor writes over it (a load timed as a compile would lower the estimates)
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    job = run.compiled_job(_user_loop(tmp_path, _new_gain()), None)
    (_, first), _ = usercode.kernels_to_compile(job.plan.kernels)
    path = _path_of(job.plan.kernels[0])
    store.write_record(path, seconds=0.25, lines=4, entry="kernel")  # (the other process)
    first()
    assert store.record(path) == {"seconds": 0.25, "lines": 4, "entry": "kernel"}
    assert not job.plan.kernels[0].dispatcher.signatures  # (not compiled here)


def test_a_store_emptied_under_a_session_leaves_its_kernels_out_of_the_steps(
        monkeypatch, tmp_path):
    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    job = run.compiled_job(_user_loop(tmp_path, _new_gain()), None)
    for path in store.folder().glob("user_*.py"):
        path.unlink()
    assert usercode.kernels_to_compile(job.plan.kernels) == []


def _closure_loop(folder, gain):
    """A loop whose function reads ``gain`` from its closure: every gain gives the same
    module text (its kernels are names) and kernels of other texts."""
    path = folder / "closure_block.py"
    if not path.exists():
        path.write_text("def make(gain):\n    def rate(t, x, u, params):\n"
                        "        return [-gain * x[0] + u[0]]\n    return rate\n")
    spec = importlib.util.spec_from_file_location(f"closure_{abs(hash(folder))}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    block = ct.nlsys(module.make(gain), None, inputs="u", outputs="x", states="x",
                     name="lag")
    return ct.interconnect([block], inputs="u", outputs="x", name="closure")


def test_a_diagram_built_anew_with_functions_of_its_own_compiles_them_before_the_module(
        monkeypatch, tmp_path):
    # a cell that builds its diagram anew from a closure of another value: the module's
    # text is the earlier diagram's, its kernels are not; the earlier diagram's estimate
    # did not count them, so they are made as steps before the compile, never in it
    first, second = (_closure_loop(tmp_path, _new_gain()) for _ in range(2))
    source = run.prepare(first).source
    assert run.prepare(second).source == source
    twin = run.compiled_job(first, None)
    for _, make in usercode.kernels_to_compile(twin.plan.kernels):
        make()
    monkeypatch.setattr(run, "compile_estimate", lambda job: 0.3)
    # (runs of 1 s: room for the kernel's step whatever the store's seconds per line, which
    # the suite's earlier compiles set; at 0.4 s a run its estimate, 0.40 s, did not fit)
    _earlier_runs(monkeypatch, source, 10.0, twins={source: twin})
    own = usercode.kernels_to_compile(run.compiled_job(second, None).plan.kernels)
    assert len(own) == 1
    assert run.Runner(second, None, None).compiled is None  # its own kernel is pending
    assert run._TWINS[source] is not twin
    assert run.Runner(second, None, None).compiled is None  # the step compiles it
    assert usercode.kernels_to_compile(run.compiled_job(second, None).plan.kernels) == []
    assert run.Runner(second, None, None).compiled is not None


@pytest.mark.parametrize("dt", [None, 0.1])
def test_the_kernels_compiled_alone_are_the_ones_the_module_calls(tmp_path, dt):
    # compile_kernel's types are those the diagrams' modules call a kernel with: the
    # module's compile adds no other (else the steps' compiles would be wasted)
    import controlkit

    loop = _user_loop(tmp_path, _new_gain())
    if dt is not None:
        block = loop.syslist[0]
        loop = ct.interconnect([ct.nlsys(block.updfcn, block.outfcn, inputs="u",
                                         outputs="y", states="x", dt=dt, name="lag")],
                               inputs="u", outputs="y")
    T = np.arange(11) * (dt or 0.1)
    assert controlkit.input_output_response(loop, T, np.ones(T.size),
                                            compile=True).engine_mode == "compiled"
    kernels = [k for k in run.compiled_job(loop, None).plan.kernels
               if k.__module__.startswith("controlkit_store_user_")]
    assert kernels and all(len(k.dispatcher.signatures) == 1 for k in kernels)


@pytest.mark.parametrize(("rate", "helper", "numpy"), [
    ("[-{gain!r} * x[0] + u[0]]", "", False),     # element by element: by its lines
    ("-{gain!r} * x + u[0]", "", True),           # the state vector whole
    ("[-{gain!r} * np.sum(x) + u[0]]", "", True),  # numpy on an array
    ("[-{gain!r} * np.linalg.norm(x) + u[0]]", "", True),
    ("[-{gain!r} * np.sin(x[0]) * np.pi + u[0]]", "", False),  # numpy's, on numbers
    ("[-{gain!r} * np.zeros(2)[0] + u[0]]", "", True),  # an array made
    # handed whole to a function of the user's: as that function uses it
    ("[-{gain!r} * first(x) + u[0]]", "def first(v):\n    return v[0]\n", False),
    ("[-{gain!r} * total(x) + u[0]]", "def total(v):\n    return v.sum()\n", True),
])
def test_a_kernel_that_works_on_arrays_is_estimated_as_numpy_compiles_take(
        monkeypatch, tmp_path, rate, helper, numpy):
    # numba compiles array code of its own for such a function: 0.3-4.7 s for one line
    # (np.linalg.solve), which its lines do not tell
    from controlkit.engines.fast.usercode.compiling import NUMPY_KERNEL_SECONDS

    monkeypatch.setattr(store, "CACHE_DIR", tmp_path / "store")
    job = run.compiled_job(_user_loop(tmp_path, _new_gain(), rate, helper), None)
    assert not isinstance(job, str), job
    seconds = sorted(step for step, _ in usercode.kernels_to_compile(job.plan.kernels))
    assert seconds[0] == pytest.approx(  # (its output function)
        (4 + KERNEL_MORE_LINES) * KERNEL_LINE_SECONDS)
    assert (seconds[1] == NUMPY_KERNEL_SECONDS) == numpy
