"""Kernels of linear time-invariant blocks: any ``control.StateSpace`` in a diagram.

python-control turns a transfer function into its state-space realisation
when it joins an interconnect, so every LTI block of a diagram is a
``StateSpace`` ``x[k+1] = A x[k] + B u[k]``, ``y[k] = C x[k] + D u[k]``.
One pair of kernels runs all of them: the matrices are packed row-major
into ``p`` after the three sizes, by :func:`pack`.

Signature and rules: see the block contract in :class:`controlkit.blocks.contract.KernelBlock`.
"""

from __future__ import annotations

import numpy as np

from .._jit import jit

#: Offsets of the sizes at the head of the packed vector.
_N, _M, _Q, _HEAD = 0, 1, 2, 3


def pack(A, B, C, D) -> np.ndarray:
    """``[n, m, q, A, B, C, D]`` (row-major) for the kernels of a block with n states.

    Examples
    --------
    >>> pack([[0.5]], [[1.0]], [[2.0]], [[0.0]]).tolist()
    [1.0, 1.0, 1.0, 0.5, 1.0, 2.0, 0.0]
    """
    A, B, C, D = (np.atleast_2d(np.asarray(a, dtype=float)) for a in (A, B, C, D))
    n, m, q = A.shape[0] if A.size else 0, D.shape[1], D.shape[0]
    A, B, C = A.reshape(n, n), B.reshape(n, m), C.reshape(q, n)
    return np.concatenate([[n, m, q], A.ravel(), B.ravel(), C.ravel(), D.ravel()])


@jit(inline=True)
def _affine(p, first, second, rows, x, u, out):
    """``out = F x + G u`` with ``F`` (``rows`` x n) at ``p[first:]`` and ``G`` (``rows`` x m)
    at ``p[second:]``, row-major: the two products summed as numpy's ``F @ x + G @ u`` does,
    so the engine and python-control's LTI path give the same numbers."""
    n, m = x.shape[0], u.shape[0]
    for i in range(rows):
        fx = 0.0
        for j in range(n):
            fx += p[first + i * n + j] * x[j]
        gu = 0.0
        for j in range(m):
            gu += p[second + i * m + j] * u[j]
        out[i] = fx + gu
    return out


@jit(inline=True)
def lti_output(t, x, u, p, out):
    """``y = C x + D u`` with ``p`` from :func:`pack`.

    Examples
    --------
    >>> p = pack([[0.5]], [[1.0]], [[2.0]], [[3.0]])
    >>> lti_output(0.0, np.array([1.0]), np.array([1.0]), p, np.empty(1)).tolist()
    [5.0]
    """
    n, m, q = int(p[_N]), int(p[_M]), int(p[_Q])
    c0 = _HEAD + n * n + n * m
    return _affine(p, c0, c0 + q * n, q, x, u, out)


@jit(inline=True)
def lti_update(t, x, u, p, out):
    """``x[k+1] = A x + B u`` (or ``x' = A x + B u`` when sampled) with ``p`` from :func:`pack`.

    Examples
    --------
    >>> p = pack([[0.5]], [[1.0]], [[2.0]], [[3.0]])
    >>> lti_update(0.0, np.array([1.0]), np.array([2.0]), p, np.empty(1)).tolist()
    [2.5]
    """
    n = int(p[_N])
    return _affine(p, _HEAD, _HEAD + n * n, n, x, u, out)
