"""Writing results: CSV tables and JSON metrics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def write_csv(path, columns: dict[str, np.ndarray], *, stride: int = 1) -> Path:
    """Write equal-length columns as CSV, keeping every ``stride``-th row.

    Parameters
    ----------
    path : str or pathlib.Path
        File to write (parents are created).
    columns : dict of str to array_like
        Column name to values, in output order.
    stride : int
        Keep rows ``0, stride, 2 stride, ...``; >= 1.

    Returns
    -------
    pathlib.Path

    Examples
    --------
    >>> import tempfile, pathlib
    >>> p = write_csv(pathlib.Path(tempfile.mkdtemp()) / "a.csv", {"t": [0, 1, 2]}, stride=2)
    >>> p.read_text().splitlines()
    ['t', '0', '2']
    """
    if isinstance(stride, bool) or not isinstance(stride, int) or stride < 1:
        raise ValueError(f"stride must be an integer >= 1, got {stride!r}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = np.column_stack([np.asarray(v, dtype=float) for v in columns.values()])[::stride]
    np.savetxt(path, data, delimiter=",", header=",".join(columns), comments="", fmt="%.10g")
    return path


def write_json(path, data) -> Path:
    """Write ``data`` as indented JSON (numpy scalars and arrays converted).

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> p = write_json(pathlib.Path(tempfile.mkdtemp()) / "m.json", {"x": np.float64(1.5)})
    >>> p.read_text()
    '{\\n  "x": 1.5\\n}\\n'
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, indent=2, default=_to_builtin) + "\n")
    return path


def save_figure(fig, path, *, dpi=110) -> Path:
    """Lay out, save and close a matplotlib figure; return its path.

    Examples
    --------
    >>> import tempfile, pathlib, matplotlib
    >>> matplotlib.use("Agg")
    >>> import matplotlib.pyplot as plt
    >>> save_figure(plt.figure(), pathlib.Path(tempfile.mkdtemp()) / "f.png").suffix
    '.png'
    """
    import matplotlib.pyplot as plt

    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)


def _to_builtin(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot write {type(value).__name__} as JSON")
