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
def _times(p, first, rows, cols, v, into):
    """``into = F v`` with ``F`` (``rows`` x ``cols``) at ``p[first:]``, row-major, summed as
    numpy's ``F @ v`` sums: its BLAS's dot product for one row, its matrix-vector product
    for more (numba's ``numpy.dot`` calls the same kernels; a plain loop sums in another
    order and differs in the last bits), a product where each row has one term."""
    if cols == 1:
        for i in range(rows):
            into[i] = p[first + i] * v[0]
    elif cols == 0:
        for i in range(rows):
            into[i] = 0.0
    elif rows == 1:
        into[0] = np.dot(p[first:first + cols], v)
    elif rows > 1:
        np.dot(p[first:first + rows * cols].reshape((rows, cols)), v, into)


@jit(inline=True)
def _affine(p, first, second, rows, x, u, out):
    """``out = F x + G u`` with ``F`` (``rows`` x n) at ``p[first:]`` and ``G`` (``rows`` x m)
    at ``p[second:]``: the two products made as numpy's ``F @ x`` and ``G @ u``
    (:func:`_times`) and added, as python-control's LTI blocks do (``A @ x + B @ u``), so
    that the engine and python-control give the same numbers."""
    m = u.shape[0]
    _times(p, first, rows, x.shape[0], x, out)
    if m <= 1:  # one product a row, or none (0.0 added, as numpy adds its zeros)
        for i in range(rows):
            out[i] += p[second + i] * u[0] if m else 0.0
    else:
        gu = np.empty(rows)
        _times(p, second, rows, m, u, gu)
        for i in range(rows):
            out[i] += gu[i]
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
