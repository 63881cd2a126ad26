"""What each block of a diagram computes, and whether it can be compiled: its tier.

Every block of a diagram gets :class:`BlockKernels` and one of :data:`TIERS`:
controlkit blocks and LTI blocks bring kernels that compile; a user's ``nlsys`` is
compiled from its source where it can be (:mod:`.usercode`); anything else is called
as Python. A diagram runs compiled only when every block can be; otherwise the whole
diagram runs as Python, the same module (:mod:`.run`). A system the engine does not
know sends the diagram to python-control. :func:`explain` lists the result.
"""

from __future__ import annotations

import numbers
import warnings
from dataclasses import dataclass
from typing import NamedTuple

import control as ct
import numpy as np

from ... import _jit
from ...blocks.contract import BlockKernels, KernelBlock
from ...blocks.sampling import SampledSystem
from ...compat import SYSTEM_CALLS
from ...kernels import common, lti
from .. import _keep_on, _kept_on, source
from ..contract import UnsupportedSystem
from . import usercode


@dataclass(frozen=True)
class PlacedBlock:
    """A block of a diagram with its kernels, tier and offsets in the stacked vectors.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> [(b.system.name, b.x0) for b in blocks_of(cmg_loop())]
    [('reference', 0), ('cmg', 0), ('smc', 6), ('saturation', 10)]
    """

    index: int
    system: object
    kernel: object
    x0: int  # state offset
    u0: int  # offset in the list of all subsystem inputs
    y0: int  # offset in the list of all subsystem outputs
    p0: int  # parameter offset
    tier: str = "compiled"
    reason: str = ""


#: The tiers a block can get, fastest first (see :func:`explain`).
TIERS = ("compiled", "python", "python-control")


class BlockTier(NamedTuple):
    """How the fast engine runs one block: ``tier`` is one of :data:`TIERS`.

    Examples
    --------
    >>> row = BlockTier("pi", "compiled", "LTI block (state space)")
    >>> row.tier
    'compiled'
    """

    name: str
    tier: str
    reason: str


def _local_params(sys, block, params):
    """The parameters python-control hands ``block`` inside ``sys`` (see its _update_params)."""
    local = dict(block.params)
    local.update(sys.params)
    if params:
        local.update(params)
    return local


def _probe_feedthrough(block, output, p):
    """Whether ``block``'s kernel ``output(t, x, u, p, out)`` moves with ``u`` at random
    trial points (True where it cannot be evaluated there, or gives a non-finite value,
    which says nothing about ``u``: the safe answer; ``log(u[0] - 2)`` is NaN at every
    trial point)."""
    nx, nu, ny = block.nstates, block.ninputs, block.noutputs
    if nu == 0 or ny == 0:
        return False
    rng = np.random.default_rng(1)
    for _ in range(3):
        x = rng.uniform(-1, 1, nx)
        u = rng.uniform(-1, 1, nu)
        try:  # trial points of ours: what numpy or the function warns there is not the user's
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                a = np.array(output(0.0, x, np.zeros(nu), p, np.empty(ny)), dtype=float)
                b = np.array(output(0.0, x, u, p, np.empty(ny)), dtype=float)
        except Exception:  # noqa: BLE001 - undefined at this point
            return True
        if not (np.isfinite(a).all() and np.isfinite(b).all()) or not np.array_equal(a, b):
            return True
    return False


