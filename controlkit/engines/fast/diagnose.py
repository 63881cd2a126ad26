"""Why a run stopped, in the words of the block that stopped it; and how each block runs
(:func:`explain`, the tiers of :mod:`.tiers` and a compiled module's verdict).

Compiled kernels signal failure with NaN (block contract, rule 6). When a run stops on
one, the failing step is evaluated again as Python, so that the block's python-control
function raises its own message (the one the python-control path gives); a state that
became non-finite is the loop diverging, said with the block and the time.
"""

from __future__ import annotations

import control as ct
import numpy as np

from ... import _checks, _jit
from ..contract import UnsupportedSystem
from . import store
from .plan import evaluation_order
from .run import compiled_job
from .tiers import (
    LONE_TRANSFER_FUNCTION,
    BlockTier,
    NotCompiled,
    _resolve,
    as_interconnect,
    blocks_of,
)


def signals_at(job, t, x, u, k):
    """Every block's inputs and outputs ``(ui, ys)`` of ``job``'s diagram at ``(t, x)``
    with the diagram's inputs ``u`` (instant ``k``; -1 between instants), as Python.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> gain = ct.ss([], [], [], [[2.0]], name="k", inputs="e", outputs="y")
    >>> job = prepare(ct.interconnect([gain], inputs="e", outputs="y"))
    >>> signals_at(job, 0.0, np.zeros(0), np.array([1.5]), 0)[1].tolist()
    [3.0]
    """
    plan = job.plan
    ys, ui, held = np.zeros(plan.ny), np.zeros(plan.nu), np.zeros(plan.ny)
    U = np.asarray(u, dtype=float).reshape(-1, 1)
    with np.errstate(all="ignore"):  # evaluated where it failed: the error below says why
        job.functions().evaluate(t, np.asarray(x, dtype=float), U, 0, job.P, ys, ui, held, k)
    return ui, ys


def explain_failure(job, t, x, u, block_index, k=0):
    """A kernel returned NaN (a user's function: inf too) at ``t``: let the block's own
    function say why.

    Raises
    ------
    Exception
        The block's own error (a controlkit block's ``check``), else
        ``FloatingPointError`` naming it and the time.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> bad = ct.nlsys(None, lambda t, x, u, p: np.log(u - 2.0), inputs=1, outputs=1,
    ...                dt=1, name="bad")
    >>> job = prepare(ct.interconnect([bad], inputs="u[0]", outputs="y[0]"))
    >>> try:
    ...     explain_failure(job, 0.0, np.zeros(0), np.ones(1), 0)
    ... except FloatingPointError as error:
    ...     print(error)
    block 'bad' returned NaN at t = 0 s
    """
    b = job.blocks[int(block_index)]
    block = b.system
    if not np.isfinite(x).all():  # the loop diverged before the block's output did
        raise diverged(job, t, x)
    with np.errstate(all="ignore"):
        if not job.plan.held:  # python-control's own evaluation, as its path would
            try:
                job.sys.output(t, x, u)
            except RuntimeError as error:  # its sweep cannot settle on non-finite signals
                if isinstance(error, _checks.Diverged):
                    raise  # (a block's own words)
        ui, ys = signals_at(job, t, x, u, k)
        inputs = ui[b.u0:b.u0 + block.ninputs]
        if np.isfinite(inputs).all():  # the block's own words
            block.output(t, x[b.x0:b.x0 + block.nstates], inputs)
    returned = ys[b.y0:b.y0 + block.noutputs]
    bad = returned[np.isinf(returned)]  # (a NaN otherwise)
    raise _checks.Diverged(f"block {block.name!r} returned {f'{bad[0]:g}' if bad.size else 'NaN'}"
                           f" at t = {t:g} s")


