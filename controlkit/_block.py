"""Building ``NonlinearIOSystem`` blocks from kernels, and remembering the kernels.

A block built here carries a :class:`BlockKernels` in its ``kernels`` attribute: the
plain functions and packed parameters that the fast engine compiles. The
python-control path calls the very same functions, so both paths compute
the same equations.
"""

from __future__ import annotations

from collections import namedtuple
from collections.abc import Callable
from dataclasses import dataclass, replace

import control as ct
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


@dataclass(frozen=True)
class BlockKernels:
    """What the fast engine needs to run a block without python-control.

    Attributes
    ----------
    output : callable
        ``output(t, x, u, p, out) -> out``, writing ``y`` into ``out``.
    update : callable or None
        ``update(t, x, u, p, out) -> out``: the next state (discrete), the derivative
        (continuous, or continuous under ``rk4``), ``None`` for a static block.
    params : numpy.ndarray
        Packed parameters ``p``.
    feedthrough : bool
        Whether ``output`` reads ``u``.
    rk4 : tuple of (float, int), optional
        ``(Ts, substeps)`` when a continuous block is sampled by
        :func:`~controlkit.sampling.sample_nlsys`.
    """

    output: Callable
    update: Callable | None
    params: np.ndarray
    feedthrough: bool
    rk4: tuple[float, int] | None = None

    def sampled(self, Ts: float, substeps: int) -> BlockKernels:
        """The same kernel under ZOH with ``substeps`` RK4 steps per period ``Ts``."""
        return replace(self, rk4=(float(Ts), int(substeps)))


def kernel_block(output, update=None, *, params=(), feedthrough=True, check=None,
                 uncompiled=None, **nlsys_kwargs) -> ct.NonlinearIOSystem:
    """A ``NonlinearIOSystem`` whose equations are the given kernels.

    Parameters
    ----------
    output, update : callable
        Kernels ``f(t, x, u, p, out)`` (``update`` None for a static block).
    params : array_like
        Packed parameters passed as ``p``.
    feedthrough : bool
        Whether the output depends on the input (for the fast engine's ordering).
    check : callable, optional
        ``check(t, x, u, y)`` called on each output on the python-control path;
        raises a ``ValueError`` with a clear message where the kernel returned NaN.
    uncompiled : str, optional
        Why the fast engine cannot compile this block (its kernels call Python
        objects); the block then has ``kernels = None`` and ``kernel_reason``.
    **nlsys_kwargs
        ``inputs``, ``outputs``, ``states``, ``dt``, ``name`` for :func:`control.nlsys`.

    Returns
    -------
    control.NonlinearIOSystem
        With attribute ``kernels`` (a :class:`BlockKernels`, or None if ``uncompiled``).

    Examples
    --------
    >>> from controlkit.kernels.common import constant_output
    >>> kernel_block(constant_output, params=[1.0, 2.0], feedthrough=False, inputs=0,
    ...              outputs=2, dt=None).output(0.0, [], []).tolist()
    [1.0, 2.0]
    """
    p = np.array(params, dtype=float).reshape(-1)
    size = {}  # filled once the system knows its dimensions

    def outfcn(t, x, u, _params):
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        y = output(t, x, u, p, np.empty(size["y"]))
        if check is not None and size["y"] and np.isnan(y[0]):
            check(t, x, u, y)
        return y

    updfcn = None
    if update is not None:
        def updfcn(t, x, u, _params):
            return update(t, np.asarray(x, dtype=float), np.asarray(u, dtype=float), p,
                          np.empty(size["x"]))

    sys = ct.nlsys(updfcn, outfcn, **nlsys_kwargs)
    size["y"], size["x"] = sys.noutputs, sys.nstates
    sys.kernels = None if uncompiled else BlockKernels(output, update, p, bool(feedthrough))
    sys.kernel_check = check
    if uncompiled:
        sys.kernel_reason = uncompiled
    return sys
