"""Running a diagram's module: as Python, or compiled, and when each.

:func:`prepare` turns a diagram into a :class:`Job`: its blocks (:mod:`.tiers`), plan
(:mod:`.plan`) and module text (:mod:`.codegen`). A job runs as Python
(``job.functions()``: nothing to compile) or compiled by numba and kept in the store
(:mod:`.store`), as Simulink runs a model in normal or accelerator mode. :class:`Runner`
decides between the pieces of a run by :data:`RULE`; a compiled module is first run beside
Python on one piece, and if their numbers differ the run goes on as Python.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from ... import _jit
from ..._checks import warn_caller
from .. import PYTHON_CONTROL_LEAST, PYTHON_CONTROL_SLOWER, check_compile
from . import reuse, store, usercode
from .codegen import generate
from .pieces import PIECE_SECONDS, checked_as, now, same_numbers
from .plan import Plan, evaluation_order, make_plan
from .tiers import NotCompiled, blocks_of, same_kernels

#: How the engine chooses between running a diagram as Python and compiled.
RULE = ("compiled when asked (compile=True), when the diagram's module is compiled "
        "already, or when the run, with the earlier runs of the same module in this "
        "process, would take longer as Python than compiling it takes, and the call "
        "stays no slower than python-control's (timed on its first pieces); else as Python")
#: Compiling pays when the rest of the run as Python, with the module's earlier runs, takes
#: this times numba's start and the compile: 1, ski rental (at most twice hindsight's best).
PAYS = 1.0
#: numba's own start in a process in two steps, ``(seconds, done, make)``: the import, the
#: first use (numba fills its tables: loading the step machine kept in the store).
NUMBA_START = ((0.15, lambda: bool(_jit._NUMBA), _jit.numba_module),
               (0.25, lambda: bool(store._MACHINE or any(_COMPILED.values())
                                   or store.integrator_to_compile()), store.step_machine))
#: What a run pays before its first compiled step even when its module is kept compiled.
NUMBA_START_SECONDS = sum(seconds for seconds, _, _ in NUMBA_START)
#: A new diagram's compile before one was measured in this store: s, and s a block.
COMPILE_SECONDS = (2.0, 1.0)
#: The modules compiled in this process, by text: their compiled entry points.
_COMPILED: dict[str, dict] = {}
#: The compiled job made in this process for a module run as Python (by its text), or why
#: it cannot be made: a diagram built anew with the same text reads its cost from it, and
#: runs compiled from its start once that module is compiled here.
_TWINS: dict = {}
#: About how long making a compiled job takes, a block (translating its functions).
TWIN_SECONDS = 0.003
#: Compiled modules compared equal with Python's on a piece in this process (checked_as).
CHECKED: set[tuple] = set()
#: About how long loading a module kept compiled takes, numba started.
LOAD_SECONDS = 0.05
#: Modules whose compiled numbers differed from Python's, by text: why (explain says it).
DIFFERS: dict[str, str] = {}
#: Seconds the runs of a module (by text) took as Python in this process: a diagram run
#: again and again (a notebook's cell, a loop over gains) compiles once they would pay.
PYTHON_SECONDS: dict[str, float] = {}
#: How many time points (or steps) the runs :data:`PYTHON_SECONDS` counts had, by module.
PYTHON_POINTS: dict[str, int] = {}


@dataclass
class Job:
    """A diagram ready to run one way (see :func:`prepare`): ``P`` the parameters in
    force, ``source`` its module's text, ``compiled`` whether its kernels are the ones
    compiled code calls.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> job = prepare(cmg_loop())
    >>> job.plan.continuous.size, job.P.size > 0, job.compiled
    (0, True, False)
    """

    sys: object
    plan: Plan
    P: np.ndarray
    source: str
    compiled: bool
    _python: object = field(default=None, repr=False)
    #: The compiled continuous run's module, loop and functions (:mod:`.continuous`).
    continuous: object = field(default=None, repr=False)

    @property
    def blocks(self):
        """The diagram's blocks with their kernels and offsets."""
        return self.plan.blocks

    def kernels(self) -> dict:
        """The kernels the module's text names ``kernel_<i>``, as this job runs them."""
        names = {}
        for i, fn in enumerate(self.plan.kernels):
            if not self.compiled:
                names[f"kernel_{i}"] = _jit.python_function(fn)
            elif isinstance(fn, _jit.Jitted) and "boundscheck" not in fn.options:
                names[f"kernel_{i}"] = _pasted(fn)
            else:  # a user's compiled kernel, or a numba function
                names[f"kernel_{i}"] = fn
        return names

    def functions(self):
        """The module's functions run as Python (a namespace; made once)."""
        if self._python is None:
            namespace = dict(self.kernels())
            exec(_module_code(self.source), namespace)
            self._python = SimpleNamespace(**namespace)
        return self._python

    def entry(self, name: str, args):
        """The compiled entry point ``name`` for the types of ``args``: loaded from the
        store, or compiled now (saying so when that takes seconds)."""
        return self.compiled_once(name, lambda path: store.compile_entry(
            getattr(store.import_module(path, self.kernels()), name), args, path,
            blocks=len(self.blocks)))

    def compiled_once(self, key, compile_it):
        """``compile_it(path)`` of the module's store file, once a process per ``key``, said
        when it takes seconds; when numba fails, :class:`NotCompiled` (kept for ``explain``)."""
        with store.LOCK:  # (one thread compiles; the others then load what it made)
            entries = _COMPILED.setdefault(self.source, {})
            if key not in entries:
                path = store.module_file(self.source, "diagram")
                if store.record(path) is None:
                    expected = compile_estimate(self)
                    if expected >= 2.0:
                        store._say(f"compiling the diagram {self.sys.name!r} (about "
                                   f"{expected:.0f} s, once: later runs load it)")
                try:
                    if store.record(path) is None:  # its user's kernels first, each timed
                        _compile_kernels(self)
                    entries[key] = compile_it(path)
                except Exception as error:  # noqa: BLE001 - numba's: runs as Python
                    DIFFERS[self.source] = str(error) if isinstance(error, NotCompiled) \
                        else f"numba could not compile it ({store.numba_said(error)})"
                    raise NotCompiled(DIFFERS[self.source]) from error
            return entries[key]

    def is_compiled(self) -> bool:
        """Whether its module is compiled already (in this process, or in the store)."""
        try:
            return self.source in _COMPILED or store.compiled_before(self.source, "diagram")
        except store.StoreRefused:
            return False


