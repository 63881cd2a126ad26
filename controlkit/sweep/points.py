"""The runs of a sweep, fixed before any starts: every combination of a grid, seeded draws
of named distributions, crossed with cases."""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np

#: Columns every row has, that parameters and metrics cannot be named.
RESERVED = ("run", "case", "seed", "error", "wall_time_s")
#: Most runs in one sweep: its plan and rows stay within memory (about 1 kB a run).
MAX_RUNS = 1_000_000


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
        """The function's keyword arguments: the parameters, and ``case`` if any.

        A list, dict, set or array among them is a fresh copy for each call: a function
        that changes the one it is given changes neither the next run's nor the row's
        record of this one's, whatever the executor (a worker process gets a copy anyway).
        """
        fresh = {name: _fresh(value) for name, value in self.params.items()}
        return fresh if self.case is None else {"case": self.case, **fresh}


def _fresh(value):
    """A copy of a mutable container of values, else the value itself (shared, as Python
    shares an object passed to a function)."""
    if isinstance(value, list | dict | set | bytearray | np.ndarray):
        return copy.deepcopy(value)
    return value


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
        if isinstance(vals, Iterator):
            raise ValueError(f"grid[{name!r}] is a {type(vals).__name__}, which can be read "
                             "only once (a resume or a second look would find it empty); "
                             "give a list, e.g. list(...)")
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
