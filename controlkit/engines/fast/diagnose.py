"""Why a compiled run stopped: the blocks' own words for a NaN or a blow-up.

Compiled kernels signal failure with NaN (block contract, rule 6). When a run
stops on one, these functions replay the failing step through python-control's
own evaluation so that the block's Python wrapper raises its message, the same
one the python-control path gives.
"""

from __future__ import annotations

import numpy as np

from ... import _checks


def explain_divergence(sys, blocks, T, X, x, k1, U, params=None):
    """A state became non-finite: a sampled block that blew up inside its sample says so
    (as on the python-control path), otherwise the loop diverged.

    Raises
    ------
    FloatingPointError or controlkit.blocks.sampling.SamplingError
        Always, naming the block whose state became non-finite and the time.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.tiers import blocks_of
    >>> grow = ct.nlsys(lambda t, x, u, p: 2 * x, None, states=1, inputs=0, outputs=1,
    ...                 dt=1, name="grow")
    >>> loop = ct.interconnect([grow], outputs="y[0]")
    >>> X = np.array([[1.0, np.inf]])
    >>> try:
    ...     explain_divergence(loop, blocks_of(loop), np.arange(2.0), X, X[:, 1], 1,
    ...                        np.zeros((0, 2)))
    ... except FloatingPointError as error:
    ...     print(str(error)[:32])
    the loop diverged at t = 1 s: th
    """
    bad = ~np.isfinite(np.column_stack([X[:, :k1], x]))
    k = int(np.argmax(bad.any(axis=0)))
    i = int(np.argmax(bad[:, k]))
    b = next(b for b in blocks if b.x0 <= i < b.x0 + b.system.nstates)
    if k >= 1 and b.kernel.rk4 is not None and np.isfinite(X[:, k - 1]).all():
        # the Python step of that sample, with its blow-up test (raises SamplingError)
        sys._update_params(params)
        try:
            with np.errstate(all="ignore"):  # the error raised below says what went wrong
                ulist, _ = sys._compute_static_io(T[k - 1], X[:, k - 1], U[:, k - 1])
        except RuntimeError:
            ulist = None
        if ulist is not None and np.isfinite(ulist).all():
            s = b.system
            with np.errstate(all="ignore"):
                s._rhs(T[k - 1], X[b.x0:b.x0 + s.nstates, k - 1], ulist[b.u0:b.u0 + s.ninputs])
    t = T[k] if k < len(T) else T[-1] + (T[-1] - T[-2] if len(T) > 1 else 0.0)
    raise _checks.diverged(t, f"the state of block {b.system.name!r} became non-finite")


def explain_failure(sys, blocks, T, X, U, status, params=None):
    """A kernel returned NaN: let the block's Python wrapper say why, in its own words.

    ``status`` is ``[k, i]``: the step and the index of the block whose output was NaN.

    Raises
    ------
    Exception
        The block's own error (its ``check``), else ``FloatingPointError`` naming it.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.tiers import blocks_of
    >>> bad = ct.nlsys(None, lambda t, x, u, p: np.log(u - 2.0), inputs=1, outputs=1,
    ...                dt=1, name="bad")
    >>> loop = ct.interconnect([bad], inputs="u[0]", outputs="y[0]")
    >>> try:
    ...     explain_failure(loop, blocks_of(loop), np.arange(2.0), np.zeros((0, 2)),
    ...                     np.ones((1, 2)), np.array([0, 0]))
    ... except FloatingPointError as error:
    ...     print(error)
    block 'bad' returned NaN at t = 0 s
    """
    k = int(status[0])
    b = blocks[int(status[1])]
    block = b.system
    sys._update_params(params)
    # the loop is evaluated where it failed, on non-finite signals: numpy's warnings there
    # say nothing the error raised here does not
    with np.errstate(all="ignore"):
        try:
            ulist, _ = sys._compute_static_io(T[k], X[:, k], U[:, k])
        except RuntimeError:  # python-control's sweep cannot settle on non-finite signals
            ulist = None
        if ulist is not None:
            block.output(T[k], X[b.x0:b.x0 + block.nstates, k],
                         ulist[b.u0:b.u0 + block.ninputs])
    if not np.isfinite(X[:, k]).all():  # the loop diverged before the block's output did
        explain_divergence(sys, blocks, T, X, X[:, k], k, U, params)
    raise FloatingPointError(f"block {block.name!r} returned NaN at t = {T[k]:g} s")


def explain_nan(sys, blocks, t, index):
    """A block's output was NaN during a continuous run: name it and the time.

    Raises
    ------
    FloatingPointError
        Always.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> block = SimpleNamespace(system=SimpleNamespace(name="sqrt"))
    >>> try:
    ...     explain_nan(None, [block], 1.5, 0)
    ... except FloatingPointError as error:
    ...     print(error)
    block 'sqrt' returned NaN at t = 1.5 s
    """
    raise FloatingPointError(f"block {blocks[index].system.name!r} returned NaN at "
                             f"t = {t:g} s")
