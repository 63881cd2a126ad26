"""Many runs of a scenario or of your own function: grids, seeded draws, any executor.

:func:`sweep` calls a function of named parameters once per run and gathers
what each run returns into a :class:`pandas.DataFrame`, one row per run. The
runs come from a grid (every combination of named values) or from seeded
random draws (named distributions), optionally crossed with a list of cases.
They run on any :class:`concurrent.futures.Executor`: local processes on all
cores by default, threads, in this process, or a Dask cluster through
``distributed.Client.get_executor()`` - the same call on a laptop or a
cluster, and the same rows whichever runs it (each run's parameters and seed
are fixed before any run starts; rows are sorted by run index).

A run that fails is a row with its ``error``, whatever the function does
(raises, calls ``sys.exit``, kills its worker process, takes longer than
``timeout``, returns something that is not a dict of plain values); the sweep
goes on. With ``store=``, each finished run is appended to ``runs.jsonl`` in
that folder as it completes, so an interrupted sweep keeps what it finished
and ``resume=True`` runs only what is missing; the store is only ever appended
to, read back row by row with checks, and locked against a second writer
(see :mod:`controlkit._store`). Every argument is checked before the store or
any process is created.

:func:`spacecraft_study` is the built-in robustness study of the spacecraft
paper: how often each case keeps the 0.05 deg requirement over draws of the
inertia error, the amplitude of ``H0`` and the initial attitude.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import inspect
import itertools
import json
import math
import multiprocessing
import os
import pickle
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._store import RUNS_FILE, SPEC_FILE, RunStore, StoreWarning, plain, same_value
from ._workers import ProcessRunner, ThreadRunner, call_in_child
from .outputs.export import json_default

__all__ = ["EXECUTORS", "MAX_RUNS", "MAX_THREADS", "RESERVED", "RUNS_FILE",
           "SCHEDULER_TIMEOUT_S", "SPEC_FILE", "Run", "StoreWarning", "check_folder",
           "draw_points", "grid_points", "max_processes", "plan", "process_context", "sweep",
           "wilson_interval"]

#: Executors by name (``executor=`` of :func:`sweep`, ``--executor`` of the CLI).
EXECUTORS = ("processes", "threads", "serial", "dask")
#: Columns every row has, that parameters and metrics cannot be named.
RESERVED = ("run", "case", "seed", "error", "wall_time_s")
#: Most runs in one sweep: its plan and rows stay within memory (about 1 kB a run).
MAX_RUNS = 1_000_000
#: Most threads of ``executor="threads"``.
MAX_THREADS = 1024
#: How long a Dask scheduler may take to answer before the sweep is refused, s.
SCHEDULER_TIMEOUT_S = 5.0


def max_processes() -> int:
    """Most worker processes of one sweep on this machine: 4 per core, at least 8.

    Examples
    --------
    >>> max_processes() >= 8
    True
    """
    return max(8, 4 * (os.cpu_count() or 1))


@dataclass(frozen=True)
class Run:
    """One run of a sweep: its index, case, seed and parameters.

    Attributes
    ----------
    index : int
        Position in the sweep (rows are sorted by it).
    case : str or None
        The case passed as ``case=`` to the function, if the sweep has cases.
    seed : int or None
        The run's own seed (random draws only), derived from the sweep's seed.
    params : dict
        Keyword arguments of the function.

    Examples
    --------
    >>> Run(0, None, None, {"F": 0.5}).kwargs()
    {'F': 0.5}
    """

    index: int
    case: str | None
    seed: int | None
    params: dict

    def kwargs(self) -> dict:
        """The function's keyword arguments: the parameters, and ``case`` if any."""
        return self.params if self.case is None else {"case": self.case, **self.params}


def _grid_values(grid: dict) -> list[list]:
    if not isinstance(grid, dict) or not grid:
        raise ValueError(f"grid must be a non-empty dict of name -> values, got {grid!r}")
    values = []
    for name, vals in grid.items():
        if isinstance(vals, str | bytes):
            raise ValueError(f"grid[{name!r}] = {vals!r} is one text, not a list of values; "
                             f"write [{vals!r}]")
        if isinstance(vals, set | frozenset | dict):
            raise ValueError(f"grid[{name!r}] is a {type(vals).__name__}, which has no fixed "
                             "order (the runs' order would change from one session to the "
                             "next); give a list")
        vals = list(np.atleast_1d(vals)) if not isinstance(vals, list | tuple) else list(vals)
        if not vals:
            raise ValueError(f"grid[{name!r}] has no values")
        values.append([v.item() if isinstance(v, np.generic) else v for v in vals])
    return values


