"""A long first run of a new wiring moves from the generic driver to the diagram's own
module as soon as a background process has compiled it.

A diagram whose module is not compiled yet runs on the generic driver, which calls each
block's kernel through its address, while another process compiles the module
(:func:`.loader.compile_in_background`, a few seconds). Over 10^5 s the driver is 2-4x
slower than the module (``benchmarks/bench_continuous.py``: the two-rate servo 232 s
against 62 s), so a run that began on the driver would wait minutes for nothing. The loops
of both run any range of steps (``k0 .. k1 - 1``, the state carried in and out), and the
driver and the module do the same arithmetic (``tests/test_continuous.py`` checks their
bits equal): a run cut into ranges gives the numbers of a run in one piece, whichever
loop ran each range. So while the compile runs, :class:`DriverThenModule` hands the run out
in ranges of about :data:`CHUNK_SECONDS` each at the pace measured, and between two it
takes the module once the compiling process has exited and the module is in numba's
cache (or starts that process once the compile of another diagram, which it waited
for, is over).

A diagram with continuous states only is one interval of its integrator (there is no
step at which its state alone says where the integration stands): it stays on the loop it
began on.

The compiling process is started :data:`COMPILE_AFTER` seconds into the run, or when the
run ends if sooner (:func:`compile_soon`, :func:`compile_now`): on a machine of two cores a
short run that shared it with the compile's start took twice as long
(``benchmarks/bench_continuous.py``, servo_pi_discrete over 100 s wired anew: 0.11 s
against 0.04 s), and the module is only needed by a later call -- or by a long run, which
loses a few hundredths of a second of a compile of seconds.
"""

from __future__ import annotations

import os
import threading
import time

from . import loader

#: Seconds into a run on the driver after which the diagram's module starts compiling.
COMPILE_AFTER = 0.5
#: Wall time of one range of a run on the driver while the module compiles: the longest
#: the run goes on on the driver once the module is ready.
CHUNK_SECONDS = 0.2
#: Steps of the first range, before the pace is known.
FIRST_CHUNK = 256

#: Compiles waiting for their moment, by module source; and the lock under which one starts.
_SOON: dict[str, threading.Timer] = {}
_STARTING = threading.Lock()
os.register_at_fork(after_in_child=_SOON.clear)  # (a child has none of the timers)


def compile_soon(source: str, entry: str) -> None:
    """Have a background process compile ``source``'s module (its entry ``entry``) in
    :data:`COMPILE_AFTER` seconds, unless :func:`compile_now` starts it sooner.

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> compile_soon(prepare(cmg_loop()).source, "run_discrete")  # doctest: +SKIP
    """
    if source in _SOON or loader.background_done(source) is not None:
        return  # waiting, running or ran
    timer = threading.Timer(COMPILE_AFTER, _start, (source, entry))
    _SOON[source] = timer
    timer.start()  # not a daemon: a process that ends meanwhile starts the compile first


def compile_now(source: str) -> None:
    """Start the compile :func:`compile_soon` left waiting for ``source`` now (in a
    thread: starting a process takes milliseconds); nothing if none waits.

    Examples
    --------
    >>> compile_now("no such module")
    """
    timer = _SOON.get(source)
    if timer is not None:
        timer.cancel()
        threading.Thread(target=_start, args=timer.args, name="controlkit-compile").start()


def wait_for_compiles() -> None:
    """Wait until the background compiles started (or waiting to start) by this process
    have ended.

    Examples
    --------
    >>> wait_for_compiles()
    """
    for timer in list(_SOON.values()):
        compile_now(timer.args[0])
    while _SOON:  # (a compile leaves it once its process is started)
        time.sleep(0.01)
    for process in list(loader._BACKGROUND.values()):
        process.wait()


def _start(source, entry):
    with _STARTING:  # the timer and compile_now may both get here: one process
        if source in _SOON:
            try:
                loader.compile_in_background(source, entry)
            finally:
                del _SOON[source]



class DriverThenModule:
    """The entry point ``name`` of ``job``, called over consecutive ranges of steps.

    Parameters
    ----------
    job : Job
        The job whose loop runs (:class:`.run.Job`).
    name : str
        ``"run_discrete"`` or ``"run_continuous"``.
    function : callable
        The entry point :meth:`.run.Job.loop` returned.
    generic : bool
        Whether ``function`` is the driver's (it takes the job's plan last).
    may_switch : bool
        False keeps the run on ``function`` (a caller that asked for the driver).

    Examples
    --------
    A run on the driver with no compile under way is handed out whole:

    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> job = prepare(cmg_loop())
    >>> function, generic = job.loop("run_discrete", policy="never")
    >>> list(DriverThenModule(job, "run_discrete", function, generic).ranges(0, 12000))
    [(0, 12000)]
    """

    def __init__(self, job, name, function, generic, *, may_switch=True):
        self.job, self.name = job, name
        self.function, self.generic = function, generic
        # the module compiled (or to be) by a background process: it may come during the run
        self.waiting = may_switch and generic and job.compiling
        self.size = FIRST_CHUNK

    def __call__(self, *arguments):
        """Run the current loop on ``arguments`` (the job's plan added for the driver)."""
        if self.generic:
            return self.function(*arguments, self.job.generic_plan())
        return self.function(*arguments)

    def ranges(self, k0, k1):
        """The ranges ``(a, b)`` covering ``k0 .. k1 - 1`` to run one after another: one
        while nothing can change, else ranges of about :data:`CHUNK_SECONDS` each; after
        each, the loop is the module's if it is ready."""
        while k0 < k1:
            if not self.waiting:
                yield k0, k1
                return
            end = min(k1, k0 + self.size)
            begin = time.perf_counter()
            yield k0, end
            took = time.perf_counter() - begin
            self.size = max(1, min(16 * self.size, int((end - k0) * CHUNK_SECONDS
                                                        / max(took, 1e-6))))
            self._maybe_switch()
            k0 = end

    def _maybe_switch(self):
        done = loader.background_done(self.job.source)
        if done is None:  # waiting for its moment, or refused while another one ran
            compile_soon(self.job.source, self.name)
        if not done:
            return  # still compiling
        self.waiting = False  # one look once the process has exited
        function, generic = self.job.loop(self.name)
        if not generic:
            self.function, self.generic = function, False
