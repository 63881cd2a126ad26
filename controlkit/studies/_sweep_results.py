"""What every study's robustness sweep does the same way: its loops compiled before the
workers start, its table and summary files, and the success rate over bins of a drawn
parameter.

The studies' ``robustness`` modules (the ``warmup``, ``write`` and ``binned`` of their
:class:`~controlkit.studies.registry.Robustness`) and
:func:`controlkit.studies.robustness.study` call these.
"""

from __future__ import annotations

import json
from pathlib import Path

from ..outputs.export import atomic

#: The files every robustness sweep writes in its ``out`` folder (the figures come after).
RESULT_FILES = ("sweep.csv", "summary.json")


def warming(run, step: float):
    """A study's ``warmup(cases)``: each case run compiled for two steps of ``step`` s,
    which compiles its diagram's module once (kept in the store) before the sweep's
    workers start, so that each of them loads it.

    Examples
    --------
    >>> ran = []
    >>> warming(lambda case, horizon, compile: ran.append((case, horizon)), 0.1)(["a", "b"])
    >>> ran
    [('a', 0.2), ('b', 0.2)]
    """
    def warm(cases) -> None:
        for case in cases:
            run(case, horizon=2 * step, compile=True)

    return warm


def write_table_and_summary(table, summary: dict, out) -> list[Path]:
    """``sweep.csv`` (``table``, one row a run) and ``summary.json`` (``summary``, indented)
    in the folder ``out`` (made if need be), each written under a temporary name and
    renamed when complete.

    Examples
    --------
    >>> import tempfile
    >>> import pandas as pd
    >>> paths = write_table_and_summary(pd.DataFrame({"run": [0]}), {"cases": {}},
    ...                                 tempfile.mkdtemp())
    >>> [p.name for p in paths], paths[0].read_text()
    (['sweep.csv', 'summary.json'], 'run\\n0\\n')
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with atomic(out / RESULT_FILES[0]) as partial:
        table.to_csv(partial, index=False)
    with atomic(out / RESULT_FILES[1]) as partial:
        partial.write_text(json.dumps(summary, indent=2) + "\n")
    return [out / name for name in RESULT_FILES]


def requirement_met(rows, success: str):
    """Per run, whether it met the requirement: its ``success`` metric is true and it
    finished (a run that failed has no metrics, and did not meet it).

    Examples
    --------
    >>> import pandas as pd
    >>> rows = pd.DataFrame({"ok": [True, None, True], "error": ["", "boom", "late"]})
    >>> requirement_met(rows, "ok").tolist()
    [True, False, False]
    """
    return rows[success].fillna(False).astype(bool) & (rows["error"] == "")


def success_by_bin(values, met, edges, name: str, *, closed: bool = False) -> list[dict]:
    """The runs and the success rate in each bin of ``values`` between ``edges``.

    A bin is ``a <= value < b`` (the last ``a <= value <= b``); with ``closed`` every bin
    is ``a <= value <= b``, so a run on an inner edge counts in both bins beside it.

    Parameters
    ----------
    values, met : pandas.Series
        The binned parameter of each run, and whether the run met the requirement.
    edges : numpy.ndarray
        Increasing bin edges.
    name : str
        The bins' keys are ``{name}_low`` and ``{name}_high``.

    Returns
    -------
    list of dict
        Per bin: its edges, ``runs``, and ``success_rate`` (the share of its runs that
        met it; NaN for an empty bin).

    Examples
    --------
    >>> import numpy as np
    >>> import pandas as pd
    >>> bins = success_by_bin(pd.Series([0.1, 0.5, 0.9]), pd.Series([True, True, False]),
    ...                       np.array([0.0, 0.5, 1.0]), "scale")
    >>> [(b["scale_low"], b["runs"], b["success_rate"]) for b in bins]
    [(0.0, 1, 1.0), (0.5, 2, 0.5)]
    """
    bins = []
    for low, high in zip(edges[:-1], edges[1:], strict=True):
        below = values <= high if closed or high >= edges[-1] else values < high
        inside = (values >= low) & below
        n = int(inside.sum())
        bins.append({f"{name}_low": float(low), f"{name}_high": float(high), "runs": n,
                     "success_rate": float(met[inside].mean()) if n else float("nan")})
    return bins
