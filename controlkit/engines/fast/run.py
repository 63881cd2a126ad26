"""Running a diagram on the fast engine: prepare it, pick its loop, run in chunks or streamed.

:func:`prepare` turns a diagram into a :class:`Job`: its blocks with their kernels
(:mod:`.tiers`), its plan (:mod:`.plan`) and its module's source (:mod:`.codegen`).
:meth:`Job.loop` picks how an entry point runs: the diagram's module compiled (from the
disk cache), the generic driver while a background process compiles the module
(:mod:`.loader`), or the module as Python when a block is on the python tier.
:func:`simulate` runs a discrete diagram step by step (python-control's discrete
simulation, with chunks, progress and streaming for long runs);
:mod:`.continuous` runs diagrams with continuous states.
"""

from __future__ import annotations

import functools
import os
from dataclasses import dataclass, field

import control as ct
import numpy as np

from ... import _jit, _quiet
from ..contract import (
    UnsupportedSystem,
    check_arguments,
    chunk_bounds,
    recorded_indices,
)
from ..contract import response as base_response
from . import loader, reuse
from .codegen import evaluation_order, generate
from .continuous import run_continuous
from .diagnose import explain_divergence, explain_failure
from .plan import Plan, make_plan
from .switching import DriverThenModule, compile_now, compile_soon
from .tiers import blocks_of

#: How a diagram's own module is compiled when not in the disk cache yet (environment
#: variable ``CONTROLKIT_MODULES``): ``"background"`` (the driver runs while another
#: process compiles it; the default), ``"now"`` (compiled before the run) or
#: ``"never"`` (the driver only; the test suite uses it to stay quick).
MODULES = os.environ.get("CONTROLKIT_MODULES", "background")
_MODULE_POLICIES = ("background", "now", "never")


@dataclass
class Job:
    """A diagram ready to run (see :func:`prepare`).

    Attributes
    ----------
    sys : control.InterconnectedSystem
    plan : Plan
    P : numpy.ndarray
        The parameters in force (packed by the blocks, at run time).
    source : str
        The diagram's module.
    injected : dict
        Kernels the module must be handed (Python functions: the python tier).
    how : str
        How the last loop picked runs: ``"module"``, ``"driver"`` or ``"python"``.
    compiling : bool
        Whether the last loop picked is the driver while the module is (to be) compiled
        by a background process (:mod:`.switching` then moves a long run to the module).

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> job = prepare(cmg_loop())
    >>> job.plan.mode, job.P.size > 0
    ('discrete', True)
    """

    sys: object
    plan: Plan
    P: np.ndarray
    source: str
    injected: dict
    how: str = ""
    compiling: bool = False
    _generic: tuple | None = field(default=None, repr=False)
    _entries_asked: bool = field(default=False, repr=False)
    _entry: str = field(default="", repr=False)

    @property
    def blocks(self):
        """The diagram's blocks with their kernels and offsets."""
        return self.plan.blocks

    def generic_plan(self) -> tuple:
        """The driver's ``plan`` argument: the plan's arrays and the kernels' addresses."""
        if self._generic is None:
            from .entries import addresses, entry

            folder = loader.cache_folder()
            self._generic = loader.driver().plan_arguments(
                self.plan, addresses([entry(k, folder) for k in self.plan.kernels]))
        return self._generic

    def after_run(self) -> None:
        """After a run on the diagram's own module, in a session that warms up (a
        notebook): the entries of its kernels are loaded in the background
        (:func:`preload_entries`), so that the same blocks wired anew run on the driver
        without loading them (about 7 ms a kernel) in the person's next call. In any
        session the run is marked for a later session's warm-up (:mod:`.recent`). After a
        run on the driver, the module's compile waiting to start starts now."""
        if self.compiling:
            compile_now(self.source)
        if self.how != "module" or self._entries_asked or not _jit.HAVE_NUMBA:
            return
        self._entries_asked = True
        from . import recent
        from .entries import loaded

        recent.note(self.source, self._entry)  # for the next session's warm-up

        if not all(loaded(k) for k in self.plan.kernels):
            _quiet.later(functools.partial(preload_entries, self))

    def loop(self, name: str, *, policy: str | None = None):
        """The entry point ``name`` (``run_discrete`` or ``run_continuous``) to call.

        Returns ``(function, generic)``: with ``generic`` the function is the driver's and
        takes :meth:`generic_plan` as its last argument (``run_continuous`` of a module
        takes the integrator's machine as its first).
        """
        policy = policy or MODULES
        if policy not in _MODULE_POLICIES:
            raise ValueError(f"CONTROLKIT_MODULES must be one of {_MODULE_POLICIES}, "
                             f"got {policy!r}")
        self.compiling = False
        if self.injected or not _jit.HAVE_NUMBA:
            self.how = "python"
            return getattr(loader.load_python(self.source, self.injected), name), False
        if policy == "never":
            return self._on_driver(name)
        if policy == "background" and not loader.module_path(self.source, write=False).exists():
            # a wiring never run: nothing compiled to look for (importing its module to ask
            # took 6 ms of a 10 ms first call); the compile writes the file
            return self._compiling(name)
        module = loader.load(self.source)
        function = getattr(module, name)
        if loader.is_compiled(function) or policy == "now":
            self.how, self._entry = "module", name
            return function, False
        return self._compiling(name)  # (policy "background": "now" has compiled it)

    def _compiling(self, name):
        """The driver's entry ``name``, the module compiled in the background meanwhile."""
        if loader.BACKGROUND_COMPILE:
            compile_soon(self.source, name)  # (or at the run's end, if sooner)
            self.compiling = True
        return self._on_driver(name)

    def _on_driver(self, name):
        self.how = "driver"
        return getattr(loader.driver(), name), True


