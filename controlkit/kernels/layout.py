"""Packed vectors declared once, by name: the layouts kernels and blocks share.

A kernel reads its parameters, states and inputs from flat float vectors (numba
compiles those, not dicts); :func:`layout` gives each entry a name, so that code
reads ``p[PLANT.H0]``, never a position, and a block packs the same vector with
size checks.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

_LAYOUT_METHODS = frozenset({"pack", "unpack", "slice", "labels", "size", "sizes", "title"})


def layout(title: str, **sizes: int):
    """Declare a packed vector once, by name: ``layout("plant parameters", J=9, H0=10)``.

    The result is a named tuple of the fields' integer offsets, so a kernel
    reads ``p[PLANT.H0]`` or ``x[TUNER_STATE.K + 1]``: numba freezes a global
    named tuple of ints as compile-time constants, so a name costs nothing
    over a literal index (inside a kernel only the offsets can be read: a size
    the kernel needs goes into a module-level int, ``_N = STATE.size``).
    The same object packs the vector with size checks (:meth:`pack`), reads it
    back (:meth:`unpack`, :meth:`slice`) and names its entries as
    python-control signals (:meth:`labels`).

    Parameters
    ----------
    title : str
        What the vector is, for error messages (``"FRIT tuner state"``).
    **sizes : int
        Field names and lengths, in packing order.

    Returns
    -------
    tuple
        A named tuple of offsets with the attributes ``title``, ``sizes``
        (a dict) and ``size`` (the total length).

    Examples
    --------
    >>> GAIN = layout("gain parameters", F=2, Ts=1)
    >>> GAIN.F, GAIN.Ts, GAIN.size
    (0, 2, 3)
    >>> GAIN.pack(F=[0.5, 0.25], Ts=0.1).tolist()
    [0.5, 0.25, 0.1]
    >>> GAIN.labels()
    ['F[0]', 'F[1]', 'Ts']
    >>> GAIN.pack(F=[0.5], Ts=0.1)
    Traceback (most recent call last):
    ...
    ValueError: gain parameters: F must have 2 values, got 1
    """
    clash = _LAYOUT_METHODS.intersection(sizes)
    if clash:
        raise ValueError(f"{title}: field names {sorted(clash)} are reserved")
    offsets, total = [], 0
    for name, n in sizes.items():
        if int(n) != n or n < 1:
            raise ValueError(f"{title}: the size of {name} must be a positive integer, got {n}")
        offsets.append(total)
        total += int(n)
    base = namedtuple("Layout", list(sizes))
    cls = type("Layout", (base, _LayoutMethods), {"__slots__": (), "title": title,
                                                  "sizes": dict(sizes), "size": total})
    return cls(*offsets)


class _LayoutMethods:
    """Methods shared by every :func:`layout` (numba only reads the offsets)."""

    __slots__ = ()

    def pack(self, **values) -> np.ndarray:
        """The packed float vector; every field given once, with its declared length."""
        missing = [name for name in self.sizes if name not in values]
        unknown = [name for name in values if name not in self.sizes]
        if missing or unknown:
            raise ValueError(f"{self.title}: missing {missing}, unknown {unknown}; "
                             f"fields are {list(self.sizes)}")
        parts = []
        for name, n in self.sizes.items():
            v = np.asarray(values[name], dtype=float).reshape(-1)
            if v.size != n:
                raise ValueError(f"{self.title}: {name} must have {n} values, got {v.size}")
            parts.append(v)
        return np.concatenate(parts)

    def slice(self, name: str) -> slice:
        """Where field ``name`` lies in the packed vector."""
        start = getattr(self, name)
        return slice(start, start + self.sizes[name])

    def unpack(self, vector) -> dict:
        """The fields of a packed ``vector`` (views), by name; refuses a wrong length."""
        vector = np.asarray(vector)
        if vector.shape[-1:] != (self.size,):
            raise ValueError(f"{self.title} must have {self.size} values, "
                             f"got shape {vector.shape}")
        return {name: vector[..., self.slice(name)] for name in self.sizes}

    def labels(self) -> list[str]:
        """python-control signal names: ``name`` for a scalar, ``name[i]`` for a vector."""
        return [name if n == 1 else f"{name}[{i}]"
                for name, n in self.sizes.items() for i in range(n)]
