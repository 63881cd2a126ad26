"""The step's arithmetic, with numpy's dot products reproduced.

scipy forms every linear combination of stages with ``numpy.dot``, which hands it to
OpenBLAS (gemv, gemm or ddot according to the operands' shapes; a 1-element operand is
a plain product). OpenBLAS sums in its own order with fused multiply-adds, and the
error estimate subtracts nearly equal numbers, so a different summation order moves
the accepted step sizes by ~1e-13 relative, which the step-size controller amplifies:
on van der Pol at scipy's default tolerances, plain loops differ from scipy by 3e-9
(RK45) and 1.5e-7 (DOP853) after 20 s. So every combination here is the same BLAS call
numpy makes (numba's ``numpy.dot`` calls the BLAS scipy ships, which on one machine picks
the same kernel), and the results agree to the last bit.

Every function here is pasted into the step machine by numba (``inline="always"``);
``f`` is the workspace's ``floats`` and ``K``/``K_flat`` its stages.
"""

from __future__ import annotations

import math

import numpy as np

from ...._jit import jit
from .workspace import (
    _ATOL,
    _ERR,
    _ERR_LOW,
    _SCALE,
    _Y,
    _Y_NEW,
    _Y_OLD,
    _Y_STAGE,
    _at,
    _dense_at,
)


@jit(inline=True)
def _py_min(a, b):
    """``min(a, b)`` with Python's rule: ``b`` only if ``b < a`` (a NaN ``b`` loses)."""
    return b if b < a else a


@jit(inline=True)
def _divided(a, b):
    """``a / b`` as numpy divides two float64: by a zero, an infinity of the quotient's
    sign, or NaN (``0 / 0``, NaN), where compiled code would raise ZeroDivisionError (a
    state at 0 with ``atol=0`` makes solve_ivp's error scale 0)."""
    if b == 0.0:
        if a == 0.0 or a != a:
            return math.nan
        return math.copysign(math.inf, a) * math.copysign(1.0, b)
    return a / b


@jit(inline=True)
def _py_max(a, b):
    """``max(a, b)`` with Python's rule: ``b`` only if ``b > a`` (a NaN ``b`` loses)."""
    return b if b > a else a


@jit(inline=True)
def _combine(K, K_flat, count, coefficients, f, out, n):
    """``f[out:out+n] = sum_{j < count} c_j K[j]`` as ``numpy.dot(K[:count].T, c[:count])``.

    With one state numpy takes the dot product of two vectors (``K_flat``'s first
    ``count`` entries are then the column).
    """
    if count > 1:
        if n == 1:
            f[out] = np.dot(K_flat[:count], coefficients[:count])
        else:
            np.dot(K[:count].T, coefficients[:count], f[out : out + n])
        return
    for i in range(n):
        total = 0.0
        for j in range(count):
            total += K[j, i] * coefficients[j]
        f[out + i] = total


@jit(inline=True)
def _stage_argument(K, K_flat, count, coefficients, f, base, h, n):
    """``y_stage = f[base:base+n] + (sum_{j < count} c_j K[j]) h``: a stage's argument."""
    stage = _at(_Y_STAGE, n)
    _combine(K, K_flat, count, coefficients, f, stage, n)
    for i in range(n):
        f[stage + i] = f[base + i] + f[stage + i] * h


@jit(inline=True)
def _sum_of_squares(f, start, n):
    """``x . x`` for ``x = f[start:start+n]`` (numpy's ``x.dot(x)`` in ``norm``)."""
    x = f[start : start + n]
    return np.dot(x, x)


@jit(inline=True)
def _rms(f, start, n):
    """scipy's RMS norm ``||x||_2 / sqrt(n)`` of ``x = f[start:start+n]``."""
    return math.sqrt(_sum_of_squares(f, start, n)) / n**0.5


@jit(inline=True)
def _all_finite(f, start, count):
    """True when ``f[start:start+count]`` holds no NaN or infinity."""
    for i in range(count):
        if not math.isfinite(f[start + i]):
            return False
    return True


@jit(inline=True)
def _error_norm(method, K, K_flat, f, h, rtol, n):
    """Scaled RMS error of the trial step; the step is accepted when this is below 1.

    ``sc_i = atol_i + max(|y_i|, |y_new,i|) rtol``. Embedded pair:
    ``||h sum_j e_j k_j / sc||``. DOP853 (``E5``, ``E3`` its two estimates over
    ``k_0..k_S``, ``n`` states):

    .. math::

        \\epsilon = |h| \\, \\|E_5 / sc\\|_2^2 \\big/
        \\sqrt{n \\, (\\|E_5 / sc\\|_2^2 + 0.01 \\|E_3 / sc\\|_2^2)}.

    A NaN anywhere makes the result NaN (the step is then rejected, as in scipy).
    """
    y = _at(_Y, n)
    y_new = _at(_Y_NEW, n)
    scale = _at(_SCALE, n)
    atol = _at(_ATOL, n)
    err = _at(_ERR, n)
    for i in range(n):
        a = abs(f[y + i])
        b = abs(f[y_new + i])
        # numpy.maximum: NaN when either is NaN
        biggest = a if (a >= b or a != a) else b
        f[scale + i] = f[atol + i] + biggest * rtol
    rows = method.n_stages + 1
    _combine(K, K_flat, rows, method.E, f, err, n)
    if not method.dop853:
        for i in range(n):
            f[err + i] = _divided(f[err + i] * h, f[scale + i])
        return _rms(f, err, n)
    err_low = _at(_ERR_LOW, n)
    _combine(K, K_flat, rows, method.E_low, f, err_low, n)
    for i in range(n):
        f[err + i] = _divided(f[err + i], f[scale + i])
        f[err_low + i] = _divided(f[err_low + i], f[scale + i])
    norm5 = math.sqrt(_sum_of_squares(f, err, n)) ** 2
    norm3 = math.sqrt(_sum_of_squares(f, err_low, n)) ** 2
    if norm5 == 0 and norm3 == 0:
        return 0.0
    denominator = norm5 + 0.01 * norm3
    return abs(h) * norm5 / math.sqrt(denominator * n)


