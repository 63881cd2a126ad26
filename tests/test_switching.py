"""A run that begins on the generic driver while the diagram's module compiles moves to the
module between two ranges of steps, with the numbers of a run in one piece."""

import control as ct
import numpy as np
import pytest
from continuous_diagrams import two_rate_servo

from controlkit.engines.fast import loader, switching
from controlkit.engines.fast.continuous import run_continuous
from controlkit.engines.fast.run import Job, prepare, simulate


def recording(function, calls, label, plan=None):
    """``function`` recording the range ``(k0, k1)`` of each call; with ``plan`` it takes
    the driver's plan itself, as a module's entry does."""

    def call(*arguments):
        calls.append((label, arguments))
        return function(*arguments, *(() if plan is None else (plan,)))

    return call


def compiling_then_done(monkeypatch, after):
    """``loader.background_done`` says a compile is under way ``after`` times, then that
    it has finished."""
    answers = iter([False] * after + [True] * 1000)
    monkeypatch.setattr(loader, "background_done", lambda source: next(answers))
    monkeypatch.setattr(switching, "FIRST_CHUNK", 7)
    monkeypatch.setattr(switching, "CHUNK_SECONDS", 1e-4)


def loops_handed(job, answers):
    """``job.loop`` handing out ``answers``, ``(function, generic)``, in turn: the driver
    while the module is compiled in the background, as :meth:`Job.loop` says it."""

    def loop(name, policy=None):
        function, generic = answers.pop(0)
        job.compiling = generic
        return function, generic

    return loop


def servo():
    """The two-rate servo's job (sampled data: 1001 instants), time points, inputs and
    initial state."""
    loop, T, X0, U = two_rate_servo()
    return prepare(loop), T, np.atleast_2d(U), X0


def ranges_of(calls, k0_index, k1_index):
    return [(label, int(a[k0_index]), int(a[k1_index])) for label, a in calls]


def test_a_sampled_data_run_moves_to_the_module_with_the_same_bits(monkeypatch):
    job, T, U, X0 = servo()
    whole = run_continuous(job, T, U, X0, generic=True)
    driver, calls = loader.driver().run_continuous, []
    module = recording(driver, calls, "module", plan=job.generic_plan())
    answers = [(recording(driver, calls, "driver"), True), (module, False)]
    monkeypatch.setattr(job, "loop", loops_handed(job, answers))
    compiling_then_done(monkeypatch, after=2)
    cut = run_continuous(job, T, U, X0)
    np.testing.assert_array_equal(cut.y, whole.y)
    np.testing.assert_array_equal(cut.x, whole.x)
    done = ranges_of(calls, 3, 4)  # (machine, instants, fire0, k0, k1, ...)
    assert [label for label, _, _ in done] == ["driver", "driver", "driver", "module"]
    assert done[0][1:] == (0, 7)
    assert all(a[2] == b[1] for a, b in zip(done, done[1:], strict=False))  # contiguous
    assert done[-1][2] == calls[0][1][1].size  # the module ran to the last instant


def test_a_discrete_run_moves_to_the_module_with_the_same_bits(monkeypatch):
    plant = ct.nlsys(lambda t, x, u, params: [0.9 * x[0] + 0.1 * np.sin(u[0])], None,
                     inputs="u", outputs="y", states="y", dt=0.01, name="plant")
    pi = ct.nlsys(lambda t, x, u, params: [x[0] + 0.01 * (1.0 - u[0])],
                  lambda t, x, u, params: 2.0 * (1.0 - u[0]) + x[0], inputs="y",
                  outputs="u", states="z", dt=0.01, name="pi")
    loop = ct.interconnect([plant, pi], outputs="y", name="discrete_loop")
    T = np.arange(3000) * 0.01
    whole = simulate(loop, T, [0.0, 0.0])  # on the driver (the tests' policy)
    driver, calls = loader.driver().run_discrete, []

    def loop_of(job, name, policy=None):
        job.compiling = not calls
        if not calls:
            return recording(driver, calls, "driver"), True
        return recording(driver, calls, "module", plan=job.generic_plan()), False

    monkeypatch.setattr(Job, "loop", loop_of)
    compiling_then_done(monkeypatch, after=1)
    cut = simulate(loop, T, [0.0, 0.0])
    np.testing.assert_array_equal(cut.outputs, whole.outputs)
    np.testing.assert_array_equal(cut.states, whole.states)
    done = ranges_of(calls, 7, 8)  # (T, X0, U, P, Y, X, status, k0, k1)
    assert [label for label, _, _ in done] == ["driver", "driver", "module"]
    assert [(a, b) for _, a, b in done][0] == (0, 7)
    assert done[-1][2] == T.size and done[1][2] == done[2][1]


