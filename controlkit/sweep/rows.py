"""One run made, one row: the function called, its metrics checked as plain values, and
whatever it raises turned into the row's ``error``."""

from __future__ import annotations

import time

import numpy as np

from .._checks import install_hint
from .._store import plain, same_value
from .points import RESERVED, Run


def _pandas():
    """pandas, which a sweep's table is; ImportError naming the extra that installs it."""
    try:
        import pandas
    except ImportError:
        raise ImportError('controlkit.sweep returns a pandas DataFrame: '
                          f'{install_hint("pandas", "sweep")}') from None
    return pandas


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

    A KeyboardInterrupt is not caught: in this process it stops the sweep. Anything else
    the function raises (an ``Exception``, ``SystemExit``, ``GeneratorExit``, asyncio's
    ``CancelledError``, a ``BaseException`` of its own) is the row's error.
    """
    started = time.perf_counter()
    try:
        metrics, trajectory = _metrics(function(**run.kwargs()), run)
        error = ""
    except KeyboardInterrupt:
        raise
    except BaseException as exc:  # noqa: B036 - a failing run is a row, not the end
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