def prepare(sys, params=None, start=None) -> Job:
    """The :class:`Job` of ``sys`` with the parameters ``params`` in force.

    ``start`` is the run's ``(t0, X0, U0)``: users' functions compiled for the run must
    agree with their Python selves there too
    (:func:`~controlkit.engines.fast.usercode.compiled_kernel`).

    Raises
    ------
    UnsupportedSystem
        Naming the block that has no kernel, or the algebraic loop.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> [b.system.name for b in prepare(cmg_loop()).blocks]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    from ...sampled_data import SampledDataSystem

    key = reuse.job_key(sys, params, start)
    job = reuse.reused(sys, key)
    if job is not None:  # called again with nothing it depends on changed
        return job
    blocks = blocks_of(sys, params, start)
    plan = make_plan(sys, blocks, evaluation_order(sys, blocks))
    source, injected = generate(plan, held_logic=isinstance(sys, SampledDataSystem))
    job = Job(sys, plan, plan.parameters(), source, injected)
    reuse.keep(sys, key, job)
    return job


def load_driver() -> bool:
    """Load the generic driver's two entry points from numba's disk cache, compiling
    nothing; False when they are not all there (the first new wiring then compiles them).

    A notebook's warm-up thread (:mod:`controlkit._warmup`) calls it, so that the first
    newly wired diagram of a session does not pay the driver's loading (about 35 ms of a
    first call, with the entries of the LTI kernels).

    Examples
    --------
    >>> isinstance(load_driver(), bool)
    True
    """
    if not _jit.HAVE_NUMBA:
        return False
    job = warm_up_job()
    driver = loader.driver()
    # typed as the driver's plan argument (the kernels' addresses are only looked at when
    # it runs)
    plan = driver.plan_arguments(job.plan, np.zeros(len(job.plan.kernels), dtype=np.int64))
    from .background import empty_arguments  # (not at the top: it runs as __main__ too)

    if not all(_jit.from_cache(getattr(driver, name), (*empty_arguments(name), plan))
               for name in ("run_continuous", "run_discrete")):
        return False
    return True


def warm_up_job() -> Job:
    """The job of a first-order lag alone: what the warm-up loads the driver for, and whose
    kernels (an LTI block's, which most diagrams call) it loads the entries of.

    Examples
    --------
    >>> [b.system.name for b in warm_up_job().blocks]
    ['lag']
    """
    lag = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs="u", outputs="y", name="lag")
    return prepare(ct.interconnect([lag], inputs="u", outputs="y", name="warm_up"))


def preload_entries(job) -> int:
    """Load the entries of ``job``'s kernels from numba's disk cache, compiling none
    (:func:`.entries.preload`, for a background thread); how many are loaded.

    Examples
    --------
    >>> preload_entries(warm_up_job()) <= len(warm_up_job().plan.kernels)
    True
    """
    from .entries import preload

    return preload(job.plan.kernels, loader.cache_folder())


def compile_system(sys, params=None):
    """The compiled discrete loop of ``sys`` and its blocks (compiled now if need be).

    Returns ``(run, blocks)`` with ``run(T, X0, U, P, Y, X, status, k0, k1) -> state``.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> run, blocks = compile_system(cmg_loop())
    >>> [b.system.name for b in blocks]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    job = prepare(sys, params)
    run, generic = job.loop("run_discrete", policy="now")
    return run, job.blocks


#: Steps simulated per chunk when a run is streamed (bounds the memory of long runs).
STREAM_CHUNK_STEPS = 20_000


def discrete_loop(job) -> DriverThenModule:
    """``run(T, X0, U, P, Y, X, status, k0, k1) -> state`` of a discrete job, however it
    runs; its ``ranges(k0, k1)`` cut a long run on the driver so that the module takes
    over once compiled (:mod:`.switching`).

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> callable(discrete_loop(prepare(cmg_loop())))
    True
    """
    return DriverThenModule(job, "run_discrete", *job.loop("run_discrete"))


def simulate(sys, T, X0, U=0.0, *, params=None, progress=None, chunks=1,
             record_every=1, on_chunk=None) -> ct.TimeResponseData:
    """Simulate a discrete interconnect without python-control's sweeps.

    Same arguments and result as :func:`control.input_output_response` for a discrete
    system (plus ``progress``, ``chunks``, ``record_every`` and ``on_chunk`` as in
    :func:`controlkit.simulation.simulate`). With ``record_every > 1`` or ``on_chunk``
    the run is streamed: it proceeds in chunks of :data:`STREAM_CHUNK_STEPS` steps
    through fixed buffers, so memory does not grow with the horizon.

    Raises
    ------
    UnsupportedSystem
        When a block cannot be compiled, or the diagram is not discrete.

    Examples
    --------
    >>> from controlkit.studies.spacecraft.scenario import build_loop, initial_attitude
    >>> from controlkit.simulation import initial_state
    >>> loop = build_loop("ideal")
    >>> X0 = initial_state(loop, plant=initial_attitude())
    >>> resp = simulate(loop, np.arange(3) * 0.1, X0)
    >>> resp.outputs.shape
    (10, 3)
    """
    if not isinstance(sys, ct.InterconnectedSystem):
        name = getattr(sys, "name", type(sys).__name__)
        raise UnsupportedSystem(f"{name!r} is a single block; the fast engine runs "
                                f"interconnects")
    T, X0, U = check_arguments(sys, T, X0, U)  # a lazy TimeGrid stays lazy, U a view
    if not sys.isdtime(strict=True):  # continuous states: the whole run at once
        T = np.asarray(T, dtype=float)
        resp = run_continuous(prepare(sys, params, (T[0], X0, U[:, 0])), T, U, X0)
        if on_chunk is not None:
            on_chunk(resp.t, resp.y, resp.x)
        if progress is not None:
            progress(1.0)
        kept = recorded_indices(resp.t.size, record_every)
        return base_response(sys, resp.t[kept], resp.y[:, kept], resp.x[:, kept],
                             resp.u[:, kept])
    job = prepare(sys, params, (T[0], X0, U[:, 0]))
    run = discrete_loop(job)
    blocks, P = job.blocks, job.P
    streamed = record_every != 1 or on_chunk is not None
    if not streamed:
        T = np.ascontiguousarray(T, dtype=float)
    N = T.size
    kept = recorded_indices(N, record_every)
    if streamed:
        resp = _stream(sys, run, blocks, T, X0, U, P, kept, on_chunk, progress, params)
        job.after_run()
        return resp
    U = np.require(U, dtype=float, requirements=["C", "W"])
    Y = np.zeros((sys.noutputs, N))
    X = np.zeros((sys.nstates, N))
    status = np.full(3, -1, dtype=np.int64)
    bounds = chunk_bounds(N, chunks)
    x = np.array(X0, dtype=float)
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        for a, b in run.ranges(k0, k1):
            x = run(T, x, U, P, Y, X, status, a, b)
            if status[0] >= 0 or not np.isfinite(x).all():
                break
        if status[0] >= 0:
            explain_failure(sys, blocks, T, X, U, status, params)
        if not np.isfinite(x).all():
            explain_divergence(sys, blocks, T, X, x, k1, U, params)
        if progress is not None:
            progress(k1 / N)
    job.after_run()
    return base_response(sys, T, Y, X, U)


def _stream(sys, run, blocks, T, x, U, P, kept, on_chunk, progress, params=None):
    """Run the loop chunk by chunk on slices of ``T`` and ``U``; keep ``kept`` only.

    The loop indexes its arrays from ``k0``, so each chunk runs on views of ``T`` and
    ``U`` with ``k0 = 0`` into buffers reused from chunk to chunk.
    """
    N = T.size
    step = min(STREAM_CHUNK_STEPS, max(N, 1))
    Yb, Xb = np.zeros((sys.noutputs, step)), np.zeros((sys.nstates, step))
    Y, X = np.zeros((sys.noutputs, kept.size)), np.zeros((sys.nstates, kept.size))
    status = np.full(3, -1, dtype=np.int64)
    x = np.array(x, dtype=float)
    for k0 in range(0, N, step):
        k1 = min(N, k0 + step)
        Tc = np.ascontiguousarray(T[k0:k1], dtype=float)
        Uc = np.require(U[:, k0:k1], dtype=float, requirements=["C", "W"])
        for a, b in run.ranges(0, k1 - k0):
            x = run(Tc, x, Uc, P, Yb, Xb, status, a, b)
            if status[0] >= 0 or not np.isfinite(x).all():
                break
        if status[0] >= 0:
            explain_failure(sys, blocks, Tc, Xb, Uc, status, params)
        if not np.isfinite(x).all():
            explain_divergence(sys, blocks, Tc, Xb, x, k1 - k0, Uc, params)
        if on_chunk is not None:
            on_chunk(Tc, Yb[:, :k1 - k0], Xb[:, :k1 - k0])
        mine = (kept >= k0) & (kept < k1)
        Y[:, mine] = Yb[:, kept[mine] - k0]
        X[:, mine] = Xb[:, kept[mine] - k0]
        if progress is not None:
            progress(k1 / N)
    return base_response(sys, T[kept], Y, X, U[:, kept])
