"""The packed parameter vector ``p`` of a block's user functions: where each ``params``
key sits, of which kind and shape, and how ``p`` is built from the values in force.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ...source import NotCompilable
from ...source.values import narrow, plain_values, sequence_loses

#: Integers up to this size are exact in a float64 (larger ones run as Python).
_EXACT_INT = 2 ** 53


class ParamEntry(NamedTuple):
    """Where one parameter sits in ``p``: ``kind`` is ``float``, ``int``, ``bool``,
    ``complex``, ``none``, ``absent`` or ``array-f``/``array-i``/``array-b``.

    Examples
    --------
    >>> ParamLayout(["pole"], {"pole": -0.5 + 1j}).entries[0]
    ParamEntry(key='pole', kind='complex', shape=(), offset=0, size=2)
    """

    key: object
    kind: str
    shape: tuple
    offset: int
    size: int


def _kind(key, value):
    """``(kind, shape)`` of a parameter value, or NotCompilable naming the parameter."""
    if value is None:
        return "none", ()
    if not plain_values(value):  # (a float subclass's own __mul__: Python's run calls it)
        raise NotCompilable(f"parameter {key!r} holds a {_not_plain(value).__name__}, whose "
                            f"own operators compiled code would not call")
    if why := sequence_loses(value):
        raise NotCompilable(f"parameter {key!r} {why}")
    if isinstance(value, np.generic | np.ndarray) and value.dtype.kind in "iufc" \
            and narrow(value.dtype):
        raise NotCompilable(f"parameter {key!r} is of type {value.dtype.name}: numpy "
                            f"computes in it, compiled code in 64 bits")
    if isinstance(value, bool | np.bool_):
        return "bool", ()
    if isinstance(value, int | np.integer):
        return "int", ()
    if isinstance(value, float | np.float64):
        return "float", ()
    if isinstance(value, complex | np.complex128):
        return "complex", ()
    if isinstance(value, np.ndarray | list | tuple):
        try:
            array = np.asarray(value)
        except (ValueError, TypeError):
            array = None
        if array is not None and (array.dtype.kind == "b" or array.dtype == np.float64
                                  or array.dtype.kind in "iu" and not narrow(array.dtype)):
            if array.ndim == 0:
                return _kind(key, array.item())
            return "array-" + {"b": "b", "i": "i", "u": "i", "f": "f"}[array.dtype.kind], \
                array.shape
        described = f"an array of {array.dtype}" if array is not None else "a ragged sequence"
        raise NotCompilable(f"parameter {key!r} is {described}, which compiled code cannot "
                            f"take (numbers, and arrays of float64, int or bool, can)")
    raise NotCompilable(f"parameter {key!r} is a {type(value).__name__} ({value!r:.40}), "
                        f"which compiled code cannot take")


def _not_plain(value) -> type:
    """The type of the first value inside ``value`` that is not plain."""
    if type(value) in (list, tuple):
        return next(_not_plain(item) for item in value if not plain_values(item))
    return type(value)


class ParamLayout:
    """The packed parameter vector ``p`` of a block's user functions.

    One entry per ``params`` key the functions read, sorted by key: its kind and
    shape (from the values in force), offset and size in ``p``. The compiled code
    depends on the entries, never on the values; :meth:`pack` builds ``p``.

    Examples
    --------
    >>> layout = ParamLayout(["K", "kp", "umax"], {"K": [[1.0, 2.0]], "kp": 2})
    >>> [(e.key, e.kind, e.shape, e.offset) for e in layout.entries]
    [('K', 'array-f', (1, 2), 0), ('kp', 'int', (), 2), ('umax', 'absent', (), 3)]
    >>> layout.pack({"K": [[1.0, 2.0]], "kp": 3}).tolist()
    [1.0, 2.0, 3.0]
    """

    def __init__(self, keys, values):
        entries, offset = [], 0
        for key in sorted(keys, key=repr):
            if key in values:
                kind, shape = _kind(key, values[key])
            else:
                kind, shape = "absent", ()
            size = (2 if kind == "complex" else 1 if kind in ("float", "int", "bool")
                    else int(np.prod(shape, dtype=int)) if kind.startswith("array") else 0)
            entries.append(ParamEntry(key, kind, shape, offset, size))
            offset += size
        self.entries = tuple(entries)
        self.size = offset
        self.by_key = {e.key: e for e in entries}

    def pack(self, values) -> np.ndarray:
        """``p`` for the parameter ``values`` in force (same kinds and shapes as the layout).

        Raises
        ------
        NotCompilable
            When a value does not fit (another type or shape, an integer beyond 2**53).
        """
        p = np.empty(self.size)
        for e in self.entries:
            if e.kind == "absent":
                if e.key in values:
                    raise NotCompilable(f"parameter {e.key!r} was not given when compiled")
                continue
            value = values[e.key]
            kind, shape = _kind(e.key, value)
            if (kind, shape) != (e.kind, e.shape):
                raise NotCompilable(f"parameter {e.key!r} is now a {kind} {shape}, compiled "
                                    f"for a {e.kind} {e.shape}")
            if kind == "complex":
                p[e.offset:e.offset + 2] = value.real, value.imag
            elif kind.startswith("array"):
                array = np.asarray(value)
                if kind == "array-i" and array.size and np.abs(array).max() > _EXACT_INT:
                    raise NotCompilable(f"parameter {e.key!r} holds integers beyond 2**53")
                p[e.offset:e.offset + e.size] = array.reshape(-1)
            elif kind != "none":
                if kind == "int" and abs(int(value)) > _EXACT_INT:
                    raise NotCompilable(f"parameter {e.key!r} = {value} is an integer beyond "
                                        f"2**53, which a float64 does not hold exactly")
                p[e.offset] = value
        return p
