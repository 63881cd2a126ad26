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

A run that raises is a row with its ``error``; the sweep goes on. With
``store=``, each finished run is appended to ``runs.jsonl`` in that folder as
it completes, so an interrupted sweep keeps what it finished and
``resume=True`` runs only what is missing.

:func:`spacecraft_study` is the built-in robustness study of the spacecraft
paper: how often each case keeps the 0.05 deg requirement over draws of the
inertia error, the amplitude of ``H0`` and the initial attitude.
"""

from __future__ import annotations

import concurrent.futures as cf
import hashlib
import itertools
import json
import math
import multiprocessing
import os
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .outputs.export import atomic, json_default

#: Executors by name (``executor=`` of :func:`sweep`, ``--executor`` of the CLI).
EXECUTORS = ("processes", "threads", "serial", "dask")
#: Where finished runs are appended, inside ``store``.
RUNS_FILE = "runs.jsonl"
#: What identifies a sweep inside ``store`` (so ``resume`` never mixes two sweeps).
SPEC_FILE = "sweep.json"


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


def grid_points(grid: dict) -> list[dict]:
    """Every combination of the named values, the last name varying fastest.

    Examples
    --------
    >>> grid_points({"a": [1, 2], "b": ["x", "y"]})
    [{'a': 1, 'b': 'x'}, {'a': 1, 'b': 'y'}, {'a': 2, 'b': 'x'}, {'a': 2, 'b': 'y'}]
    """
    if not isinstance(grid, dict) or not grid:
        raise ValueError(f"grid must be a non-empty dict of name -> values, got {grid!r}")
    values = []
    for name, vals in grid.items():
        vals = list(np.atleast_1d(vals)) if not isinstance(vals, list | tuple) else list(vals)
        if not vals:
            raise ValueError(f"grid[{name!r}] has no values")
        values.append([v.item() if isinstance(v, np.generic) else v for v in vals])
    return [dict(zip(grid, combo, strict=True)) for combo in itertools.product(*values)]


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


def plan(*, grid=None, draws=None, samples=None, seed=0, cases=None,
         fixed=None) -> list[Run]:
    """The runs of a sweep, in order: each point (grid, draw, or grid point crossed with
    every draw) for each case.

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
    if draws is not None and samples is None:
        raise ValueError("draws= needs samples= (how many draws)")
    if grid is not None and draws is not None:
        both = sorted(set(grid) & set(draws))
        if both:
            raise ValueError(f"{both} are both in grid= and in draws=; vary each one way")
    grid_part = grid_points(grid) if grid is not None else [{}]
    draw_part = draw_points(draws, samples, seed) if draws is not None else [(None, {})]
    points = [(run_seed, {**g, **d}) for g in grid_part for run_seed, d in draw_part]
    cases = [None] if cases is None else list(cases)
    if not cases:
        raise ValueError("cases must not be empty (omit it for a sweep without cases)")
    fixed = dict(fixed or {})
    runs, index = [], 0
    for run_seed, params in points:
        for case in cases:
            runs.append(Run(index, case, run_seed, {**fixed, **params}))
            index += 1
    return runs


def _call(function, run: Run) -> dict:
    """Run one point in a worker; any error becomes the row's ``error``."""
    started = time.perf_counter()
    try:
        result = function(**run.kwargs())
        if not isinstance(result, dict):
            raise TypeError(f"the swept function must return a dict of metrics, got "
                            f"{type(result).__name__}")
        error = ""
    except Exception as exc:  # a failing run is a row, not the end of the sweep
        result, error = {}, f"{type(exc).__name__}: {exc}"
    row = {"run": run.index, "case": run.case, "seed": run.seed, **run.params}
    trajectory = result.pop("trajectory", None)
    row.update(result)
    row["error"] = error
    row["wall_time_s"] = round(time.perf_counter() - started, 4)
    if trajectory is not None:
        row["trajectory"] = {k: np.asarray(v).tolist() for k, v in trajectory.items()}
    return row


