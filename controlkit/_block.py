"""Building ``NonlinearIOSystem`` blocks from kernels, and remembering the kernels.

A block built here carries a :class:`BlockKernels` in its ``kernels`` attribute: the
plain functions and packed parameters that the fast engine compiles. The
python-control path calls the very same functions, so both paths compute
the same equations.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import control as ct
import numpy as np


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
