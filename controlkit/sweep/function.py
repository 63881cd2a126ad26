"""Sweeping a function: :func:`sweep` checks every argument, opens the store, makes the
runs on the executor and gathers the rows into a table."""

from __future__ import annotations

import hashlib
import inspect
import json
import os
import sys
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from .. import _checks
from .._store import RunStore
from .._workers import ProcessRunner, ThreadRunner
from ..outputs.export import json_default
from .executors import (
    _check_executor,
    _connect,
    _on_executor,
    _sendable,
    prestart,
    process_context,
)
from .points import plan
from .rows import _call, _call_elsewhere, _failed_row, _pandas, _row


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
    return _checks.folder(name, path)


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
        value. For process executors, and with ``timeout``, a function that other
        processes cannot import by name (one defined in a notebook, a lambda, a closure)
        is sent by value, with ``cloudpickle`` (in the ``sweep`` extra).
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
    pd = _pandas()
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
    sent = _sendable(function, kind, executor, timeout)
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
            _make(sent, todo, rows, run_store, kind, executor, workers, client, timeout,
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
    in_processes = kind in ("processes", "threads", "serial") and not (
        kind in ("serial", "threads") and timeout is None)
    try:
        if in_processes:
            context = process_context()
            prestart(context, function)  # the workers' imports, once, beside the warm-up
        if warmup is not None:
            warmup()
        if kind == "serial" and timeout is None:
            for run in todo:
                record(_call(function, run))
        elif kind == "threads" and timeout is None:
            ThreadRunner(_call, function, n).map(todo, record)
        elif in_processes:
            runner = ProcessRunner(_call_elsewhere, _failed_row, function,
                                   1 if kind == "serial" else n, context, timeout)
            runner.map(todo, record)
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
