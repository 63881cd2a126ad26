"""Sweeping a diagram: every run of one system in one compiled call, then a metric per
response."""

from __future__ import annotations

import sys
import time

from ..engines.params import check_params
from .points import RESERVED, plan
from .rows import _describe, _pandas, _plain_metrics


def sweep_system(sys, timepts, inputs=0.0, initial_state=0.0, *, metrics, grid=None,
                 draws=None, samples=None, seed=None, params=None, progress=False,
                 **simulation):
    """Run a diagram over a grid or seeded draws of its ``params``; one row per run.

    Where :func:`sweep` calls a Python function per run on an executor, this runs every
    run of one diagram in one compiled call over all cores
    (:func:`controlkit.input_output_response` with a list of parameter sets), then
    calls ``metrics`` on each response.

    Parameters
    ----------
    sys : control.InputOutputSystem
        Any diagram :func:`controlkit.input_output_response` runs (continuous, discrete,
        sampled-data).
    timepts, inputs, initial_state
        As for :func:`controlkit.input_output_response`, shared by the runs.
    metrics : callable
        ``metrics(response) -> dict`` of numbers, strings or booleans for a run.
    grid, draws, samples, seed
        The values of the swept ``params`` keys, as in :func:`sweep`.
    params : dict, optional
        Values every run shares (the swept ones replace them).
    progress : bool
        Print how many runs there are and how long they took (stderr).
    **simulation
        More keywords of :func:`controlkit.input_output_response` (e.g.
        ``solve_ivp_method``).

    Returns
    -------
    pandas.DataFrame
        Columns ``run``, the swept parameters, the metrics, ``error`` (empty when the run
        succeeded).

    Examples
    --------
    >>> import control as ct
    >>> import numpy as np
    >>> def decay(t, x, u, params):
    ...     return -params["a"] * x + u
    >>> plant = ct.nlsys(decay, None, inputs="u", outputs="y", states=1,
    ...                  params={"a": 1.0}, name="plant")
    >>> table = sweep_system(plant, np.linspace(0.0, 5.0, 51), 1.0, 0.0,
    ...                      grid={"a": [0.5, 1.0, 2.0]},
    ...                      metrics=lambda r: {"final": round(float(r.outputs[-1]), 3)})
    >>> table[["a", "final"]].values.tolist()
    [[0.5, 1.836], [1.0, 0.993], [2.0, 0.5]]
    """
    pd = _pandas()
    if not callable(metrics):
        raise ValueError(f"metrics must be a function of a response, got {metrics!r}")
    if not isinstance(progress, bool):
        raise ValueError(f"progress must be True or False, got {progress!r}")
    if params is not None and not isinstance(params, dict):
        raise ValueError(f"params must be a dict of the values every run shares, got "
                         f"{type(params).__name__} {params!r:.60}")
    runs = plan(grid=grid, draws=draws, samples=samples, seed=seed)
    shared = dict(params or {})
    params_list = [{**shared, **run.params} for run in runs]
    check_params(sys, params_list[0])  # a swept name no block reads would change nothing
    started = time.perf_counter()
    from ..simulation import input_output_response

    try:
        responses = input_output_response(sys, timepts, inputs, initial_state,
                                          params=params_list, **simulation)
        failures = [None] * len(runs)
    except Exception as together:  # noqa: BLE001 - run each on its own, to know which
        responses, failures = [], []
        for p in params_list:
            try:
                responses.append(input_output_response(sys, timepts, inputs, initial_state,
                                                       params=p, **simulation))
                failures.append(None)
            except Exception as each:  # noqa: BLE001 - this run's error, in its row
                responses.append(None)
                failures.append(_describe(each))
        if len(set(failures)) == 1 and failures[0] is not None:
            raise together  # every run fails alike: the call's arguments, not a run
    rows = [_system_row(run, resp, failure, metrics)
            for run, resp, failure in zip(runs, responses, failures, strict=True)]
    if progress:
        elapsed = time.perf_counter() - started
        print(f"sweep_system: {len(runs)} runs in {elapsed:.2f} s", file=_stderr())
    return pd.DataFrame(rows)


def _system_row(run, resp, failure, metrics) -> dict:
    """One run's row: its parameters, the metrics of its response, or why it has none."""
    row = {"run": run.index, **run.params}
    if failure is not None:
        return {**row, "error": failure}
    try:
        result = metrics(resp)
        if not isinstance(result, dict):
            raise TypeError(f"metrics must return a dict, got {type(result).__name__}")
        clash = sorted(k for k in result if k in RESERVED or k in run.params)
        if clash:
            raise ValueError(f"metrics returned {clash}: names of the table's own columns "
                             f"(run, error and the swept parameters); rename these metrics")
        row.update(_plain_metrics(result))
        row["error"] = ""
    except Exception as error:  # noqa: BLE001 - a failing metric is the row's error
        row["error"] = _describe(error)
    return row


def _stderr():
    return sys.stderr
