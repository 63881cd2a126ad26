"""Writing results: CSV tables and JSON metrics, each file complete or absent."""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
from pathlib import Path

import numpy as np

from .._lock import process_alive


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
    data = np.column_stack([np.asarray(v, dtype=float) for v in columns.values()])[::stride]
    with atomic(path) as partial, partial.open("w") as handle:
        handle.write(",".join(columns) + "\n")
        write_rows(handle, data)
    return Path(path)


#: Rows formatted per ``%`` operation by :func:`write_rows` (bounds its memory).
ROWS_PER_BLOCK = 10_000


def write_rows(handle, data, fmt: str = "%.10g") -> None:
    """Write a 2-D array as comma-separated rows: ``np.savetxt(handle, data, fmt=fmt,
    delimiter=",")``, the same text, a third quicker.

    savetxt formats each row with its own ``%`` operation; here one ``%`` formats a
    block of :data:`ROWS_PER_BLOCK` rows with the very same format, so every number is
    written exactly as savetxt writes it.

    Examples
    --------
    >>> import io
    >>> out = io.StringIO()
    >>> write_rows(out, np.array([[0.1, 2.0], [1e-12, 3.25]]))
    >>> out.getvalue()
    '0.1,2\\n1e-12,3.25\\n'
    """
    data = np.asarray(data, dtype=float)
    if data.ndim != 2:
        raise ValueError(f"data must be 2-D (rows by columns), got shape {data.shape}")
    row = ",".join([fmt] * data.shape[1]) + "\n"
    for start in range(0, data.shape[0], ROWS_PER_BLOCK):
        block = data[start:start + ROWS_PER_BLOCK]
        handle.write((row * block.shape[0]) % tuple(block.ravel().tolist()))


@contextlib.contextmanager
def atomic(path):
    """Write a file under a temporary name and rename it when complete.

    Yields the temporary path (a hidden name in the same folder, unique to this process
    and this call: ``.NAME.PID.TOKEN.partial``); on success it replaces ``path`` in one
    step, on any error or interruption it is removed. So a reader, or a run that was
    stopped, never sees a half-written file under the final name, and two processes (or
    threads) writing the same file never write into, or remove, each other's temporary
    file: the last to finish wins, whole. A killed writer's leftover keeps its pid in its
    name, for whoever cleans the folder to tell it from a live writer's file.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
    >>> with atomic(target) as partial:
    ...     _ = partial.write_text("done")
    >>> target.read_text(), sorted(p.name for p in target.parent.iterdir())
    ('done', ['a.txt'])
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.partial")
    try:
        yield partial
        os.replace(partial, path)
    finally:
        with contextlib.suppress(FileNotFoundError):
            partial.unlink()


def remove_stale_partials(folder) -> int:
    """Remove the temporary files that killed writers left in ``folder``; how many.

    A temporary file (:func:`atomic`, ``.NAME.PID[.TOKEN].partial``) whose writer's
    process no longer runs is a leftover; one of a live process, this one included, is
    being written and stays.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / f".a.csv.{2 ** 22 + 7}.0123abcd.partial").write_text("half")
    >>> _ = (folder / f".b.csv.{os.getpid()}.partial").write_text("being written")
    >>> remove_stale_partials(folder), sorted(p.name for p in folder.iterdir())[0][:6]
    (1, '.b.csv')
    """
    removed = 0
    for leftover in Path(folder).glob(".*.partial"):
        found = (re.search(r"\.(\d+)\.[0-9a-f]{8}\.partial$", leftover.name)
                 or re.search(r"\.(\d+)\.partial$", leftover.name))
        if found is None or process_alive(int(found[1])):
            continue
        with contextlib.suppress(OSError):
            leftover.unlink()
            removed += 1
    return removed


def write_json(path, data) -> Path:
    """Write ``data`` as indented JSON (numpy scalars and arrays converted).

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> p = write_json(pathlib.Path(tempfile.mkdtemp()) / "m.json", {"x": np.float64(1.5)})
    >>> p.read_text()
    '{\\n  "x": 1.5\\n}\\n'
    """
    text = json.dumps(data, indent=2, default=json_default) + "\n"
    with atomic(path) as partial:
        partial.write_text(text)
    return Path(path)


def json_default(value):
    """``default=`` of :func:`json.dumps` for numpy scalars and arrays.

    Examples
    --------
    >>> import json, numpy as np
    >>> json.dumps({"x": np.arange(2)}, default=json_default)
    '{"x": [0, 1]}'
    """
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"cannot write {type(value).__name__} as JSON")