@functools.lru_cache(maxsize=64)  # (a diagram built again writes the same text)
def _module_code(source: str):
    """A module text's code, compiled once a process (half of a rebuilt diagram's call)."""
    return compile(source, "<controlkit diagram module>", "exec")


def _compile_kernels(job) -> None:
    """Compile the user's kernels of ``job`` not compiled yet, one by one (timed for the
    estimates); numba's refusal of one is :class:`NotCompiled` naming its block."""
    for _, make in usercode.kernels_to_compile(job.plan.kernels):
        try:
            make()  # (a partial of compile_kernel: its kernel is make.args[0])
        except (MemoryError, OSError):  # (the machine's: the module's compile says)
            continue
        except Exception as error:  # noqa: BLE001 - numba's refusal, kept in the store
            who = next(b for b in job.blocks if make.args[0] in (b.kernel.output, b.kernel.update))
            raise NotCompiled(f"numba could not compile block {who.system.name!r} "
                              f"({store.numba_said(error)})") from error


def _pasted(fn):
    """``fn`` as numba pastes it into a module's entry point (``inline="always"``)."""
    pasted = getattr(fn, "_controlkit_pasted", None)
    if pasted is None:
        pasted = _jit.Jitted(fn.py_func, {"inline": "always"})
        fn._controlkit_pasted = pasted
    return pasted


