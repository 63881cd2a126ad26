"""Kernels of the two-wheel spacecraft blocks (spacecraft paper, eq. 1-12).

Signature and rules: see the block contract in :mod:`controlkit._block`.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit

#: Length of a packed momentum profile ``H(t) = c + a_s sin(w t) + a_c cos(w t)``.
MOMENTUM_SIZE = 10


@jit
def momentum_at(t, p, o):
    """Momentum profile packed at ``p[o:o+10]`` as ``[c(3), a_s(3), a_c(3), w]``."""
    w = p[o + 9]
    s = math.sin(w * t)
    c = math.cos(w * t)
    return (p[o] + p[o + 3] * s + p[o + 6] * c,
            p[o + 1] + p[o + 4] * s + p[o + 7] * c,
            p[o + 2] + p[o + 5] * s + p[o + 8] * c)


@jit
def body_from_inertial(q, H):
    """``R_bs(q)^T H``: an inertial vector expressed in the body frame (a tuple)."""
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    return (((1 - 2 * (q2 * q2 + q3 * q3)) * H[0] + 2 * (q1 * q2 + q0 * q3) * H[1]
             + 2 * (q1 * q3 - q0 * q2) * H[2]),
            (2 * (q1 * q2 - q0 * q3) * H[0] + (1 - 2 * (q1 * q1 + q3 * q3)) * H[1]
             + 2 * (q2 * q3 + q0 * q1) * H[2]),
            (2 * (q1 * q3 + q0 * q2) * H[0] + 2 * (q2 * q3 - q0 * q1) * H[1]
             + (1 - 2 * (q1 * q1 + q2 * q2)) * H[2]))


@jit
def mat3_vec(p, o, v):
    """``A v`` for a 3x3 matrix stored row-major at ``p[o:o+9]`` (a tuple)."""
    return (p[o] * v[0] + p[o + 1] * v[1] + p[o + 2] * v[2],
            p[o + 3] * v[0] + p[o + 4] * v[1] + p[o + 5] * v[2],
            p[o + 6] * v[0] + p[o + 7] * v[1] + p[o + 8] * v[2])


@jit
def quaternion_rate(q0, q1, q2, q3, w):
    """``Q(q) w`` of eq. (4), as a tuple."""
    return (0.5 * (-q1 * w[0] - q2 * w[1] - q3 * w[2]),
            0.5 * (q0 * w[0] - q3 * w[1] + q2 * w[2]),
            0.5 * (q3 * w[0] + q0 * w[1] - q1 * w[2]),
            0.5 * (-q2 * w[0] + q1 * w[1] + q0 * w[2]))


@jit
def plant_rhs(t, x, u, p, out):
    """Plant eq. (2)-(4); ``p = [J_t^-1 (9), J_w1 v1 (3), J_w2 v2 (3), H0 profile (10)]``."""
    v = body_from_inertial(x, momentum_at(t, p, 15))
    v = (v[0] - p[9] * u[0] - p[12] * u[1],
         v[1] - p[10] * u[0] - p[13] * u[1],
         v[2] - p[11] * u[0] - p[14] * u[1])
    w = mat3_vec(p, 0, v)
    rate = quaternion_rate(x[0], x[1], x[2], x[3], w)
    for i in range(4):
        out[i] = rate[i]
    return out


@jit
def linearizer_output(t, x, u, p, out):
    """Eq. (11) for ``h = [q1, q2]``; ``p = [G (6), J_m^-1 (9), H0n profile (10), thr]``.

    ``G = -J_m^-1 [J_w1 v1, J_w2 v2]`` (3x2 row-major), so ``dh/dq g = Q_12(q) G``.
    Returns NaN when the smallest singular value of ``dh/dq g`` is below
    ``thr |q|``; zero input (python-control's trial sweep) gives zero.
    """
    q0, q1, q2, q3 = u[2], u[3], u[4], u[5]
    out[0] = 0.0
    out[1] = 0.0
    norm_sq = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    if norm_sq == 0.0:
        return out
    # dh/dq g = rows 1-2 of Q(q) times the columns of G
    _, a, c, _ = quaternion_rate(q0, q1, q2, q3, (p[0], p[2], p[4]))
    _, b, d, _ = quaternion_rate(q0, q1, q2, q3, (p[1], p[3], p[5]))
    det = a * d - b * c
    frob = a * a + b * b + c * c + d * d
    largest = math.sqrt(0.5 * (frob + math.sqrt(max(frob * frob - 4.0 * det * det, 0.0))))
    smallest = abs(det) / largest if largest > 0.0 else 0.0
    if smallest < p[25] * math.sqrt(norm_sq):
        out[0] = np.nan
        out[1] = np.nan
        return out
    w = mat3_vec(p, 6, body_from_inertial(u[2:6], momentum_at(t, p, 15)))
    _, f1, f2, _ = quaternion_rate(q0, q1, q2, q3, w)
    r0 = u[0] - f1
    r1 = u[1] - f2
    out[0] = (d * r0 - b * r1) / det
    out[1] = (a * r1 - c * r0) / det
    return out


@jit
def attitude_output(t, x, u, p, out):
    """Eq. (9): ``h = [q1, q2]`` from the input ``q``."""
    out[0] = u[1]
    out[1] = u[2]
    return out


@jit
def controller_output(t, x, u, p, out):
    """Eq. (12): ``mu = F (r - h)``; ``p = [F1, F2]``."""
    out[0] = p[0] * (u[0] - u[2])
    out[1] = p[1] * (u[1] - u[3])
    return out