def _feeds_through(system) -> bool:
    """Whether ``system``'s output may move with its input at the same instant, read from
    its structure: an LTI block's ``D``, a user function's source (whether it reads ``u``),
    a nested interconnect's paths through such blocks. True where it cannot be told (a
    function whose source is not available): a trial of the function at some points
    cannot tell (a dead zone of width 1 at inputs within 1, a switch on the time), and
    the block that reads it would be computed a step late (python-control repeats its
    pass over the blocks until the signals settle, so its order never matters)."""
    if system.ninputs == 0 or system.noutputs == 0:
        return False
    if isinstance(system, KernelBlock):
        return system.feedthrough  # declared (the block contract's rule 8)
    if isinstance(system, SampledSystem):
        return _feeds_through(system.continuous)
    if isinstance(system, ct.StateSpace):
        return bool(np.any(system.D != 0))
    if isinstance(system, ct.InterconnectedSystem):
        inputs = np.any(system.input_map != 0, axis=1)  # the blocks' inputs it moves
        outputs = np.zeros(system.connect_map.shape[1], dtype=bool)
        feeds = [_feeds_through(s) for s in system.syslist]
        for _ in range(len(system.syslist) + 1):
            u0 = y0 = 0
            for sub, feed in zip(system.syslist, feeds, strict=True):
                if feed and inputs[u0:u0 + sub.ninputs].any():
                    outputs[y0:y0 + sub.noutputs] = True
                u0, y0 = u0 + sub.ninputs, y0 + sub.noutputs
            inputs = inputs | np.any(system.connect_map[:, outputs] != 0, axis=1)
        read = np.concatenate([outputs, inputs])  # its outputs read blocks' outputs, inputs
        return bool(np.any(system.output_map[:, read] != 0))
    if isinstance(system, ct.NonlinearIOSystem):
        if system.outfcn is None:
            return False  # its output is its state
        return source.reads_input(system.outfcn) is not False
    return True


class NotCompiled(Exception):
    """A block that cannot be compiled (the message names it and says why).

    Examples
    --------
    >>> str(NotCompiled("block 'plant': it calls print()"))
    "block 'plant': it calls print()"
    """


def _python_kernels(block, local, reason):
    """A block python-control runs itself, called through its public functions (one thread
    at a time: it keeps a call's ``params`` on itself, :data:`controlkit.compat.
    SYSTEM_CALLS`)."""
    def output(t, x, u, p, out):
        with SYSTEM_CALLS:
            out[:] = block.output(t, x, u, local)
        return out

    def update(t, x, u, p, out):
        with SYSTEM_CALLS:
            out[:] = block.dynamics(t, x, u, local)
        return out

    return (BlockKernels(output, update if block.nstates else None, np.zeros(0),
                         _feeds_through(block)), "python", reason)


def _changed_in_place(value, indexed) -> bool:
    """Whether an operator (``+=``) on what ``indexed`` integer indexes into ``value`` reach
    changes it in place: an array or a list (a row of a 2-D array), not a number."""
    for _ in range(indexed):  # (an element: a number, or a row)
        if not (isinstance(value, np.ndarray) and value.ndim and len(value)
                or isinstance(value, list | tuple) and value):
            return False
        value = value[0]
    return not (value is None or isinstance(value, numbers.Number | str | bytes | tuple
                                            | frozenset | np.generic))


def _user_kernels(block, local, compiled):
    """A user's ``nlsys``: its functions as Python kernels, or compiled from their source
    for the types of its parameters (their values packed into ``p`` at run time). One
    whose function has effects outside itself (a ``print``) or writes into its arguments
    is refused: python-control runs the diagram, so that it is called as many times, in
    the same order, on python-control's own arrays."""
    for fn in (block.outfcn, block.updfcn if block.nstates else None):
        effect = source.side_effect(fn) if fn is not None else None
        if effect is None and fn is block.outfcn and fn is not None:
            drawn = source.draws(fn)  # (an update is called once a step in both)
            effect = drawn and (f"its output function draws random numbers ({drawn}), "
                                f"which python-control calls several times a step")
        changed = [(key, text) for key, indexed, text in (
            source.params_changed(fn) if fn is not None else ()) if any(
            _changed_in_place(value, indexed) for value in (
                [local[key]] if key in local else local.values() if key is None else []))]
        if effect is None and changed:  # (the values in force decide: an array, a number)
            key, text = changed[0]
            which = f"the params value {key!r}" if key is not None else "a params value"
            effect = (f"it changes {which} in place ({text}), the block's own in "
                      f"python-control's run")
        if effect:
            raise UnsupportedSystem(f"block {block.name!r}: {effect}; python-control runs "
                                    f"the diagram, so that the block is called as many "
                                    f"times, in the same order, on the same arrays")
    output = (usercode.UserKernel(block.outfcn, local, block.name, "output")
              if block.outfcn is not None else None)
    update = (usercode.UserKernel(block.updfcn, local, block.name, "update")
              if block.nstates and block.updfcn is not None else None)
    feed = _feeds_through(block)
    if block.nstates and update is None:
        raise UnsupportedSystem(f"block {block.name!r} has states but no update function")
    mine = [k for k in (output, update) if k is not None]
    if not compiled:
        return (BlockKernels(output or common.state_output, update, np.zeros(0), feed),
                "python", "")
    try:
        layout = usercode.block_layout(mine, local)
        for k in mine:
            k.text(layout)
        params = layout.pack(local)
    except source.NotCompilable as why:
        raise NotCompiled(f"block {block.name!r}: {why}") from None

    def repack(values):
        try:
            if usercode.block_layout(mine, values).entries != layout.entries:
                return None
            return layout.pack(values)
        except source.NotCompilable:
            return None

    return (BlockKernels(output.compiled() if output else common.state_output,
                         update.compiled() if update else None, params, feed,
                         repack=repack),
            "compiled", "user nlsys compiled (parameters passed at run time)")