def diverged(job, t, x) -> _checks.Diverged:
    """The error of a loop whose state became non-finite at ``t`` (``x``: the state then),
    naming the first block whose state did.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> grow = ct.nlsys(lambda t, x, u, p: 2 * x, None, states=1, inputs=0, outputs=1,
    ...                 dt=1, name="grow")
    >>> job = prepare(ct.interconnect([grow], outputs="y[0]"))
    >>> str(diverged(job, 1.0, np.array([np.inf])))[:32]
    'the loop diverged at t = 1 s: th'
    """
    bad = ~np.isfinite(np.asarray(x, dtype=float))
    i = int(np.argmax(bad))
    block = next((b for b in job.blocks if b.x0 <= i < b.x0 + b.system.nstates), job.blocks[0])
    return _checks.diverged(t, f"the state of block {block.system.name!r} became non-finite")


def sampled_block_blew_up(job, t, x, u, k, after=None):
    """A sampled block (RK4 inside a sample) whose state became non-finite says so in
    its own words (:class:`controlkit.blocks.sampling.SamplingError`), from the finite
    state ``x`` at the step before; nothing when none did. ``after`` is the state at the
    next step: only the block whose state went non-finite first is asked (another's
    blow-up is the loop diverging).

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import prepare
    >>> gain = ct.ss([], [], [], [[2.0]], name="k", inputs="e", outputs="y")
    >>> job = prepare(ct.interconnect([gain], inputs="e", outputs="y"))
    >>> sampled_block_blew_up(job, 0.0, np.zeros(0), np.ones(1), 0) is None
    True
    """
    ui, _ = signals_at(job, t, x, u, k)
    if not np.isfinite(ui).all():
        return
    first = None if after is None else int(np.argmax(~np.isfinite(after)))
    for b in job.blocks:
        if first is not None and not b.x0 <= first < b.x0 + b.system.nstates:
            continue
        if b.kernel.rk4 is not None and b.system.nstates:
            s = b.system
            with np.errstate(all="ignore"):
                s.dynamics(t, x[b.x0:b.x0 + s.nstates], ui[b.u0:b.u0 + s.ninputs])


def explain(sys, params=None) -> list[BlockTier]:
    """How the fast engine runs each block of ``sys``: its tier and the reason.

    Tiers (:data:`.tiers.TIERS`): ``"compiled"`` (the block's functions read as code numba
    compiles with Python's numbers: the diagram runs compiled when every block can, and
    :data:`RULE` says when; numba's own verdict comes with the first compile, kept in the
    store, and is said from then on), ``"python"`` (the
    block runs as Python, and with it the whole diagram: the reason says why; also every
    block of a diagram whose compiled module gave other numbers than Python, or did not
    compile) and ``"python-control"`` (the whole diagram falls back to
    :func:`control.input_output_response`; the reason says why).

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
    >>> plant = ct.nlsys(lambda t, x, u, p: x + 0.1 * (u - p.get("a", 1.0) * x[0] ** 3),
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
    if isinstance(sys, ct.TransferFunction):  # (its conversion may even need slycot)
        return [BlockTier(sys.name, "python-control", LONE_TRANSFER_FUNCTION)]
    try:
        sys = as_interconnect(sys)  # a single block runs as a one-block diagram
        evaluation_order(sys, blocks_of(sys, params))
    except UnsupportedSystem as why:
        return [BlockTier(s.name, "python-control", str(why))
                for s in getattr(sys, "syslist", [sys])]
    rows = []
    for block in sys.syslist:
        try:
            _, tier, reason = _resolve(sys, block, params, compiled=True)
        except NotCompiled as why:
            tier, reason = "python", str(why).split(": ", 1)[-1]
        except store.StoreRefused as why:
            tier, reason = "python", str(why)
        if tier == "compiled" and not _jit.available():
            tier, reason = "python", reason + " (numba not installed: the loop runs as Python)"
        rows.append(BlockTier(block.name, tier, reason))
    job = compiled_job(sys, params) if all(r.tier == "compiled" for r in rows) else None
    if isinstance(job, str):  # its compiled module differed from Python, or failed
        rows = [BlockTier(r.name, "python", f"{r.reason}; but the diagram runs as Python: "
                                            f"{job}") for r in rows]
    return rows
