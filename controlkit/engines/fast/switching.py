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
"""

from __future__ import annotations

import time

from . import loader

#: Wall time of one range of a run on the driver while the module compiles: the longest
#: the run goes on on the driver once the module is ready.
CHUNK_SECONDS = 0.2
#: Steps of the first range, before the pace is known.
FIRST_CHUNK = 256


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
        if done is None:  # not started: another diagram's compile ran; now, if it is over
            loader.compile_in_background(self.job.source, self.name)
        if not done:
            return  # still compiling
        self.waiting = False  # one look once the process has exited
        function, generic = self.job.loop(self.name)
        if not generic:
            self.function, self.generic = function, False