def _kernel_block(block, compiled):
    """A block of the block contract: its own kernels (plain Python ones are numba's to
    compile, or not); refused if declared without feedthrough while its output moves with
    its input."""
    kernels = block.kernels
    if not kernels.feedthrough and _probe_feedthrough(
            block, _jit.python_function(kernels.output), kernels.params):
        raise ValueError(
            f"block {block.name!r} is declared without feedthrough (feedthrough=False) but "
            f"its output changes with its input; declare feedthrough=True")
    functions = [f for f in (kernels.output, kernels.update) if f is not None]
    if compiled and not all(isinstance(f, _jit.Jitted) or hasattr(f, "py_func")
                            for f in functions):
        raise NotCompiled(f"block {block.name!r}: its kernels are plain Python functions "
                          f"(decorate them with controlkit._jit.jit to compile them)")
    return kernels, "compiled", "controlkit block"


def _sampled_kernels(sys, block, local, compiled):
    """A continuous block under ZOH: its own kernels (or its user functions) under RK4."""
    if block.method != "rk4":
        if compiled:
            raise NotCompiled(f"block {block.name!r} is sampled with solve_ivp")
        return _python_kernels(block, local, "sampled with solve_ivp")
    continuous = block.continuous
    if isinstance(continuous, KernelBlock) and continuous.kernels is not None:
        kernel, tier, reason = _kernel_block(continuous, compiled)
    else:
        kernel, tier, reason = _resolve(sys, continuous, {**continuous.params, **local},
                                        compiled, local=True)
    return (kernel.sampled(block.dt, block.substeps), tier, f"{reason}, sampled by RK4")


def _resolve(sys, block, params, compiled, local=False):
    """``(BlockKernels, tier, reason)`` for one block of ``sys`` (NotCompiled when
    ``compiled`` and it cannot be)."""
    if isinstance(block, KernelBlock) and block.kernels is not None:
        return _kernel_block(block, compiled)
    values = params if local else _local_params(sys, block, params)
    if isinstance(block, ct.StateSpace):  # (a transfer function is one in an interconnect)
        D = np.asarray(block.D, dtype=float)
        return (BlockKernels(lti.lti_output, lti.lti_update if block.nstates else None,
                             lti.pack(block.A, block.B, block.C, D), bool(D.any())),
                "compiled", "LTI block (state space)")
    if isinstance(block, SampledSystem):
        return _sampled_kernels(sys, block, values, compiled)
    if isinstance(block, ct.InterconnectedSystem) or isinstance(block, KernelBlock):
        reason = ("a nested interconnect" if isinstance(block, ct.InterconnectedSystem)
                  else block.uncompiled_reason)
        if compiled:
            raise NotCompiled(f"block {block.name!r}: {reason}")
        return _python_kernels(block, values, reason)
    if isinstance(block, ct.NonlinearIOSystem):
        return _user_kernels(block, values, compiled)
    raise UnsupportedSystem(f"block {block.name!r} cannot be run: a "
                            f"{type(block).__name__}, not an I/O system the engine knows")