def grid_points(grid: dict) -> list[dict]:
    """Every combination of the named values, the last name varying fastest.

    Examples
    --------
    >>> grid_points({"a": [1, 2], "b": ["x", "y"]})
    [{'a': 1, 'b': 'x'}, {'a': 1, 'b': 'y'}, {'a': 2, 'b': 'x'}, {'a': 2, 'b': 'y'}]
    """
    values = _grid_values(grid)
    _check_count(math.prod(len(v) for v in values), "grid points")
    return [dict(zip(grid, combo, strict=True)) for combo in itertools.product(*values)]


def _check_count(count: int, what: str) -> None:
    if count > MAX_RUNS:
        raise ValueError(f"{count:,} {what} is more than one sweep holds (MAX_RUNS = "
                         f"{MAX_RUNS:,}, about 1 kB of memory each); split it into several "
                         "sweeps, e.g. over parts of the grid")


def _check_draw(name, spec) -> None:
    if callable(spec) or (isinstance(spec, list) and spec):
        return
    if isinstance(spec, tuple) and len(spec) == 2:
        try:
            low, high = (float(v) for v in spec)
        except (TypeError, ValueError):
            low = high = math.nan
        if math.isfinite(low) and math.isfinite(high) and low <= high:
            return
        raise ValueError(f"draws[{name!r}] = {spec!r}: a (low, high) pair needs finite "
                         "low <= high")
    raise ValueError(f"draws[{name!r}] must be a (low, high) tuple (uniform), a non-empty "
                     f"list (choice) or a callable rng -> value, got {spec!r}")


def _draw_one(name, spec, rng):
    if callable(spec):
        value = spec(rng)
    elif isinstance(spec, tuple) and len(spec) == 2:
        low, high = (float(v) for v in spec)
        if not (math.isfinite(low) and math.isfinite(high) and low <= high):
            raise ValueError(f"draws[{name!r}] = {spec!r}: a (low, high) pair needs finite "
                             "low <= high")
        value = rng.uniform(low, high)
    elif isinstance(spec, list) and spec:
        value = spec[int(rng.integers(len(spec)))]
    else:
        raise ValueError(f"draws[{name!r}] must be a (low, high) tuple (uniform), a non-empty "
                         f"list (choice) or a callable rng -> value, got {spec!r}")
    return value.item() if isinstance(value, np.generic) else value


def draw_points(draws: dict, samples: int, seed: int) -> list[tuple[int, dict]]:
    """``samples`` seeded draws of named distributions, as ``(run seed, parameters)``.

    Each draw has its own generator, spawned from ``seed`` by
    :class:`numpy.random.SeedSequence`, and draws the names in the order given;
    so draw ``i`` is the same whatever ``samples`` is and wherever it runs.

    Parameters
    ----------
    draws : dict
        Name to distribution: ``(low, high)`` for uniform, a list to choose from, or a
        callable ``rng -> value`` (e.g. ``lambda rng: rng.normal()``).
    samples : int
        Number of draws, >= 1.
    seed : int
        The sweep's seed, >= 0.

    Examples
    --------
    >>> [round(p["x"], 3) for _, p in draw_points({"x": (0.0, 1.0)}, 3, seed=1)]
    [0.699, 0.476, 0.233]
    >>> draw_points({"x": (0.0, 1.0)}, 5, seed=1)[2] == draw_points({"x": (0, 1)}, 3, 1)[2]
    True
    """
    if not isinstance(draws, dict) or not draws:
        raise ValueError(f"draws must be a non-empty dict of name -> distribution, "
                         f"got {draws!r}")
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 1:
        raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
    points = []
    for child in np.random.SeedSequence(int(seed)).spawn(int(samples)):
        run_seed = int(child.generate_state(1, dtype=np.uint64)[0] >> np.uint64(1))
        rng = np.random.default_rng(child)
        points.append((run_seed, {name: _draw_one(name, spec, rng)
                                  for name, spec in draws.items()}))
    return points


def _check_seed(seed) -> None:
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise ValueError(f"seed must be an integer >= 0, got {seed!r}")