def prepare(sys, params=None, *, compiled=False, like=None) -> Job:
    """The :class:`Job` of ``sys`` with the parameters ``params`` in force.

    ``compiled``: the job of the compiled module (NotCompiled naming a block that cannot
    be compiled); else the job run as Python. ``like``: the job of the same call run as
    Python, whose plan and text a compiled job takes when its blocks have the very same
    kernels (no user's function): they would be written again the same.

    Raises
    ------
    UnsupportedSystem
        Naming the block that cannot run, or the algebraic loop.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> [b.system.name for b in prepare(cmg_loop()).blocks]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    key = reuse.job_key(sys, params, compiled)
    job = reuse.reused(sys, key)
    if job is not None:  # called again with nothing it depends on changed
        return job
    blocks = blocks_of(sys, params, compiled=compiled)
    if like is not None and same_kernels(blocks, like.blocks):
        job = Job(sys, like.plan, like.P, like.source, compiled)
    else:
        plan = make_plan(sys, blocks, evaluation_order(sys, blocks))
        job = Job(sys, plan, plan.parameters(), generate(plan), compiled)
    reuse.keep(sys, key, job)
    return job


def compile_estimate(job) -> float:
    """About how long compiling ``job``'s module takes, in seconds: the store's median time
    per block for its kind (:func:`.store.compile_times`, else :data:`COMPILE_SECONDS`),
    its user's kernels not compiled yet, and the integrator if needed and not compiled.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> compile_estimate(prepare(cmg_loop())) > 0
    True
    """
    continuous = bool(job.plan.continuous.size or job.plan.held)
    measured = store.compile_times("continuous" if continuous else "run_discrete")
    if measured:
        seconds = float(np.median(measured)) * len(job.blocks)
    else:
        seconds = COMPILE_SECONDS[0] + COMPILE_SECONDS[1] * len(job.blocks)
    seconds += sum(step for step, _ in usercode.kernels_to_compile(job.plan.kernels))
    return seconds + (store.integrator_to_compile() if continuous else 0.0)


def compiled_job(sys, params, like=None):
    """The compiled job of ``sys``, or the reason it cannot be had (a str); ``like`` as
    :func:`prepare` takes it.

    Examples
    --------
    >>> import control as ct
    >>> gain = ct.ss([], [], [], [[2.0]], name="k", inputs="e", outputs="y")
    >>> job = compiled_job(ct.interconnect([gain], inputs="e", outputs="y"), None)
    >>> isinstance(job, str) or job.compiled
    True
    """
    if not _jit.available():
        return "numba is not installed (pip install \".[fast]\")"
    try:
        store.folder()
    except store.StoreRefused as why:
        return str(why)
    try:
        job = prepare(sys, params, compiled=True, like=like)
    except NotCompiled as why:
        return str(why)
    if job.source in DIFFERS:
        return DIFFERS[job.source]
    return job


def compiled_cost(candidate) -> float:
    """Seconds before the compiled job ``candidate`` can run: numba's start if not made,
    and loading its module if kept compiled, else compiling it.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> compiled_cost(prepare(cmg_loop(), compiled=True)) >= LOAD_SECONDS
    True
    """
    return sum(seconds for seconds, done, _ in NUMBA_START if not done()) + (
        LOAD_SECONDS if candidate.is_compiled() else compile_estimate(candidate))


class Runner:
    """How one call runs: its mode now and the rule that may change it between pieces.

    ``compile`` is the call's argument: True (compiled), False (Python), None (the rule).

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> runner = Runner(cmg_loop(), None, False)
    >>> runner.job.compiled, runner.decided
    (False, True)
    """

    def __init__(self, sys, params, compile, points=1):
        check_compile(compile)
        self.sys, self.params, self.asked, self.points = sys, params, compile, points
        self.python = prepare(sys, params)
        self.compiled, self.decided = None, compile is False
        self.spent, self.last = 0.0, None  # (steps' seconds; the last piece's elapsed, done)
        twin = _TWINS.get(self.python.source)
        if compile or compile is None and getattr(twin, "source", None) in _COMPILED:
            # asked for, or compiled already in this process: compiled from the start
            candidate = compiled_job(sys, params, self.python)
            if isinstance(candidate, str):
                self.decided = True
                if compile:
                    warn_caller(f"running {sys.name!r} as Python: {candidate}")
            elif compile or candidate.source in _COMPILED:
                self.compiled, self.decided = candidate, True
                _TWINS[self.python.source] = candidate
        elif compile is None:
            self._compile_if_earlier_runs_paid()

    def _compile_if_earlier_runs_paid(self) -> None:
        """Compiled from the start when the earlier runs of this module in this process
        took, as Python, longer than compiling it takes, and it fits in this call (about
        python-control's), numba started and the user's kernels compiled; else the steps
        (numba's start, each kernel) that fit in this call are made."""
        source = self.python.source
        before = PYTHON_SECONDS.get(source, 0.0)
        typical = before * self.points / max(PYTHON_POINTS.get(source, 1), 1)  # (this call's)
        # what this call can spend on steps: what it saves against python-control's call
        room = (PYTHON_CONTROL_SLOWER - 1.0) * typical
        if before <= PAYS * NUMBA_START_SECONDS or any(
                seconds > room for seconds, done, _ in NUMBA_START if not done()):
            return  # (not worth numba's start, or a start that never fits in a call)
        if source not in _TWINS:  # (its cost, read by the diagrams of this text to come)
            # made before its steps are known: only where it fits even beside
            # python-control's quickest call (0.75x on a 20-block chain of one-line functions)
            if TWIN_SECONDS * len(self.python.blocks) > (PYTHON_CONTROL_LEAST - 1) * typical:
                return
            _TWINS[source] = compiled_job(self.sys, self.params, self.python)
        twin = _TWINS[source]
        if isinstance(twin, str):
            return
        cost = compiled_cost(twin)
        if before <= PAYS * cost:
            return
        # numba's start, then the user's kernels: steps runs as Python can make first
        steps = [(seconds, make) for seconds, done, make in NUMBA_START if not done()]
        if not twin.is_compiled():
            steps += usercode.kernels_to_compile(twin.plan.kernels)
        if cost - sum(seconds for seconds, _ in steps) > PYTHON_CONTROL_SLOWER * typical:
            return  # (the compile never fits in a call: the steps would be for nothing)
        if not steps:
            # (this diagram's, its values)
            candidate = compiled_job(self.sys, self.params, self.python)
            if isinstance(candidate, str):
                return
            _TWINS[source] = candidate
            # (a diagram built anew whose functions read other values than the twin's has
            # kernels of its own, not counted yet: made as steps by the runs to come)
            if candidate.is_compiled() or not usercode.kernels_to_compile(
                    candidate.plan.kernels):
                self.compiled, self.decided = candidate, True
            return
        # each run as Python makes the steps that fit in its room: a call that made them and
        # compiled too would be slower (the continuous cruise cell: runs of 0.3 s, a compile
        # of 1.1-1.3 s)
        if max(seconds for seconds, _ in steps) > room:
            return  # (a step that never fits in a call: the others would be for nothing)
        for seconds, make in steps:
            if seconds > room - self.spent:
                break
            began = now()
            try:
                make()
            except Exception as error:  # noqa: BLE001 - numba's: no more steps here
                _TWINS[source] = f"numba could not compile a function ({store.numba_said(error)})"
                return
            self.spent += now() - began  # (what it took: an estimate errs)

    @property
    def mode(self) -> str:
        """How the run goes on: ``"compiled"`` (a compiled job checked in this process) or
        ``"python"``."""
        return "compiled" if self.compiled is not None and not self.to_check else "python"

    @property
    def to_check(self) -> bool:
        """Whether the next piece compares the compiled job with Python (:meth:`check`)."""
        return self.compiled is not None and checked_as(self.compiled,
                                                        self.params) not in CHECKED

    @property
    def job(self) -> Job:
        """The job running now."""
        return self.compiled or self.python

    def decide(self, elapsed: float, done: float) -> Job | None:
        """After a piece as Python: the compiled job if compiling now pays (the next piece
        checks it), else None (and no more asking). ``elapsed`` seconds so far, ``done``
        the fraction done."""
        last, self.last = self.last, (elapsed, done)
        if self.decided or elapsed < PIECE_SECONDS and done < 1.0 or last is None:
            return None
        self.decided = True
        if done >= 1.0:
            return None
        # (at the faster pace, the run's so far or its last piece's: the first pieces carry
        # one-time costs; 0.13% of a 3-s run in 0.14 s foretold 104 s, and a vain compile)
        rest = (1.0 - done) * min(elapsed / max(done, 1e-9),
                                  (elapsed - last[0]) / max(done - last[1], 1e-9))
        before = PYTHON_SECONDS.get(self.python.source, 0.0)
        # what compiling can save: this run's rest, and as much again for the runs to come
        # when earlier ones of the same module took that long (a sunk cost that predicts)
        saved = rest + before
        # and what this call can spend on it and stay no slower than python-control's run
        # (about PYTHON_CONTROL_SLOWER times the run as Python), its steps made before
        room = PYTHON_CONTROL_SLOWER * (elapsed + rest) - elapsed - self.spent
        if saved <= PAYS * NUMBA_START_SECONDS or room <= LOAD_SECONDS:
            return None  # (not even worth numba's start, or no time for it)
        candidate = compiled_job(self.sys, self.params, self.python)
        if isinstance(candidate, str):
            return None
        cost = compiled_cost(candidate)
        if saved <= PAYS * cost or cost > room:
            return None
        _TWINS[self.python.source] = candidate
        self.compiled = candidate  # (compared with Python on the next piece)
        return candidate

    def piece(self, run, budget, check_budget=None) -> None:
        """One piece of ``run`` (a driver's, as :meth:`check` takes it) on the job running
        now, or its check when :attr:`to_check` (at most ``check_budget`` long). A compiled
        piece that fails or stops is run again as Python from the same start, and so is the
        rest of the run: Python's error is raised if there is one, else Python's numbers
        stand (compiled code and Python part ways there, and Python is the meaning)."""
        if self.to_check:
            job, self.compiled = self.compiled, None
            self.check(job, run, min(budget, check_budget or budget))
            return
        if not self.job.compiled:
            run.piece(self.job, budget)
            return
        start = run.snapshot()
        try:
            run.piece(self.job, budget)
            if not run.stopped():
                return
            self.compiled = None
        except NotCompiled as why:  # numba's compile failed: the run is Python's
            self.python_from_now(str(why))
        except Exception:  # noqa: BLE001 - the piece run as Python says what it is
            self.compiled = None
        run.restore(start)
        run.piece(self.python, budget)

    def check(self, job, run, budget) -> None:
        """The next piece of ``run`` as Python, then on the compiled ``job`` from the same
        start: compiled from then on when the two agree to the bit (what the piece wrote,
        and all the run carries), else Python's piece stands and the run goes on as Python,
        saying why. A piece where Python stops is left as Python ran it: the driver says why.
        ``run``: ``snapshot()``, ``restore(saved)``, ``piece(job, budget)``, ``position``
        (results written) and their ``times``, ``written(n0, n1)`` (copies of results
        ``n0:n1``), ``put_back``, ``where(job, n0, n1, mine, theirs)`` (where results part,
        in words), ``stopped()``, ``handed_back()`` (a compiled piece asked for Python)."""
        start, n0 = run.snapshot(), run.position
        run.piece(self.python, budget)
        if run.stopped():
            return
        python, n1 = run.snapshot(), run.position
        written = run.written(n0, n1)
        run.restore(start)
        try:
            run.piece(job, budget)
        except Exception as error:  # noqa: BLE001 - the run goes on as Python
            verdict = str(error) if isinstance(error, NotCompiled) else (
                f"its compiled module failed ({type(error).__name__}: {error})")
        else:
            mine = run.written(n0, n1)
            if run.handed_back():
                verdict = None
            elif run.position == n1 and all(same_numbers(a, b) for a, b in zip(
                    (*run.snapshot(), *mine), (*python, *written), strict=True)):
                self.compiled = job
                CHECKED.add(checked_as(job, self.params))
                return
            else:
                verdict = (f"its compiled numbers differ from Python's "
                           f"{run.where(job, n0, n1, mine, written)}")
        run.restore(python)
        run.put_back(written, n0, n1)
        if verdict is not None:
            self.differs(job, verdict)

    def finished(self, seconds: float) -> None:
        """A run that took ``seconds`` ended: counted for its module when it ran as Python
        by the rule (``compile=None``)."""
        if self.mode == "python" and self.asked is None:
            source = self.python.source
            PYTHON_SECONDS[source] = PYTHON_SECONDS.get(source, 0.0) + seconds
            PYTHON_POINTS[source] = PYTHON_POINTS.get(source, 0) + self.points

    def differs(self, job, why: str) -> None:
        """The compiled module cannot be trusted: Python from now on, with a warning."""
        DIFFERS[job.source] = why
        self.python_from_now(why)

    def python_from_now(self, why: str) -> None:
        """The run goes on as Python, and says why."""
        self.compiled = None
        self.decided = True
        warn_caller(f"{self.sys.name!r} runs as Python: {why} (controlkit.explain lists "
                    f"every block's tier)")