def test_a_run_asked_of_the_driver_stays_on_it(monkeypatch):
    job, T, U, X0 = servo()
    compiling_then_done(monkeypatch, after=0)
    job.compiling = True
    monkeypatch.setattr(job, "loop", lambda name, policy=None: pytest.fail("switched"))
    run_continuous(job, T, U, X0, generic=True)


def test_a_failed_compile_leaves_the_run_on_the_driver(monkeypatch):
    job, T, U, X0 = servo()
    whole = run_continuous(job, T, U, X0, generic=True)
    driver, calls = loader.driver().run_continuous, []
    answers = [(recording(driver, calls, "driver"), True)] * 2  # no module after it either
    monkeypatch.setattr(job, "loop", loops_handed(job, answers))
    compiling_then_done(monkeypatch, after=1)
    cut = run_continuous(job, T, U, X0)
    np.testing.assert_array_equal(cut.y, whole.y)
    done = ranges_of(calls, 3, 4)
    assert {label for label, _, _ in done} == {"driver"}
    assert done[-1][2] == calls[0][1][1].size and len(done) == 3  # two ranges, then the rest
    assert not answers


def test_a_compile_refused_while_another_ran_is_started_during_the_run(monkeypatch):
    # one background compile at a time: this diagram's starts once the other one is over
    job, T, U, X0 = servo()
    driver, calls, started = loader.driver().run_continuous, [], []
    module = recording(driver, calls, "module", plan=job.generic_plan())
    answers = [(recording(driver, calls, "driver"), True), (module, False)]
    monkeypatch.setattr(job, "loop", loops_handed(job, answers))
    asked = []

    def done(source):  # not started (refused), then compiling a while, then compiled
        asked.append(source)
        return None if not started else len(asked) > 8

    monkeypatch.setattr(loader, "background_done", done)
    monkeypatch.setattr(switching, "COMPILE_AFTER", 0.0)
    monkeypatch.setattr(loader, "compile_in_background",
                        lambda source, entry: started.append((source, entry)))
    monkeypatch.setattr(switching, "FIRST_CHUNK", 7)
    monkeypatch.setattr(switching, "CHUNK_SECONDS", 1e-4)
    run_continuous(job, T, U, X0)
    switching.wait_for_compiles()
    assert started and set(started) == {(job.source, "run_continuous")}
    labels = [label for label, _ in calls]
    assert labels[-1] == "module" and set(labels[:-1]) == {"driver"}


def test_a_short_run_starts_its_modules_compile_when_it_ends(monkeypatch):
    # not during the run (on two cores the compile's start slowed a short run twofold)
    job, T, U, X0 = servo()
    started = []
    monkeypatch.setattr(loader, "compile_in_background",
                        lambda source, entry: started.append((source, entry)))
    monkeypatch.setattr(switching, "COMPILE_AFTER", 60.0)
    driver = loader.driver().run_continuous

    def loop_of(name, policy=None):
        switching.compile_soon(job.source, name)  # as Job.loop does, policy background
        job.compiling = True
        return driver, True

    monkeypatch.setattr(job, "loop", loop_of)
    monkeypatch.setattr(loader, "background_done", lambda source: None if not started
                        else False)
    seen = []
    real = switching.DriverThenModule.__call__
    monkeypatch.setattr(switching.DriverThenModule, "__call__", lambda self, *a: (
        seen.append(list(started)), real(self, *a))[1])
    run_continuous(job, T[:11], U[:, :11], X0)  # 0.2 s: one range
    switching.wait_for_compiles()
    assert seen == [[]]  # nothing started while it ran
    assert started == [(job.source, "run_continuous")]  # started at its end


def test_a_wiring_never_run_goes_to_the_driver_without_importing_its_module(monkeypatch):
    import uuid

    loop, T, X0, U = two_rate_servo()
    loop.syslist[0].name += f"_{uuid.uuid4().hex[:8]}"  # block names are in the module
    job = prepare(loop)
    started = []
    monkeypatch.setattr(loader, "compile_in_background",
                        lambda source, entry: started.append(entry))
    function, generic = job.loop("run_continuous", policy="background")
    assert generic and job.how == "driver" and job.compiling
    assert job.source not in loader._LOADED
    assert not loader.module_path(job.source, write=False).exists()
    switching.compile_now(job.source)
    switching.wait_for_compiles()
    assert started == ["run_continuous"]