def plan(*, grid=None, draws=None, samples=None, seed=None, cases=None,
         fixed=None) -> list[Run]:
    """The runs of a sweep, in order: each point (grid, draw, or grid point crossed with
    every draw) for each case.

    Every argument is checked, and the number of runs counted (at most :data:`MAX_RUNS`),
    before any run is planned. ``seed`` (default 0) goes with ``draws``; a parameter is
    named once (in ``grid``, ``draws`` or ``fixed``) and not as one of :data:`RESERVED`.

    Examples
    --------
    >>> [(r.index, r.case, r.params) for r in plan(grid={"F": [1, 2]}, cases=["a", "b"])]
    [(0, 'a', {'F': 1}), (1, 'b', {'F': 1}), (2, 'a', {'F': 2}), (3, 'b', {'F': 2})]
    """
    if grid is None and draws is None:
        raise ValueError("give grid= (named values), draws= (named distributions with "
                         "samples=), or both (each grid point crossed with the same draws)")
    if draws is None and samples is not None:
        raise ValueError("samples= goes with draws=, not with grid= alone")
    if draws is None and seed is not None:
        raise ValueError("seed= goes with draws= (a grid is not random)")
    if draws is not None and samples is None:
        raise ValueError("draws= needs samples= (how many draws)")
    seed = 0 if seed is None else seed
    grid_values = _grid_values(grid) if grid is not None else []
    if draws is not None:
        if not isinstance(draws, dict) or not draws:
            raise ValueError(f"draws must be a non-empty dict of name -> distribution, "
                             f"got {draws!r}")
        for name, spec in draws.items():
            _check_draw(name, spec)
        if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or \
                samples < 1:
            raise ValueError(f"samples must be an integer >= 1, got {samples!r}")
        _check_seed(seed)
    if fixed is not None and not isinstance(fixed, dict):
        raise ValueError(f"fixed must be a dict of name -> value, got {fixed!r}")
    fixed = dict(fixed or {})
    named = {"grid=": list(grid or {}), "draws=": list(draws or {}), "fixed=": list(fixed)}
    seen = {}
    for where, names in named.items():
        for name in names:
            if not isinstance(name, str) or not name:
                raise ValueError(f"{where} names must be non-empty texts, got {name!r}")
            if name in RESERVED or name == "trajectory":
                raise ValueError(f"{where} names {name!r}, a column of the sweep's own "
                                 f"({', '.join(RESERVED)}, trajectory)"
                                 + ("; pass cases with cases=" if name == "case" else ""))
            if name in seen:
                raise ValueError(f"{name!r} is both in {seen[name]} and in {where}; "
                                 "name each parameter once")
            seen[name] = where
    if cases is None:
        cases = [None]
    else:
        if isinstance(cases, str | bytes | set | frozenset) or not isinstance(cases, Iterable):
            raise ValueError(f"cases must be a list of case names (in order), got {cases!r}"
                             + (f" (write [{cases!r}] for one case)"
                                if isinstance(cases, str) else ""))
        cases = list(cases)
        if not cases:
            raise ValueError("cases must not be empty (omit it for a sweep without cases)")
        bad = [c for c in cases if not isinstance(c, str) or not c]
        if bad:
            raise ValueError(f"cases must be non-empty texts, got {bad[0]!r}")
        repeated = sorted({c for c in cases if cases.count(c) > 1})
        if repeated:
            raise ValueError(f"cases {repeated} are given more than once")
    _check_count(math.prod(len(v) for v in grid_values) * (samples if draws else 1)
                 * len(cases), "runs")
    grid_part = grid_points(grid) if grid is not None else [{}]
    draw_part = draw_points(draws, samples, seed) if draws is not None else [(None, {})]
    runs, index = [], 0
    for g in grid_part:
        for run_seed, d in draw_part:
            params = {**fixed, **g, **d}
            for case in cases:
                runs.append(Run(index, case, run_seed, params))
                index += 1
    return runs


def _describe(exc: BaseException) -> str:
    """``"Type: message"`` of an exception, even one whose message cannot be made."""
    name = type(exc).__name__
    if isinstance(exc, SystemExit):
        return f"SystemExit: the function called sys.exit({exc.code!r})"
    try:
        message = str(exc)
    except Exception as inner:  # its __str__ fails: say so rather than lose the run
        message = f"(its message cannot be shown: {type(inner).__name__})"
    if isinstance(exc, KeyboardInterrupt) and not message:
        message = "raised by the function"
    return f"{name}: {message}" if message else name


def _plain_metrics(result: dict) -> dict:
    """The metrics as they read back from JSON; TypeError naming one that cannot be."""
    try:
        return plain(result)
    except (TypeError, ValueError, RecursionError):
        for name, value in result.items():
            try:
                plain(value)
            except (TypeError, ValueError, RecursionError) as exc:
                raise TypeError(f"metric {name!r} = {value!r:.60} is a "
                                f"{type(value).__name__}, not a number, text, boolean or a "
                                f"list or dict of them ({exc})") from None
        raise


