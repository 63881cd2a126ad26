"""The block contract: a ``NonlinearIOSystem`` whose equations are kernels.

A controlkit block is an ordinary python-control system whose equations are
*kernels*: plain functions that both the python-control path and the fast
engine (:mod:`controlkit.engines.fast`) call, so that both compute the same
numbers. :class:`KernelBlock` is that system; its docstring lists the rules a
block follows to compile. :func:`layout` names the entries of a packed vector
(parameters, states, inputs) once, for kernels and blocks alike.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import control as ct
import numpy as np

from .. import _checks
from ..kernels.layout import layout  # noqa: F401  (re-exported: blocks and kernels share it)


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
        :func:`~controlkit.blocks.sampling.sample_nlsys`.
    repack : callable, optional
        ``repack(local_params) -> p`` for a block whose ``p`` is packed from
        python-control's ``params`` (a user's function): the vector for other values,
        or None when they would change the compiled code (a value of another type or
        shape). None for a block whose parameters were bound when it was built.

    Examples
    --------
    >>> from controlkit.blocks.common import lowpass_filter
    >>> k = lowpass_filter(tau=1.0, Ts=0.1).kernels
    >>> k.output.__name__, k.update.__name__, k.feedthrough
    ('state_output', 'lowpass_update', False)
    >>> k.sampled(0.1, 2).rk4
    (0.1, 2)
    """

    output: Callable
    update: Callable | None
    params: np.ndarray
    feedthrough: bool
    rk4: tuple[float, int] | None = None
    repack: Callable | None = None

    def sampled(self, Ts: float, substeps: int) -> BlockKernels:
        """The same kernel under ZOH with ``substeps`` RK4 steps per period ``Ts``."""
        return replace(self, rk4=(float(Ts), int(substeps)))


class KernelBlock(ct.NonlinearIOSystem):
    """A ``NonlinearIOSystem`` whose equations are compiled kernels: the block contract.

    The block calls its kernels from python-control's ``(t, x, u, params)``
    functions, and the fast engine calls the same kernels from its compiled loop,
    so the two paths compute the same numbers. To compile, a block follows these
    rules; the ones marked *checked* are enforced where they can be.

    **Kernels.**

    1. A kernel is a function ``f(t, x, u, p, out) -> out``, best at a module's
       level. The engine hands it to the module it generates and names it there by
       its name, a digest of its module's source and one of what it runs (the
       values of its closure and of the globals it reads, the helpers it calls:
       a kernel made by a factory with other values, or a helper edited since, is
       compiled anew: *checked* by the engine). The
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
       :func:`controlkit.blocks.sampling.sample_nlsys` with ``method="rk4"``: its update
       kernel is then the right-hand side ``x'`` that both paths hand to
       :func:`controlkit.kernels.common.rk4_step`.
    10. Inputs and states are checked once, at the block's boundary: called with
        the wrong number of inputs or states, the block raises a ``ValueError``
        naming itself, the argument and the expected size (*checked* by the
        wrappers of :class:`KernelBlock`), so the compiled kernels can trust them.

    **Failures.**

    11. A block that can signal failure passes ``check=``: a function
        ``check(t, x, u, y)`` that the wrapper calls when ``y[0]`` is NaN and that
        raises an exception saying why in the user's terms (the attitude, the
        angle, the value that vanished). It tells divergence (non-finite or
        absurdly large signals coming in: a loop that blew up, most often a gain
        too high for the sample time) from a genuine singularity of the equation.
        The fast engine stops at the first NaN and calls the same check, so both
        paths report a failure in the same words.
    12. A block whose states must satisfy a condition (a unit quaternion) passes
        ``check_state=``: a function ``check_state(label, x0)`` raising a
        ``ValueError`` that names ``label`` ("initial state of block 'plant'") when an
        initial state breaks it. :func:`controlkit.simulation.initial_state` and both
        engines' argument checks call it (:func:`check_initial_state`).
    13. A block whose equations call Python objects (a user's function) passes
        ``uncompiled=`` with the reason; the fast engine then calls its Python
        functions inside its own loop (the ``python`` tier of
        :func:`controlkit.engines.fast.explain`, which also gives that reason).

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
        objects); the block then has ``kernels = None`` and the reason in
        ``uncompiled_reason``.
    check_state : callable, optional
        ``check_state(label, x0)``, raising a ``ValueError`` naming ``label`` when
        ``x0`` is not a valid initial state (rule 12).
    x0 : array_like, optional
        The block's natural initial state (e.g. the FRIT tuner's ``P(0) = gamma I``),
        used by :func:`controlkit.simulation.initial_state` when none is given.
    **nlsys_kwargs
        ``inputs``, ``outputs``, ``states``, ``dt``, ``name`` for
        :class:`control.NonlinearIOSystem`.

    Attributes
    ----------
    kernels : BlockKernels or None
        What the fast engine runs (None with ``uncompiled``).
    check : callable or None
        As given.
    uncompiled_reason : str or None
        As given in ``uncompiled``.
    check_state : callable or None
        As given.
    x0 : numpy.ndarray
        The natural initial state (zeros unless given).

    Examples
    --------
    >>> from controlkit.kernels.common import constant_output
    >>> KernelBlock(constant_output, params=[1.0, 2.0], feedthrough=False, inputs=0,
    ...             outputs=2, dt=None).output(0.0, [], []).tolist()
    [1.0, 2.0]
    >>> from controlkit.blocks.spacecraft import io_linearizer
    >>> try:
    ...     io_linearizer().output(0.0, [], [1e-3, 0.0, 1.0])  # q forgotten
    ... except ValueError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    block 'linearizer': the input u must have 6 values
    (mu[0], mu[1], q[0], q[1], q[2], q[3]), got shape (3,)
    """

    def __init__(self, output, update=None, *, params=(), feedthrough=True, check=None,
                 uncompiled=None, x0=None, check_state=None, **nlsys_kwargs):
        p = np.array(params, dtype=float).reshape(-1)
        outfcn = self._wrap(output, p, check, output=True)
        updfcn = None if update is None else self._wrap(update, p, None, output=False)
        super().__init__(updfcn, outfcn, **nlsys_kwargs)
        self.feedthrough = bool(feedthrough)  # (rule 8; also when it runs as Python)
        self.kernels = None if uncompiled else BlockKernels(output, update, p,
                                                            self.feedthrough)
        self.check = check
        self.check_state = check_state
        self.uncompiled_reason = uncompiled
        self.x0 = np.zeros(self.nstates) if x0 is None else np.array(x0, dtype=float)

    def _wrap(self, kernel, p, check, output):
        """python-control's ``f(t, x, u, params)`` around ``kernel`` (rule 10's checks)."""

        def function(t, x, u, _params):
            x = self._checked("state x", x, self.nstates, self.state_labels)
            u = self._checked("input u", u, self.ninputs, self.input_labels)
            # a kernel says itself where it fails (NaN, rule 6; its check says why), as
            # compiled, so numpy's overflow warnings are not the block's words
            with np.errstate(over="ignore", invalid="ignore"):
                out = kernel(t, x, u, p, np.empty(self.noutputs if output else self.nstates))
            if check is not None and self.noutputs and np.isnan(out[0]):
                check(t, x, u, out)
            return out

        return function

    def _checked(self, arg, value, n, labels):
        value = _checks.float_array(f"block {self.name!r}: the {arg}", value)
        if value.shape != (n,):
            raise ValueError(f"block {self.name!r}: the {arg} must have {n} values "
                             f"({_describe(labels)}), got shape {value.shape}")
        return value