@jit(inline=True)
def _build_interpolant(method, K, K_flat, f, h, n):
    """Coefficients of the interpolant over the last step (its stages all in ``K``).

    Powers (RK23, RK45): ``Q = K^T P`` (``n x p``, row-major from the coefficients'
    offset) so that ``y(t_old + x h) = y_old + h Q (x, x^2, .., x^p)``.

    DOP853 (extra stages ``k_13..k_15`` already in ``K``), with ``dy = y - y_old``:
    ``F_0 = dy``, ``F_1 = h f_old - dy``, ``F_2 = 2 dy - h (f + f_old)``,
    ``F_{3..6} = h D K`` (rows of ``n``).
    """
    dense = _dense_at(n)
    rows = method.n_stages + 1
    if not method.dop853:
        P = method.dense
        powers = P.shape[1]
        if n == 1:
            np.dot(K_flat[:rows], P, f[dense : dense + powers])
        else:
            Q = f[dense : dense + n * powers].reshape((n, powers))
            np.dot(K[:rows].T, P, Q)
        return
    S = method.n_stages
    y = _at(_Y, n)
    y_old = _at(_Y_OLD, n)
    for i in range(n):
        delta = f[y + i] - f[y_old + i]
        f[dense + i] = delta
        f[dense + n + i] = h * K[0, i] - delta
        f[dense + 2 * n + i] = 2 * delta - h * (K[S, i] + K[0, i])
    D = method.dense
    high = dense + 3 * n
    if n == 1:
        np.dot(D, K_flat[: method.n_rows], f[high : high + 4])
    else:
        np.dot(D, K[: method.n_rows], f[high : high + 4 * n].reshape((4, n)))
    for k in range(4 * n):
        f[high + k] = h * f[high + k]


@jit(inline=True)
def _evaluate_interpolant(method, f, t_old, h, t_eval, first, stop, y_eval, scratch_at, n):
    """States at ``t_eval[first:stop]`` from the interpolant over ``[t_old, t_old + h]``
    (RK23 and RK45 work in ``f[scratch_at:]``, or in an array of their own when that is
    too short).

    With ``x = (t - t_old) / h``: powers, ``y_old + h Q (x, .., x^p)`` (all the times
    of the step in one product, as scipy evaluates them); DOP853, nested from the last
    coefficient,
    ``y_old + x(F_0 + (1-x)(F_1 + x(F_2 + (1-x)(F_3 + x(F_4 + (1-x)(F_5 + x F_6))))))``.
    """
    m = stop - first
    dense = _dense_at(n)
    y_old = _at(_Y_OLD, n)
    if method.dop853:
        for k in range(m):
            x = (t_eval[first + k] - t_old) / h
            for i in range(n):
                value = 0.0
                for r in range(7):
                    value += f[dense + (6 - r) * n + i]
                    if r % 2 == 0:
                        value *= x
                    else:
                        value *= 1 - x
                y_eval[first + k, i] = value + f[y_old + i]
        return
    powers = method.dense.shape[1]
    # numpy: p = cumprod of x over the powers, (powers x m); y = h * Q p + y_old.
    if scratch_at + (powers + n) * m <= f.shape[0]:
        scratch = f[scratch_at : scratch_at + (powers + n) * m]
    else:
        scratch = np.empty((powers + n) * m)
    p = scratch[: powers * m].reshape((powers, m))
    for k in range(m):
        x = (t_eval[first + k] - t_old) / h
        p[0, k] = x
        for r in range(1, powers):
            p[r, k] = p[r - 1, k] * x
    product = scratch[powers * m :]
    Q = f[dense : dense + n * powers]
    if n == 1 and m == 1:
        product[0] = np.dot(Q, scratch[:powers])
    elif n == 1:
        np.dot(Q, p, product)
    elif m == 1:
        np.dot(Q.reshape((n, powers)), scratch[:powers], product)
    else:
        np.dot(Q.reshape((n, powers)), p, product.reshape((n, m)))
    for k in range(m):
        for i in range(n):
            y_eval[first + k, i] = h * product[i * m + k] + f[y_old + i]