def _metrics(result, run: Run) -> tuple[dict, dict | None]:
    """Check what the function returned: ``(metrics, trajectory)`` or an exception."""
    if not isinstance(result, dict):
        raise TypeError(f"the swept function must return a dict of metrics, got "
                        f"{type(result).__name__}")
    bad = [k for k in result if not isinstance(k, str)]
    if bad:
        raise TypeError(f"metric names must be texts, got {bad[0]!r}")
    result = dict(result)
    trajectory = result.pop("trajectory", None)
    if trajectory is not None:
        if not isinstance(trajectory, dict) or \
                any(not isinstance(k, str) for k in trajectory):
            raise TypeError('"trajectory" must be a dict of name -> array, got '
                            f"{type(trajectory).__name__}")
        arrays = {k: np.asarray(v) for k, v in trajectory.items()}
        odd = [k for k, a in arrays.items() if a.dtype.kind not in "biuf"]
        if odd:
            raise TypeError(f'"trajectory" entry {odd[0]!r} is not an array of numbers')
        trajectory = {k: a.tolist() for k, a in arrays.items()}
    clash = sorted(k for k in result if k in RESERVED and k != "case")
    if clash:
        raise ValueError(f"the function returned {clash}: names of the sweep's own columns "
                         f"({', '.join(RESERVED)}); rename these metrics")
    own = dict(run.params) if run.case is None else {"case": run.case, **run.params}
    for name in [k for k in result if k in own or k == "case"]:
        if name not in own:
            raise ValueError("the function returned 'case', but this sweep has no cases; "
                             "rename this metric")
        if not same_value(result[name], own[name]):
            raise ValueError(f"the function returned {name}={result[name]!r:.60}, but this "
                             f"run's {name} is {own[name]!r:.60}; a metric cannot take the "
                             "name of a parameter (rename it)")
        del result[name]  # the same value as the row has already
    return _plain_metrics(result), trajectory


def _row(run: Run, metrics: dict, error: str, wall_time_s: float, trajectory=None) -> dict:
    row = {"run": run.index, "case": run.case, "seed": run.seed, **run.params, **metrics,
           "error": error, "wall_time_s": round(wall_time_s, 4)}
    if trajectory is not None:
        row["trajectory"] = trajectory
    return row


def _failed_row(run: Run, error: str, wall_time_s: float) -> dict:
    """The row of a run that ended with ``error`` (no metrics)."""
    return _row(run, {}, error, wall_time_s)


def _call(function, run: Run) -> dict:
    """Make one run; whatever the function raises (or returns wrong) is the row's error.

    A KeyboardInterrupt is not caught: in this process it stops the sweep.
    """
    started = time.perf_counter()
    try:
        metrics, trajectory = _metrics(function(**run.kwargs()), run)
        error = ""
    except (Exception, SystemExit) as exc:  # a failing run is a row, not the end
        metrics, trajectory, error = {}, None, _describe(exc)
    return _row(run, metrics, error, time.perf_counter() - started, trajectory)


def _call_elsewhere(function, run: Run) -> dict:
    """:func:`_call` in a worker of an executor: there even a KeyboardInterrupt raised by
    the function is the run's error (it would otherwise end the worker)."""
    started = time.perf_counter()
    try:
        return _call(function, run)
    except BaseException as exc:  # noqa: B036 - a row whatever happens
        return _failed_row(run, _describe(exc), time.perf_counter() - started)


def _spec_key(function, runs, *, stored: bool) -> str:
    """What identifies the sweep: a hash of the function's name and of every run.

    With ``stored`` every parameter must also be storable as JSON (ValueError if not).
    """
    name = f"{getattr(function, '__module__', '')}.{getattr(function, '__qualname__', '')}"
    digest = hashlib.sha256()
    digest.update(b"[" + json.dumps(name).encode())
    for r in runs:
        digest.update(b", " + json.dumps([r.index, r.case, r.seed, r.params], sort_keys=True,
                                         default=str).encode())
    digest.update(b"]")
    if stored:
        checked = set()
        for r in runs:
            if id(r.params) in checked:
                continue
            checked.add(id(r.params))
            for param, value in r.params.items():
                try:
                    json.dumps(value, default=json_default)
                except (TypeError, ValueError) as exc:
                    raise ValueError(f"parameter {param} = {value!r:.60} of run {r.index} "
                                     f"cannot be stored as JSON in store= ({exc}); use "
                                     "numbers, texts or lists of them, or omit store=") from None
    return digest.hexdigest()


def _check_signature(function, names, has_cases: bool) -> None:
    """Refuse parameters the function does not take, and ones it needs that no one gives."""
    try:
        signature = inspect.signature(function)
    except (TypeError, ValueError):  # no signature to read (some builtins): the runs tell
        return
    title = getattr(function, "__qualname__", None) or repr(function)
    kinds = (inspect.Parameter.POSITIONAL_OR_KEYWORD, inspect.Parameter.KEYWORD_ONLY)
    takes = [p.name for p in signature.parameters.values() if p.kind in kinds]
    given = set(names) | ({"case"} if has_cases else set())
    if not any(p.kind is inspect.Parameter.VAR_KEYWORD
               for p in signature.parameters.values()):
        unknown = sorted(given - set(takes))
        positional = [p.name for p in signature.parameters.values()
                      if p.kind is inspect.Parameter.POSITIONAL_ONLY and p.name in unknown]
        if positional:
            raise ValueError(f"{title}() takes {positional} by position only; a sweep passes "
                             "every parameter by name (def f(x) rather than def f(x, /))")
        if unknown:
            raise ValueError(f"{title}() takes no parameter {unknown} (it takes {takes})"
                             + ("; cases= passes case= to the function" if "case" in unknown
                                else ""))
    missing = [p.name for p in signature.parameters.values()
               if p.default is p.empty and p.name not in given
               and p.kind not in (inspect.Parameter.VAR_POSITIONAL,
                                  inspect.Parameter.VAR_KEYWORD)]
    if missing:
        raise ValueError(f"{title}() needs {missing}, which no grid=, draws= or fixed= gives"
                         + ("; cases= gives case=" if "case" in missing else ""))