def check_initial_state(sys, x0) -> None:
    """Refuse an initial state that a block of ``sys`` declares invalid (rule 12).

    Each block with a ``check_state`` (a nested interconnect's blocks, a sampled
    block's continuous one too) is handed its part of ``x0``.

    Raises
    ------
    ValueError
        Naming the block, from its ``check_state``.

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> check_initial_state(spacecraft_plant(), [1.0, 0.0, 0.0, 0.0])
    >>> check_initial_state(spacecraft_plant(), [0.0, 0.0, 0.0, 0.0])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: initial state of block 'plant' must be a unit quaternion ... got norm 0; ...
    """
    x0 = np.asarray(x0, dtype=float).reshape(-1)
    blocks = getattr(sys, "syslist", None)
    if blocks is None:
        check = getattr(sys, "check_state", None)
        if check is not None:
            check(f"initial state of block {sys.name!r}", x0)
        return
    offset = 0
    for block in blocks:
        check_initial_state(block, x0[offset:offset + block.nstates])
        offset += block.nstates


def _describe(labels) -> str:
    if not labels:
        return "none"
    if len(labels) <= 6:
        return ", ".join(labels)
    return f"{labels[0]}, {labels[1]}, ..., {labels[-1]}"


def drawn_as(sys, symbol, *, default_name, junction=None):
    """Give a factory's block the symbol the papers draw it with, if it keeps its default name.

    :func:`~controlkit.drawing.draw_block_diagram` writes a block's ``display_name``
    (TeX) in its box, with the block's name under it, and draws a block's ``junction``
    (``{input base name: sign}``: the block first forms ``r - h``, say) as a summing
    junction in front of it. A block that its user named (``name="wheel_limit"``) is
    someone else's element, so it is drawn with that name alone: the factory's symbol
    would claim it is the paper's.

    Parameters
    ----------
    sys : control.InputOutputSystem
        The block, as the factory built it.
    symbol : str
        Its symbol in the papers, e.g. ``"$F$"``.
    default_name : str
        The factory's default ``name``.
    junction : dict, optional
        The signs of the inputs the block sums first, e.g. ``{"r": 1, "h": -1}``.

    Returns
    -------
    control.InputOutputSystem
        ``sys``, with ``display_name`` (and ``junction``) set when ``sys.name`` is
        ``default_name``.

    Examples
    --------
    >>> import control as ct
    >>> gain = ct.nlsys(None, lambda t, x, u, p: u, inputs=1, outputs=1, name="gain")
    >>> drawn_as(gain, "$K$", default_name="gain").display_name
    '$K$'
    >>> other = ct.nlsys(None, lambda t, x, u, p: u, inputs=1, outputs=1, name="mine")
    >>> getattr(drawn_as(other, "$K$", default_name="gain"), "display_name", None) is None
    True
    """
    if sys.name == default_name:
        sys.display_name = symbol
        if junction is not None:
            sys.junction = dict(junction)
    return sys
