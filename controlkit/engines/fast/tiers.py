"""How the fast engine runs each block: compiled, called from Python, or not at all.

Every block of a diagram gets :class:`BlockKernels` and one of :data:`TIERS`:
controlkit blocks and LTI blocks bring compiled kernels; a user's ``nlsys`` is
compiled from its source where it can be (:mod:`.usercode`), else its Python
functions are called from the generated loop; a system the engine does not know
sends the whole diagram to python-control. :func:`explain` lists the result.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import control as ct
import numpy as np

from ... import _jit
from ...blocks.contract import BlockKernels, KernelBlock
from ...blocks.sampling import SampledSystem
from ...kernels import common, lti
from .. import source
from ..contract import UnsupportedSystem
from . import usercode
from .codegen import evaluation_order
from .loader import cache_folder


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


def _probe_feedthrough(output, nx, nu, ny, on_error=True):
    """Whether ``output(t, x, u, out)`` moves with ``u`` at random trial points
    (``on_error`` where the output cannot be evaluated there)."""
    if nu == 0 or ny == 0:
        return False
    rng = np.random.default_rng(1)
    for _ in range(3):
        x = rng.uniform(-1, 1, nx)
        u = rng.uniform(-1, 1, nu)
        try:  # trial points of ours: what numpy or the function warns there is not the user's
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                a = np.array(output(0.0, x, np.zeros(nu), np.empty(ny)), dtype=float)
                b = np.array(output(0.0, x, u, np.empty(ny)), dtype=float)
        except Exception:  # undefined at this point
            return on_error
        if not np.array_equal(a, b, equal_nan=True):
            return True
    return False


def _python_kernels(block, local, reason):
    """Kernels calling ``block``'s own functions from Python, inside the engine's loop."""
    if isinstance(block, ct.InterconnectedSystem):  # a nested diagram: its own sweeps
        def output(t, x, u, p, out):
            block._update_params(local)
            out[:] = block._out(t, x, u)
            return out

        def update(t, x, u, p, out):
            block._update_params(local)
            out[:] = block._rhs(t, x, u)
            return out
        feed = None
    else:
        output = (usercode.python_kernel(block.outfcn, local) if block.outfcn is not None
                  else common.state_output)
        update = usercode.python_kernel(block.updfcn, local) if block.nstates else None
        feed = source.reads_input(block.outfcn) if block.outfcn is not None else False
    if not feed or isinstance(block, KernelBlock):
        # its source said no (or nothing): ask the function itself too, for the source
        # may not be what runs (a module file edited since it was imported; then the
        # compiled version differed from it, which is how the block came to this tier)
        feed = _probe_feedthrough(lambda t, x, u, out: output(t, x, u, None, out),
                                  block.nstates, block.ninputs, block.noutputs)
    return BlockKernels(output, update, np.zeros(0), feed), "python", reason


def _user_kernels(block, local, trial=None):
    """A user's ``nlsys``: compiled once for the types of its parameters, their values
    packed into ``p`` for this run; else called from Python.

    ``trial`` is ``(t, x, u)`` of the block at the start of the run, a point at which the
    compiled functions must agree with the Python ones (as at zero and random points).
    """
    folder = cache_folder()
    functions = [f for f in (block.outfcn, block.updfcn if block.nstates else None)
                 if f is not None]
    trials = [trial] if trial is not None else []
    try:
        plans = [source.plan_function(f) for f in functions]
        layout = usercode.ParamLayout.of(plans, local)
        output = common.state_output
        if block.outfcn is not None:
            output = usercode.compiled_kernel(block.outfcn, local, folder, block.noutputs,
                                              block.nstates, block.ninputs, layout=layout,
                                              trials=trials, plan=plans[0]).kernel
        update = None
        if block.nstates:
            update = usercode.compiled_kernel(block.updfcn, local, folder, block.nstates,
                                              block.nstates, block.ninputs, layout=layout,
                                              trials=trials, plan=plans[-1]).kernel
        params = layout.pack(local)
    except source.NotCompilable as why:
        return _python_kernels(block, local, f"user function not compiled: {why}")
    except Exception as error:  # noqa: BLE001 - never worse than running it as Python
        return _python_kernels(block, local, f"user function not compiled: "
                                             f"{type(error).__name__}: {error}")
    feed = source.reads_input(block.outfcn) if block.outfcn is not None else False
    if feed is None:
        feed = True
    def repack(values):
        try:
            if usercode.ParamLayout.of(plans, values).entries != layout.entries:
                return None
            return layout.pack(values)
        except source.NotCompilable:
            return None

    return (BlockKernels(output, update, params, feed, repack=repack), "compiled",
            "user nlsys compiled (parameters passed at run time)")


def _lti_kernels(block):
    """Any ``StateSpace`` (a transfer function is one inside an interconnect)."""
    D = np.asarray(block.D, dtype=float)
    return (BlockKernels(lti.lti_output, lti.lti_update if block.nstates else None,
                         lti.pack(block.A, block.B, block.C, D), bool(D.any())),
            "compiled", "LTI block (state space)")


def _sampled_kernels(sys, block, local, trial=None):
    """A continuous block under ZOH: its own kernels (or its user functions) under RK4."""
    if block.method != "rk4":
        return _python_kernels(block, local, "sampled with solve_ivp")
    continuous = block.continuous
    if isinstance(continuous, KernelBlock) and continuous.kernels is not None:
        kernel, tier, reason = _resolve(sys, continuous, None)
    else:
        kernel, tier, reason = _resolve_with(continuous, {**continuous.params, **local}, trial)
    return (kernel.sampled(block.dt, block.substeps), tier, f"{reason}, sampled by RK4")


def _resolve_with(block, local, trial=None):
    """A block that is not a controlkit block, given the parameters it is handed."""
    if isinstance(block, ct.InterconnectedSystem):
        return _python_kernels(block, local, "a nested interconnect")
    if isinstance(block, KernelBlock):  # one whose kernels call Python objects
        return _python_kernels(block, local, block.uncompiled_reason)
    return _user_kernels(block, local, trial)


def _resolve(sys, block, params, trial=None):
    """``(BlockKernels, tier, reason)`` for one block of ``sys`` (``trial``: the block's
    ``(t, x, u)`` at the start of the run, when known)."""
    if isinstance(block, KernelBlock) and block.kernels is not None:
        _check_feedthrough(block, block.kernels)
        return block.kernels, "compiled", "controlkit block"
    local = _local_params(sys, block, params)
    if isinstance(block, ct.StateSpace):
        return _lti_kernels(block)
    if isinstance(block, SampledSystem):
        return _sampled_kernels(sys, block, local, trial)
    if isinstance(block, ct.NonlinearIOSystem):
        return _resolve_with(block, local, trial)
    raise UnsupportedSystem(f"block {block.name!r} cannot be compiled: "
                            f"a {type(block).__name__}, not an I/O system the engine knows")


def _check_feedthrough(block, kernel):
    """Refuse a block declared without feedthrough whose output moves with its input."""
    if kernel.feedthrough or not block.ninputs or not block.noutputs:
        return
    p = kernel.params
    sizes = block.nstates, block.ninputs, block.noutputs
    # asked of the kernel's Python function first: its compiled code would be loaded from
    # numba's cache for it (7 ms of a first call; the diagram's module has it compiled in)
    python = _jit.python_function(kernel.output)
    moves = _probe_feedthrough(lambda t, x, u, out: python(t, x, u, p, out), *sizes,
                               on_error=None)
    if moves is None:  # not evaluable as Python (numba's own features): the compiled one
        moves = _probe_feedthrough(lambda t, x, u, out: kernel.output(t, x, u, p, out),
                                   *sizes, on_error=False)
    if moves:
        raise ValueError(
            f"block {block.name!r} is declared without feedthrough (feedthrough=False) but "
            f"its output changes with its input; declare feedthrough=True")


def _has_user_functions(block) -> bool:
    """Whether ``block`` has user functions to compile (and check at the run's start)."""
    if isinstance(block, KernelBlock | ct.StateSpace | ct.InterconnectedSystem):
        return False  # controlkit's kernels, an LTI block's, or the python tier
    if isinstance(block, SampledSystem):
        return _has_user_functions(block.continuous)
    return isinstance(block, ct.NonlinearIOSystem)


def _start_points(sys, params, start):
    """Each block's ``(t, x, u)`` at the run's start ``(t0, X0, U0)``, by python-control's
    own evaluation of the diagram (None for every block where it cannot be evaluated)."""
    if start is None:
        return None
    t0, X0, U0 = start
    try:
        sys._update_params(params)
        ulist, _ = sys._compute_static_io(t0, np.asarray(X0, dtype=float),
                                          np.asarray(U0, dtype=float))
    except Exception:  # noqa: BLE001 - not evaluable there: the other trial points remain
        return None
    points, xs, us = [], 0, 0
    for block in sys.syslist:
        points.append((t0, X0[xs:xs + block.nstates], ulist[us:us + block.ninputs]))
        xs += block.nstates
        us += block.ninputs
    return points


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
    return ct.interconnect([sys], inputs=sys.input_labels, outputs=sys.output_labels,
                           name=sys.name, check_unused=False)


def blocks_of(sys, params=None, start=None):
    """The blocks of ``sys`` with their kernels, tiers and offsets (or UnsupportedSystem).

    ``start`` is the run's ``(t0, X0, U0)``: user functions compiled for the run must
    agree with their Python selves there too (see
    :func:`~controlkit.engines.fast.usercode.compiled_kernel`).

    Examples
    --------
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> [b.tier for b in blocks_of(cmg_loop())]
    ['compiled', 'compiled', 'compiled', 'compiled']
    """
    if not isinstance(sys, ct.InterconnectedSystem):
        name = getattr(sys, "name", type(sys).__name__)
        raise UnsupportedSystem(
            f"{name!r} is a single block; the fast engine runs interconnects")
    # evaluating the diagram calls every block: only where a user function is checked
    needed = start is not None and any(_has_user_functions(b) for b in sys.syslist)
    points = _start_points(sys, params, start) if needed else None
    blocks, xs, us, ys, ps = [], 0, 0, 0, 0
    for i, block in enumerate(sys.syslist):
        kernel, tier, reason = _resolve(sys, block, params,
                                        points[i] if points is not None else None)
        blocks.append(PlacedBlock(i, block, kernel, xs, us, ys, ps, tier, reason))
        xs += block.nstates
        us += block.ninputs
        ys += block.noutputs
        ps += kernel.params.size
    return blocks


def explain(sys, params=None) -> list[BlockTier]:
    """How the fast engine runs each block of ``sys``: its tier and the reason.

    Tiers (:data:`TIERS`): ``"compiled"`` (numba, in the generated loop),
    ``"python"`` (the block's own Python function called from the generated
    loop: no python-control sweeps, but slower) and ``"python-control"``
    (the whole diagram falls back to :func:`control.input_output_response`;
    the reason says why).

    Parameters
    ----------
    sys : control.InterconnectedSystem
        The diagram.
    params : dict, optional
        Parameters as for :func:`controlkit.simulation.simulate` (their types and
        shapes decide the code compiled for user functions; a value that compiled
        code cannot take, such as a string, sends its block to the ``python`` tier).

    Returns
    -------
    list of BlockTier
        ``(name, tier, reason)`` per block, in ``sys.syslist`` order.

    Raises
    ------
    ValueError
        ``sys`` is not a python-control system.

    Examples
    --------
    >>> import control as ct
    >>> pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi",
    ...                       inputs="e", outputs="u")
    >>> plant = ct.nlsys(lambda t, x, u, p: x + 0.1 * (u - p.get("a", 1.0) * x ** 3),
    ...                  lambda t, x, u, p: x, inputs="u", outputs="y", states=1,
    ...                  dt=0.1, name="plant")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, pi, error], inputs="r", outputs="y")
    >>> for row in explain(loop):
    ...     print(row.name, "|", row.tier, "|", row.reason)
    plant | compiled | user nlsys compiled (parameters passed at run time)
    pi | compiled | LTI block (state space)
    error | compiled | LTI block (state space)
    """
    if not isinstance(sys, ct.InputOutputSystem):
        raise ValueError(f"sys must be a python-control system (a block or an interconnect), "
                         f"got {type(sys).__name__} {sys!r:.60}"
                         + ("; call explain on each system of the list" if isinstance(
                             sys, list | tuple) else ""))
    try:
        sys = as_interconnect(sys)  # a single block runs as a one-block diagram
        blocks = blocks_of(sys, params)
        evaluation_order(sys, blocks)
    except UnsupportedSystem as why:
        return [BlockTier(s.name, "python-control", str(why))
                for s in getattr(sys, "syslist", [sys])]
    note = "" if _jit.HAVE_NUMBA else " (numba not installed: the loop runs as Python)"
    return [BlockTier(b.system.name, b.tier, b.reason + note) for b in blocks]