def _spec_key(function, runs) -> str:
    name = f"{getattr(function, '__module__', '')}.{getattr(function, '__qualname__', '')}"
    text = json.dumps([name] + [[r.index, r.case, r.seed, r.params] for r in runs],
                      sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def _load_finished(store: Path, key: str, resume: bool) -> dict[int, dict]:
    spec, runs_file = store / SPEC_FILE, store / RUNS_FILE
    if spec.exists() and runs_file.exists():
        if not resume:
            raise ValueError(f"store {store} already holds a sweep; pass resume=True "
                             "(--resume) to complete it, or choose another folder")
        if json.loads(spec.read_text()).get("key") != key:
            raise ValueError(f"store {store} holds a different sweep (other function, "
                             "parameters, cases or seed); choose another folder")
        finished = {}
        for line in runs_file.read_text().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:  # a line cut by an interruption: run it again
                continue
            finished[row["run"]] = row
        return finished
    store.mkdir(parents=True, exist_ok=True)
    with atomic(spec) as partial:
        partial.write_text(json.dumps({"key": key}) + "\n")
    runs_file.write_text("")
    return {}


def _append(store: Path, row: dict) -> None:
    with (store / RUNS_FILE).open("a") as handle:
        handle.write(json.dumps(row, default=json_default) + "\n")
        handle.flush()
        os.fsync(handle.fileno())


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


def _executor(executor, workers, scheduler):
    """``(executor, close)`` for a name or an executor the user passed (never closed here).

    ``executor`` is None for ``"serial"``: the runs then go one by one in this process.
    Closing cancels the runs not yet started (an interrupted sweep stops promptly).
    """
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
    if isinstance(executor, cf.Executor):
        return executor, lambda: None
    if executor is None:
        executor = "processes"
    if executor not in EXECUTORS:
        raise ValueError(f"executor must be one of {EXECUTORS} or a concurrent.futures."
                         f"Executor, got {executor!r}")
    n = workers or os.cpu_count() or 1
    if executor == "serial":
        return None, lambda: None
    if executor == "threads":
        pool = cf.ThreadPoolExecutor(n)
        return pool, lambda: pool.shutdown(cancel_futures=True)
    if executor == "processes":
        pool = cf.ProcessPoolExecutor(n, mp_context=process_context())
        return pool, lambda: pool.shutdown(cancel_futures=True)
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise ValueError('executor="dask" needs Dask: pip install "controlkit[cluster]"'
                         ) from None
    if scheduler:
        client = Client(scheduler)
        return client.get_executor(), client.close
    cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    client = Client(cluster)

    def close():
        client.close()
        cluster.close()

    return client.get_executor(), close


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
          draws: dict | None = None, samples: int | None = None, seed: int = 0,
          cases: Iterable | None = None, fixed: dict | None = None, executor=None,
          workers: int | None = None, scheduler: str | None = None, store=None,
          resume: bool = False, warmup: Callable[[], object] | None = None,
          progress: bool = True):
    """Run ``function`` over a grid or seeded draws of named parameters; one row per run.

    Parameters
    ----------
    function : callable
        ``function(**params) -> dict`` of metrics (numbers, strings or booleans), with
        ``case=`` when the sweep has ``cases``. An entry ``"trajectory"`` (a dict of
        arrays, e.g. decimated time and error) is kept per run in
        ``result.attrs["trajectories"]``, not in the table. For process or Dask
        executors it must be importable (a module-level function, not a lambda).
    grid : dict, optional
        Name to a list of values: every combination is run (with ``draws`` too: each
        combination with every draw).
    draws : dict, optional
        Name to a distribution (see :func:`draw_points`); with ``samples`` and ``seed``.
    samples : int, optional
        Number of random draws.
    seed : int
        Seed of the draws (default 0): the same seed gives the same rows.
    cases : iterable of str, optional
        Each point runs once per case (the same parameters for every case).
    fixed : dict, optional
        Parameters passed to every run (e.g. ``horizon``), recorded in each row.
    executor : {"processes", "threads", "serial", "dask"} or concurrent.futures.Executor
        Where the runs go. Default: processes on all cores (or ``workers``). ``"dask"``
        starts a local Dask cluster, or uses the scheduler at ``scheduler``; any
        executor object is used as given (e.g. ``client.get_executor()``) and not closed.
    workers : int, optional
        Number of workers for the executors made here (default: the CPU count).
    scheduler : str, optional
        Address of a running Dask scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    store : str or pathlib.Path, optional
        Folder where each finished run is appended (``runs.jsonl``) as it completes.
    resume : bool
        Complete the sweep already in ``store``, skipping its finished runs.
    warmup : callable, optional
        Called once here before the workers start (e.g. to compile and cache the
        simulation loops, so that workers load them from the disk cache).
    progress : bool
        Show a progress bar with an estimated time left (tqdm) on stderr.

    Returns
    -------
    pandas.DataFrame
        Columns ``run``, ``case``, ``seed``, the parameters, the metrics, ``error``
        (empty when the run succeeded) and ``wall_time_s``; sorted by ``run``.

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
    if not callable(function):
        raise ValueError(f"function must be callable, got {function!r}")
    runs = plan(grid=grid, draws=draws, samples=samples, seed=seed, cases=cases, fixed=fixed)
    finished: dict[int, dict] = {}
    if store is not None:
        store = Path(store)
        finished = _load_finished(store, _spec_key(function, runs), resume)
    elif resume:
        raise ValueError("resume=True needs store= (the folder of the sweep to complete)")
    todo = [r for r in runs if r.index not in finished]
    rows = dict(finished)
    if todo:
        if warmup is not None:
            warmup()
        pool, close = _executor(executor, workers, scheduler)
        bar = _progress_bar(len(runs), progress)
        bar.update(len(finished))
        def record(row):
            rows[row["run"]] = row
            if store is not None:
                _append(store, row)
            bar.update(1)

        try:
            if pool is None:  # serial: one run after the other, here
                for run in todo:
                    record(_call(function, run))
            else:
                futures = [pool.submit(_call, function, run) for run in todo]
                for future in cf.as_completed(futures):
                    record(future.result())
        finally:
            bar.close()
            close()
    ordered = [rows[r.index] for r in runs]
    trajectories = {row["run"]: row.pop("trajectory") for row in ordered if "trajectory" in row}
    table = pd.DataFrame(ordered)
    if all(r.case is None for r in runs):
        table = table.drop(columns="case")
    if all(r.seed is None for r in runs):
        table = table.drop(columns="seed")
    table.attrs["trajectories"] = trajectories
    return table


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