def check_folder(path, name: str = "store") -> Path:
    """A folder argument, refused before anything is written: empty, a file, or under a
    place where nothing can be written.

    Examples
    --------
    >>> check_folder("results/sweep").name
    'sweep'
    >>> check_folder("", "--out")
    Traceback (most recent call last):
    ...
    ValueError: --out must name a folder, got ''
    """
    if not isinstance(path, str | os.PathLike):
        raise ValueError(f"{name} must be a folder path, got {path!r}")
    if not str(os.fspath(path)).strip():
        raise ValueError(f"{name} must name a folder, got {path!r}")
    folder = Path(path).expanduser()  # "~/results" means the home folder, as in a shell
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"{name} {folder} is a file, not a folder")
    existing = folder.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise ValueError(f"{name} {folder} cannot be made: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ValueError(f"cannot write to {name} {folder}: {existing} is not writable")
    return folder


def process_context():
    """The start method of worker processes: ``forkserver`` where there is one, else ``spawn``.

    ``fork`` would copy a parent that may already hold numba's compiler state and
    threads (not fork-safe); a fresh interpreter imports controlkit and loads the
    loops from numba's disk cache instead.

    Examples
    --------
    >>> process_context().get_start_method() in ("forkserver", "spawn")
    True
    """
    methods = multiprocessing.get_all_start_methods()
    return multiprocessing.get_context("forkserver" if "forkserver" in methods else "spawn")


def _check_executor(executor, workers, scheduler, timeout) -> str:
    """The executor's kind (a name of :data:`EXECUTORS`, or ``"given"``), all checked."""
    if isinstance(executor, cf.Executor):
        kind = "given"
    elif executor is None:
        kind = "processes"
    elif isinstance(executor, str) and executor in EXECUTORS:
        kind = executor
    else:
        raise ValueError(f"executor must be one of {EXECUTORS} or a concurrent.futures."
                         f"Executor, got {executor!r}")
    if workers is not None:
        if isinstance(workers, bool) or not isinstance(workers, int | np.integer) or \
                workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        if kind in ("given", "serial"):
            raise ValueError(f"workers= does not apply to executor={executor!r} ("
                             + ("it runs one run at a time" if kind == "serial" else
                                "the executor you pass has its own workers") + "); omit it")
        if kind == "dask" and scheduler is not None:
            raise ValueError("workers= does not apply with scheduler= (the cluster's workers "
                             "are started with `dask worker`); omit it")
        most = MAX_THREADS if kind == "threads" else max_processes()
        if workers > most:
            raise ValueError(f"workers must be <= {most} for executor={kind!r} on this "
                             f"machine ({os.cpu_count()} cores), got {workers}")
    if scheduler is not None:
        if kind != "dask":
            raise ValueError(f"scheduler= goes with executor='dask', not {executor!r}")
        if not isinstance(scheduler, str) or not scheduler.strip():
            raise ValueError(f"scheduler must be the address of a running Dask scheduler, "
                             f"e.g. 'tcp://10.0.0.5:8786', got {scheduler!r} (omit it for a "
                             "local cluster)")
    if kind == "dask":
        try:
            import distributed  # noqa: F401
        except ImportError:
            raise ValueError('executor="dask" needs Dask: pip install "controlkit[cluster]"'
                             ) from None
    if timeout is not None and (isinstance(timeout, bool) or not isinstance(
            timeout, int | float | np.integer | np.floating) or not math.isfinite(timeout)
            or timeout <= 0):
        raise ValueError(f"timeout must be a finite number of seconds > 0, got {timeout!r}")
    return kind


def _check_sendable(function, kind, executor, timeout) -> None:
    """Refuse a function that the executor would have to send to another process but
    cannot (a lambda, a closure, a function of an interactive session)."""
    given_processes = kind == "given" and isinstance(executor, cf.ProcessPoolExecutor)
    if kind != "processes" and timeout is None and not given_processes:
        return  # threads and this process take any callable; Dask uses cloudpickle
    why = ("timeout= makes each run in another process (a thread cannot be stopped)"
           if timeout is not None and kind != "processes" else
           f"executor={kind if kind != 'given' else executor!r} makes the runs in other "
           "processes")
    main = sys.modules.get("__main__")
    if getattr(function, "__module__", None) == "__main__" and \
            not getattr(main, "__file__", None):
        raise ValueError(f"{why}, which cannot import {function!r} from an interactive "
                         "session or notebook; define it in a module (a .py file) and "
                         "import it, or use executor='threads' or 'serial'"
                         + (" without timeout=" if timeout is not None else ""))
    try:
        pickle.dumps(function)
    except Exception as exc:
        raise ValueError(f"{why}, which needs a function importable by name (defined at the "
                         f"top of a module, not a lambda or a closure); {function!r} is "
                         f"not ({type(exc).__name__}: {exc}); use executor='threads' or "
                         "'serial'" + (" without timeout=" if timeout is not None else "")
                         ) from None


def _unreachable(scheduler: str, why: str) -> ValueError:
    return ValueError(f"scheduler {scheduler!r} {why}; start one with `dask scheduler`, check "
                      "the address, or omit scheduler= for a local cluster")


def _handshake(address: str) -> BaseException | None:
    """Open and close one Dask connection to ``address`` within SCHEDULER_TIMEOUT_S; the
    error, if any. (Dask's own connect waits for the peer's greeting without a limit, so a
    port that accepts and says nothing would hold it forever: the whole attempt is bounded
    here, in a thread of its own so that a running event loop, e.g. Jupyter's, is left
    alone.)"""
    import asyncio
    import threading

    from distributed.comm import connect

    outcome = {"error": TimeoutError(f"no answer within {SCHEDULER_TIMEOUT_S:g} s")}

    async def attempt():
        comm = await asyncio.wait_for(connect(address, timeout=SCHEDULER_TIMEOUT_S),
                                      SCHEDULER_TIMEOUT_S)
        comm.abort()

    def run():
        try:
            asyncio.run(attempt())
            outcome["error"] = None
        except BaseException as exc:  # noqa: B036 - reported to the caller
            outcome["error"] = exc

    thread = threading.Thread(target=run, daemon=True, name="controlkit-scheduler-check")
    thread.start()
    thread.join(SCHEDULER_TIMEOUT_S + 2)
    return outcome["error"]


def _connect(scheduler: str):
    """A Dask client of the scheduler, or a ValueError within about SCHEDULER_TIMEOUT_S.

    A TCP address is tried first with a plain connection (a refused one fails at once;
    Dask's client would keep trying until its timeout), then with one Dask handshake.
    """
    import socket
    import urllib.parse

    from distributed import Client

    address = scheduler if "://" in scheduler else f"tcp://{scheduler}"
    parts = urllib.parse.urlsplit(address)
    try:
        port = parts.port
    except ValueError as exc:
        raise ValueError(f"scheduler {scheduler!r} is not an address ({exc}); e.g. "
                         "'tcp://10.0.0.5:8786'") from None
    if parts.scheme == "tcp" and not (parts.hostname and port):
        raise ValueError(f"scheduler {scheduler!r} is not an address: it needs a host and a "
                         "port, e.g. 'tcp://10.0.0.5:8786'")
    if parts.scheme == "tcp":
        try:
            socket.create_connection((parts.hostname, port), SCHEDULER_TIMEOUT_S).close()
        except OSError as exc:
            raise _unreachable(scheduler, f"cannot be reached ({type(exc).__name__}: {exc})"
                               ) from None
        error = _handshake(address)
        if isinstance(error, TimeoutError):  # asyncio's too, since Python 3.11
            raise _unreachable(scheduler, f"did not answer within {SCHEDULER_TIMEOUT_S:g} s "
                                          "(is it a Dask scheduler?)")
        if error is not None:
            raise _unreachable(scheduler, f"did not answer as a Dask scheduler "
                                          f"({type(error).__name__}: {error})")
    try:
        return Client(scheduler, timeout=SCHEDULER_TIMEOUT_S)
    except Exception as exc:  # OSError, TimeoutError, ValueError, ... all mean "not there"
        why = (f"did not answer within {SCHEDULER_TIMEOUT_S:g} s" if isinstance(
            exc, TimeoutError | OSError) else "cannot be used")
        raise _unreachable(scheduler, f"{why} ({type(exc).__name__}: {exc})") from None


def _on_executor(pool, function, todo, timeout, record, fail):
    """The runs on a concurrent.futures executor (Dask's, or one the user passed)."""
    by_future = {}
    try:
        for run in todo:
            if timeout is None:
                future = pool.submit(_call_elsewhere, function, run)
            else:
                future = pool.submit(call_in_child, _call_elsewhere, _failed_row, function,
                                     run, timeout)
            by_future[future] = run
        lost = []
        for future in cf.as_completed(by_future):
            run = by_future[future]
            try:
                row = future.result()
            except KeyboardInterrupt:
                raise
            except BaseException as exc:  # noqa: B036 - the executor failed this run
                if type(exc).__name__ == "KilledWorker":  # it killed every Dask worker tried
                    row = fail(run, f"WorkerDied: {exc}", 0.0)
                else:
                    lost.append((run, exc))
                    continue
            record(row)
        if lost:
            run, exc = lost[0]
            hint = ("; a worker process died, and this executor cannot tell which run killed "
                    "it: executor='processes' makes that run a failed row and goes on"
                    if isinstance(exc, cf.BrokenExecutor) else "")
            raise RuntimeError(f"{len(lost)} run(s) were lost by the executor (run {run.index}: "
                               f"{type(exc).__name__}: {exc}); the others are kept (in the "
                               f"store, if any: resume to make the lost ones){hint}")
    finally:
        for future in by_future:
            future.cancel()


def _progress_bar(total, enabled):
    try:
        from tqdm import tqdm
    except ImportError:  # tqdm is optional: a plain counter then
        tqdm = None
    if tqdm is not None:
        return tqdm(total=total, disable=not enabled, file=sys.stderr, unit="run",
                    dynamic_ncols=True)

    class _Plain:
        def __init__(self):
            self.n = 0

        def update(self, k=1):
            self.n += k
            if enabled:
                sys.stderr.write(f"\r  {self.n}/{total} runs")
                sys.stderr.flush()

        def close(self):
            if enabled:
                sys.stderr.write("\n")

    return _Plain()


def sweep(function: Callable[..., dict], *, grid: dict | None = None,
          draws: dict | None = None, samples: int | None = None, seed: int | None = None,
          cases: Iterable | None = None, fixed: dict | None = None, executor=None,
          workers: int | None = None, scheduler: str | None = None, store=None,
          resume: bool = False, timeout: float | None = None,
          warmup: Callable[[], object] | None = None, progress: bool = True):
    """Run ``function`` over a grid or seeded draws of named parameters; one row per run.

    Row ``i`` holds run ``i``'s parameters ``p_i`` and metrics ``function(**p_i)``; the
    runs are fixed before any starts (:func:`plan`), so the table is the same whatever
    executor makes them and however often the sweep is interrupted and resumed.

    Parameters
    ----------
    function : callable
        ``function(**params) -> dict`` of metrics (numbers, texts, booleans, or lists and
        dicts of them), with ``case=`` when the sweep has ``cases``. An entry
        ``"trajectory"`` (a dict of arrays, e.g. decimated time and error) is kept per run
        in ``result.attrs["trajectories"]``, not in the table. A metric may not be named
        as one of :data:`RESERVED`, nor as a parameter unless it has the parameter's
        value. For process executors, and with ``timeout``, it must be importable (a
        module-level function, not a lambda).
    grid : dict, optional
        Name to a list of values: every combination is run (with ``draws`` too: each
        combination with every draw).
    draws : dict, optional
        Name to a distribution (see :func:`draw_points`); with ``samples`` and ``seed``.
    samples : int, optional
        Number of random draws.
    seed : int, optional
        Seed of the draws (default 0): the same seed gives the same rows.
    cases : list of str, optional
        Each point runs once per case (the same parameters for every case).
    fixed : dict, optional
        Parameters passed to every run (e.g. ``horizon``), recorded in each row.
    executor : {"processes", "threads", "serial", "dask"} or concurrent.futures.Executor
        Where the runs go. Default: processes on all cores (or ``workers``). ``"dask"``
        starts a local Dask cluster, or uses the scheduler at ``scheduler``; any
        executor object is used as given (e.g. ``client.get_executor()``) and not closed.
    workers : int, optional
        Number of workers for the executors made here (default: the CPU count; at most
        :func:`max_processes` processes or :data:`MAX_THREADS` threads).
    scheduler : str, optional
        Address of a running Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``; refused if
        it does not answer within :data:`SCHEDULER_TIMEOUT_S`.
    store : str or pathlib.Path, optional
        Folder where each finished run is appended (``runs.jsonl``) as it completes; it
        is locked while the sweep runs (see :mod:`controlkit._store`).
    resume : bool
        Complete the sweep already in ``store``, skipping its finished runs (a run that
        failed is finished: its row says why).
    timeout : float, optional
        Longest run, s: a run still going after it is a failed row (``TimeoutError``)
        and the sweep goes on. Only a process can be stopped, so with ``"serial"`` and
        ``"threads"`` the runs then go to worker processes (one, or ``workers``), and on
        Dask or a given executor each run goes to a child interpreter of the worker.
    warmup : callable, optional
        Called once here before the workers start (e.g. to compile and cache the
        simulation loops, so that workers load them from the disk cache).
    progress : bool
        Show a progress bar with an estimated time left (tqdm) on stderr.

    Returns
    -------
    pandas.DataFrame
        Columns ``run``, ``case``, ``seed``, the parameters, the metrics, ``error``
        (empty when the run succeeded) and ``wall_time_s``; sorted by ``run``. With a
        store, every value is as it reads back from the store (tuples as lists).

    Raises
    ------
    ValueError
        A bad argument, a store that belongs to another sweep or is in use (the holder
        is named), an unreachable scheduler: all before the store or any process is
        created.

    Examples
    --------
    >>> def gain_margin(F, Ts):
    ...     return {"stable": abs(1 - F * Ts) < 1}
    >>> table = sweep(gain_margin, grid={"F": [1.0, 30.0]}, fixed={"Ts": 0.1},
    ...               executor="serial", progress=False)
    >>> table[["F", "stable"]].values.tolist()
    [[1.0, True], [30.0, False]]
    """
    try:
        import pandas as pd
    except ImportError:
        raise ImportError('controlkit.sweep returns a pandas DataFrame: '
                          'pip install "controlkit[sweep]"') from None
    # --- every argument, before anything is created -------------------------------------
    if not callable(function):
        raise ValueError(f"function must be callable, got {function!r}")
    for name, value in (("resume", resume), ("progress", progress)):
        if not isinstance(value, bool | np.bool_):
            raise ValueError(f"{name} must be True or False, got {value!r}")
    if warmup is not None and not callable(warmup):
        raise ValueError(f"warmup must be callable, got {warmup!r}")
    kind = _check_executor(executor, workers, scheduler, timeout)
    if store is not None:
        store = check_folder(store, "store")
    elif resume:
        raise ValueError("resume=True needs store= (the folder of the sweep to complete)")
    runs = plan(grid=grid, draws=draws, samples=samples, seed=seed, cases=cases, fixed=fixed)
    _check_signature(function, runs[0].params, runs[0].case is not None)
    _check_sendable(function, kind, executor, timeout)
    key = _spec_key(function, runs, stored=store is not None)
    run_store = None
    if store is not None:
        run_store = RunStore(store, key, runs, resume=bool(resume))
        run_store.check()
    client = _connect(scheduler) if scheduler is not None else None
    # --- the runs -------------------------------------------------------------------------
    rows: dict[int, dict] = {}
    try:
        if run_store is not None:
            rows.update(run_store.open())
        todo = [r for r in runs if r.index not in rows]
        if todo:
            _make(function, todo, rows, run_store, kind, executor, workers, client, timeout,
                  warmup, len(runs), progress)
    finally:
        if run_store is not None:
            run_store.close()
        if client is not None:
            client.close()
    ordered = [rows[r.index] for r in runs]
    trajectories = {row["run"]: row.pop("trajectory") for row in ordered if "trajectory" in row}
    table = pd.DataFrame(ordered)
    if all(r.case is None for r in runs):
        table = table.drop(columns="case")
    if all(r.seed is None for r in runs):
        table = table.drop(columns="seed")
    table.attrs["trajectories"] = trajectories
    return table


def _make(function, todo, rows, run_store, kind, executor, workers, client, timeout, warmup,
          total, progress) -> None:
    """Make the runs of ``todo`` on the executor, each row recorded as it arrives."""
    bar = _progress_bar(total, progress)
    bar.update(total - len(todo))

    def record(row):
        if run_store is not None:
            try:
                line = run_store.line(row)
            except TypeError as exc:  # guard: metrics are plain, parameters were checked
                row = _row(todo_by_index[row["run"]], {}, f"TypeError: {exc}",
                           row["wall_time_s"])
                line = run_store.line(row)
            run_store.append(row, line)
            row = json.loads(line)  # the row as a resume reads it back
        rows[row["run"]] = row
        bar.update(1)

    todo_by_index = {r.index: r for r in todo}
    n = workers or os.cpu_count() or 1
    cluster = None
    try:
        if warmup is not None:
            warmup()
        if kind == "serial" and timeout is None:
            for run in todo:
                record(_call(function, run))
        elif kind == "threads" and timeout is None:
            ThreadRunner(_call, function, n).map(todo, record)
        elif kind in ("processes", "threads", "serial"):
            ProcessRunner(_call_elsewhere, _failed_row, function, 1 if kind == "serial" else n,
                          process_context(), timeout).map(todo, record)
        else:
            pool = executor
            if kind == "dask":
                if client is None:
                    from distributed import Client, LocalCluster

                    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
                    client = Client(cluster)
                pool = client.get_executor()
            _on_executor(pool, function, todo, timeout, record, _failed_row)
    finally:
        bar.close()
        if cluster is not None:
            client.close()
            cluster.close()


def wilson_interval(successes: int, trials: int, z: float = 1.959964) -> tuple[float, float]:
    """Wilson score interval of a success rate (95 % by default).

    Better than the normal approximation at rates near 0 or 1 and for small samples
    (Wilson 1927; Brown, Cai & DasGupta 2001).

    Examples
    --------
    >>> [round(v, 3) for v in wilson_interval(45, 50)]
    [0.786, 0.957]
    """
    if trials <= 0:
        return (math.nan, math.nan)
    p = successes / trials
    denominator = 1 + z * z / trials
    centre = (p + z * z / (2 * trials)) / denominator
    half = z * math.sqrt(p * (1 - p) / trials + z * z / (4 * trials * trials)) / denominator
    return (max(0.0, centre - half), min(1.0, centre + half))