#: Why a transfer function alone is python-control's (:func:`explain` and the run say it).
LONE_TRANSFER_FUNCTION = ("a transfer function alone, which python-control's "
                          "input_output_response refuses: ct.ss(sys) runs")


def as_interconnect(sys):
    """``sys`` itself if it is a diagram, else a one-block diagram around it.

    Examples
    --------
    >>> sys = ct.nlsys(lambda t, x, u, p: -x, None, inputs=1, states=1, outputs=1,
    ...                name="decay")
    >>> as_interconnect(sys).syslist[0] is sys
    True
    """
    if isinstance(sys, ct.InterconnectedSystem):
        return sys
    if not isinstance(sys, ct.InputOutputSystem):
        raise UnsupportedSystem(f"a {type(sys).__name__} is not an I/O system")
    kept, shape = _kept_on(sys, "_controlkit_one_block"), (  # (dt True is not dt 1)
        sys.name, repr(sys.dt), sys.nstates, tuple(sys.input_labels), tuple(sys.output_labels))
    if kept is not None and kept[0] == shape and kept[1].syslist[0] is sys:
        return kept[1]  # (whose prepared job is kept on it: a short run's most time)
    if isinstance(sys, ct.TransferFunction):  # as python-control's interconnect takes it
        return _one_block(ct.ss(sys, name=sys.name))
    wrapped = _one_block(sys)
    _keep_on(sys, "_controlkit_one_block", (shape, wrapped))
    return wrapped


def _one_block(sys):
    """A new one-block diagram around the system ``sys``."""
    for what, count in (("inputs", sys.ninputs), ("outputs", sys.noutputs),
                        ("states", sys.nstates)):
        if count is None:
            raise UnsupportedSystem(f"system {sys.name!r} does not declare its number of {what}")
    wrapped = ct.interconnect([sys], inputs=sys.input_labels, outputs=sys.output_labels,
                              name=sys.name, check_unused=False)
    wrapped.params = {}  # (its copy of the system's, kept, would hide their later values)
    # python-control hands a single system its inputs and outputs as they are, and an
    # interconnect's blocks numpy's products of its maps (a -0.0 becomes 0.0): codegen asks
    wrapped.single_system = True
    return wrapped


def blocks_of(sys, params=None, *, compiled=False):
    """The blocks of ``sys`` with their kernels, tiers and offsets.

    ``compiled``: the kernels compiled code calls (NotCompiled naming a block that
    cannot be compiled); else the kernels Python calls.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> [b.tier for b in blocks_of(cmg_loop(), compiled=True)]
    ['compiled', 'compiled', 'compiled', 'compiled']
    """
    if not isinstance(sys, ct.InterconnectedSystem):
        name = getattr(sys, "name", type(sys).__name__)
        raise UnsupportedSystem(f"{name!r} is a single block; the fast engine runs interconnects")
    blocks, xs, us, ys, ps = [], 0, 0, 0, 0
    for i, block in enumerate(sys.syslist):
        kernel, tier, reason = _resolve(sys, block, params, compiled)
        blocks.append(PlacedBlock(i, block, kernel, xs, us, ys, ps, tier, reason))
        xs += block.nstates
        us += block.ninputs
        ys += block.noutputs
        ps += kernel.params.size
    if xs != sys.nstates:  # (python-control builds it: `states=3` given for two)
        raise UnsupportedSystem(f"{sys.name!r} declares {sys.nstates} states where its blocks "
                                f"hold {xs}")
    return blocks


def same_kernels(blocks, others) -> bool:
    """Whether ``blocks`` have the very kernels of ``others`` (from :func:`blocks_of`), with
    equal parameters: a diagram's blocks with nothing of a user's, read to run compiled
    and to run as Python.

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> loop = cmg_loop()
    >>> same_kernels(blocks_of(loop), blocks_of(loop, compiled=True))
    True
    """
    return len(blocks) == len(others) and all(
        a.kernel.output is b.kernel.output and a.kernel.update is b.kernel.update
        and a.kernel.feedthrough == b.kernel.feedthrough and a.kernel.rk4 == b.kernel.rk4
        and np.array_equal(a.kernel.params, b.kernel.params)
        for a, b in zip(blocks, others, strict=True))
