"""The block contract: building ``NonlinearIOSystem`` blocks from kernels.

A controlkit block is an ordinary python-control system whose equations are
*kernels*: plain functions that both the python-control path and the fast
engine (:mod:`controlkit.engine`) call, so that both compute the same numbers.
A block built by :func:`kernel_block` carries its kernels and packed parameters
in its ``kernels`` attribute (a :class:`BlockKernels`). To compile, a block
follows these rules; the ones marked *checked* are enforced where they can be.

**Kernels.**

1. A kernel is a module-level function ``f(t, x, u, p, out) -> out`` in an
   importable module (the engine writes ``from <module> import <name>`` into
   the loop it generates; a lambda or a function defined in ``__main__`` or
   inside another function cannot be imported: *checked* by the engine). The
   controlkit kernels live in :mod:`controlkit.kernels`, one module per family,
   named ``<block>_output``, ``<block>_update`` (discrete: the next state) or
   ``<block>_rhs`` (continuous: the derivative).
2. It is written in the subset of Python and NumPy that numba compiles: scalar
   arithmetic, :mod:`math`, loops, indexing, tuples, calls of other ``@jit``
   functions. No Python objects, dicts, exceptions raised to signal failure,
   or reads of mutable globals (numba freezes globals when it compiles).
   Decorate it, and every helper it calls, with :func:`controlkit._jit.jit`.
3. It writes its result into ``out`` (length ``noutputs`` for an output
   kernel, ``nstates`` for an update or rhs kernel) and returns ``out``; it
   allocates nothing and never modifies ``x``, ``u`` or ``p``.
4. It reads parameters from the flat float vector ``p`` through a named
   :func:`layout` declared once in the kernel's module (``p[PLANT.H0]``), and
   reads ``x`` and ``u`` by the positions of the block's declared states and
   inputs (or through a layout of them).
5. It tolerates the all-zero first sweep: python-control evaluates the
   outputs of an interconnect once with every signal zero before the real
   inputs are known. An output kernel must return finite numbers (or zero)
   for an all-zero input, even where zero is not a physical value.
6. Where the equation is undefined (a singular matrix, a vanishing
   denominator), it writes NaN into ``out[0]`` instead of raising: compiled
   code cannot raise a useful message, so NaN is the failure signal.

**Blocks.**

7. A block declares its signals, states and parameters once: input, output
   and state names as python-control labels (``inputs=``, ``outputs=``,
   ``states=``; a layout's ``labels()`` gives them), and the packed
   parameters as ``params=`` (a layout's ``pack()``, which checks
   every size). Parameters are bound in the factory, never shared through
   python-control's ``params`` dict, so two blocks cannot collide on a name.
8. It declares ``feedthrough``: whether its output kernel reads ``u``. The
   fast engine evaluates blocks without feedthrough first and orders the
   others by their inputs, so a wrong ``False`` reads stale inputs.
9. It declares its timebase: ``dt=None`` for a static block (it joins a
   discrete or a continuous diagram), ``dt=Ts`` for a discrete one; a
   continuous block joins the fast engine once sampled by
   :func:`controlkit.sampling.sample_nlsys` with ``method="rk4"``: its update
   kernel is then the right-hand side ``x'`` that both paths hand to
   :func:`controlkit.kernels.common.rk4_step`.
10. Inputs and states are checked once, at the block's boundary: called with
    the wrong number of inputs or states, the block raises a ``ValueError``
    naming itself, the argument and the expected size (*checked* by the
    wrappers of :func:`kernel_block`), so the compiled kernels can trust them.

**Failures.**

11. A block that can signal failure passes ``check=``: a function
    ``check(t, x, u, y)`` that the wrapper calls when ``y[0]`` is NaN and that
    raises an exception saying why in the user's terms (the attitude, the
    angle, the value that vanished). It tells divergence (non-finite or
    absurdly large signals coming in: a loop that blew up, most often a gain
    too high for the sample time) from a genuine singularity of the equation.
    The fast engine stops at the first NaN and calls the same check, so both
    paths report a failure in the same words.
12. A block whose equations call Python objects (a user's function) passes
    ``uncompiled=`` with the reason; the fast engine then calls its Python
    functions inside its own loop (the ``python`` tier of
    :func:`controlkit.engine.explain`, which also gives that reason).
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
    >>> from controlkit.blocks.spacecraft import io_linearizer
    >>> try:
    ...     io_linearizer().output(0.0, [], [1e-3, 0.0, 1.0])  # q forgotten
    ... except ValueError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    block 'linearizer': the input u must have 6 values
    (mu[0], mu[1], q[0], q[1], q[2], q[3]), got shape (3,)
    """
    p = np.array(params, dtype=float).reshape(-1)
    size = {}  # filled once the system knows its dimensions

    def inputs_and_state(x, u):
        x = np.asarray(x, dtype=float)
        u = np.asarray(u, dtype=float)
        for arg, value, n, labels in (("state x", x, size["x"], size["states"]),
                                      ("input u", u, size["u"], size["inputs"])):
            if value.shape != (n,):
                raise ValueError(
                    f"block {size['name']!r}: the {arg} must have {n} values "
                    f"({_describe(labels)}), got shape {value.shape}")
        return x, u

    def outfcn(t, x, u, _params):
        x, u = inputs_and_state(x, u)
        y = output(t, x, u, p, np.empty(size["y"]))
        if check is not None and size["y"] and np.isnan(y[0]):
            check(t, x, u, y)
        return y

    updfcn = None
    if update is not None:
        def updfcn(t, x, u, _params):
            x, u = inputs_and_state(x, u)
            return update(t, x, u, p, np.empty(size["x"]))

    sys = ct.nlsys(updfcn, outfcn, **nlsys_kwargs)
    size.update(y=sys.noutputs, x=sys.nstates, u=sys.ninputs, name=sys.name,
                states=sys.state_labels, inputs=sys.input_labels)
    sys.kernels = None if uncompiled else BlockKernels(output, update, p, bool(feedthrough))
    sys.kernel_check = check
    if uncompiled:
        sys.kernel_reason = uncompiled
    return sys


def _describe(labels) -> str:
    if not labels:
        return "none"
    if len(labels) <= 6:
        return ", ".join(labels)
    return f"{labels[0]}, {labels[1]}, ..., {labels[-1]}"
