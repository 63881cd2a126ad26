"""Kernels of the two-wheel spacecraft blocks (spacecraft paper, eq. 1-12).

Signature and rules: see the block contract in :class:`controlkit.blocks.contract.KernelBlock`.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit
from .layout import layout

#: A total angular momentum ``H(t) = c + a_s sin(w t) + a_c cos(w t)`` (N m s), packed.
MOMENTUM = layout("momentum profile", constant=3, sine=3, cosine=3, omega=1)
#: Plant parameters: ``J_t^-1`` (row-major), ``b_l = J_wl v_l`` and the profile of ``H0``.
PLANT = layout("spacecraft plant parameters", J_t_inv=9, b1=3, b2=3, H0=MOMENTUM.size)
#: Linearizer parameters: ``G = -J_m^-1 [b1, b2]`` (3x2 row-major), ``J_m^-1``, the
#: profile of ``H0n`` and the singularity threshold.
LINEARIZER = layout("linearizer parameters", G=6, J_m_inv=9, H0n=MOMENTUM.size, threshold=1)
#: Inputs of the linearizer: the virtual input ``mu`` and the attitude ``q``.
LINEARIZER_INPUTS = layout("linearizer inputs", mu=2, q=4)
#: Outer controller: parameters ``F = (F1, F2)``; inputs ``r`` and ``h``.
CONTROLLER = layout("outer controller parameters", F=2)
CONTROLLER_INPUTS = layout("outer controller inputs", r=2, h=2)


@jit
def momentum_at(t, p, o):
    """``H(t)`` of the profile packed as :data:`MOMENTUM` at ``p[o:]`` (a tuple).

    Examples
    --------
    >>> z = np.zeros(3)
    >>> p = MOMENTUM.pack(constant=[0, 0, 0.1], sine=z, cosine=z, omega=0.0)
    >>> [float(v) for v in momentum_at(5.0, p, 0)]
    [0.0, 0.0, 0.1]
    """
    w = p[o + MOMENTUM.omega]
    s = math.sin(w * t)
    c = math.cos(w * t)
    c0, s0, k0 = o + MOMENTUM.constant, o + MOMENTUM.sine, o + MOMENTUM.cosine
    return (p[c0] + p[s0] * s + p[k0] * c,
            p[c0 + 1] + p[s0 + 1] * s + p[k0 + 1] * c,
            p[c0 + 2] + p[s0 + 2] * s + p[k0 + 2] * c)


@jit
def rotation(q):
    """``R_bs(q)`` (body to inertial, Hamilton, scalar first), row-major as a 9-tuple.

    Examples
    --------
    >>> [float(v) for v in rotation(np.array([0.0, 0.0, 0.0, 1.0]))]  # 180 deg about z
    [-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0]
    """
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    return (1 - 2 * (q2 * q2 + q3 * q3), 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2),
            2 * (q1 * q2 + q0 * q3), 1 - 2 * (q1 * q1 + q3 * q3), 2 * (q2 * q3 - q0 * q1),
            2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), 1 - 2 * (q1 * q1 + q2 * q2))


@jit
def body_from_inertial(q, H):
    """``R_bs(q)^T H``: an inertial vector expressed in the body frame (a tuple).

    Examples
    --------
    >>> [float(v) for v in body_from_inertial(np.array([0.0, 0.0, 0.0, 1.0]), (1.0, 0.0, 0.0))]
    [-1.0, 0.0, 0.0]
    """
    R = rotation(q)
    return (R[0] * H[0] + R[3] * H[1] + R[6] * H[2],
            R[1] * H[0] + R[4] * H[1] + R[7] * H[2],
            R[2] * H[0] + R[5] * H[1] + R[8] * H[2])


@jit
def mat3_vec(p, o, v):
    """``A v`` for a 3x3 matrix stored row-major at ``p[o:o+9]`` (a tuple).

    Examples
    --------
    >>> [float(v) for v in mat3_vec(np.arange(9.0), 0, (1.0, 0.0, 0.0))]  # first column
    [0.0, 3.0, 6.0]
    """
    return (p[o] * v[0] + p[o + 1] * v[1] + p[o + 2] * v[2],
            p[o + 3] * v[0] + p[o + 4] * v[1] + p[o + 5] * v[2],
            p[o + 6] * v[0] + p[o + 7] * v[1] + p[o + 8] * v[2])


@jit
def quaternion_rate(q0, q1, q2, q3, w):
    """``Q(q) w`` of eq. (4), as a tuple.

    Examples
    --------
    >>> [r + 0.0 for r in quaternion_rate(1.0, 0.0, 0.0, 0.0, (2.0, 0.0, 0.0))]
    [0.0, 1.0, 0.0, 0.0]
    """
    return (0.5 * (-q1 * w[0] - q2 * w[1] - q3 * w[2]),
            0.5 * (q0 * w[0] - q3 * w[1] + q2 * w[2]),
            0.5 * (q3 * w[0] + q0 * w[1] - q1 * w[2]),
            0.5 * (-q2 * w[0] + q1 * w[1] + q0 * w[2]))


@jit
def body_rate(t, q, u, p):
    """Eq. (2): ``w_b = J_t^-1 (R_bs(q)^T H0(t) - b1 u1 - b2 u2)``, parameters :data:`PLANT`.

    Examples
    --------
    >>> z = np.zeros(3)
    >>> H0 = MOMENTUM.pack(constant=[0, 0, 0.5], sine=z, cosine=z, omega=0.0)
    >>> p = PLANT.pack(J_t_inv=np.eye(3), b1=[1, 0, 0], b2=[0, 1, 0], H0=H0)
    >>> [float(v) for v in body_rate(0.0, np.array([1.0, 0, 0, 0]), np.array([2.0, 0.0]), p)]
    [-2.0, 0.0, 0.5]
    """
    v = body_from_inertial(q, momentum_at(t, p, PLANT.H0))
    b1, b2 = PLANT.b1, PLANT.b2
    v = (v[0] - p[b1] * u[0] - p[b2] * u[1],
         v[1] - p[b1 + 1] * u[0] - p[b2 + 1] * u[1],
         v[2] - p[b1 + 2] * u[0] - p[b2 + 2] * u[1])
    return mat3_vec(p, PLANT.J_t_inv, v)


@jit
def plant_rhs(t, x, u, p, out):
    """Plant eq. (2)-(4): ``q' = Q(q) w_b``; parameters :data:`PLANT`, inputs wheel speeds.

    ``w_b`` is :func:`body_rate`, the function behind the plant block's ``body_rate``.

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> p = spacecraft_plant().kernels.params
    >>> q_dot = plant_rhs(0.0, np.array([1.0, 0, 0, 0]), np.array([1.0, 0.0]), p, np.empty(4))
    >>> (q_dot + 0.0).round(8).tolist()  # wheel 1 spins
    [0.0, -5.624e-05, 0.0, 0.0]
    """
    rate = quaternion_rate(x[0], x[1], x[2], x[3], body_rate(t, x, u, p))
    for i in range(4):
        out[i] = rate[i]
    return out


@jit
def linearizer_output(t, x, u, p, out):
    """Eq. (11) for ``h = [q1, q2]``; parameters :data:`LINEARIZER`, inputs ``[mu, q]``.

    ``G = -J_m^-1 [J_w1 v1, J_w2 v2]`` (3x2 row-major), so ``dh/dq g = Q_12(q) G``.
    Returns NaN when the smallest singular value of ``dh/dq g`` is below
    ``thr |q|``; zero input (python-control's trial sweep) gives zero.

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import io_linearizer
    >>> p = io_linearizer().kernels.params
    >>> u = LINEARIZER_INPUTS.pack(mu=[0.001, 0.0], q=[1.0, 0, 0, 0])
    >>> (linearizer_output(0.0, np.zeros(0), u, p, np.empty(2)) + 0.0).round(6).tolist()
    [-17.780778, 0.0]
    """
    iq = LINEARIZER_INPUTS.q
    q0, q1, q2, q3 = u[iq], u[iq + 1], u[iq + 2], u[iq + 3]
    out[0] = 0.0
    out[1] = 0.0
    norm_sq = q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3
    if norm_sq == 0.0:
        return out
    # dh/dq g = rows 1-2 of Q(q) times the columns of G
    G = LINEARIZER.G
    _, a, c, _ = quaternion_rate(q0, q1, q2, q3, (p[G], p[G + 2], p[G + 4]))
    _, b, d, _ = quaternion_rate(q0, q1, q2, q3, (p[G + 1], p[G + 3], p[G + 5]))
    det = a * d - b * c
    frob = a * a + b * b + c * c + d * d
    largest = math.sqrt(0.5 * (frob + math.sqrt(max(frob * frob - 4.0 * det * det, 0.0))))
    smallest = abs(det) / largest if largest > 0.0 else 0.0
    if smallest < p[LINEARIZER.threshold] * math.sqrt(norm_sq):
        out[0] = np.nan
        out[1] = np.nan
        return out
    H = momentum_at(t, p, LINEARIZER.H0n)
    w = mat3_vec(p, LINEARIZER.J_m_inv, body_from_inertial(u[iq:iq + 4], H))
    _, f1, f2, _ = quaternion_rate(q0, q1, q2, q3, w)
    r0 = u[LINEARIZER_INPUTS.mu] - f1
    r1 = u[LINEARIZER_INPUTS.mu + 1] - f2
    out[0] = (d * r0 - b * r1) / det
    out[1] = (a * r1 - c * r0) / det
    return out


@jit
def attitude_output(t, x, u, p, out):
    """Eq. (9): ``h = [q1, q2]`` from the input ``q``.

    Examples
    --------
    >>> q = np.array([0.9, 0.1, 0.2, 0.3])
    >>> attitude_output(0.0, np.zeros(0), q, np.zeros(0), np.empty(2)).tolist()
    [0.1, 0.2]
    """
    out[0] = u[1]
    out[1] = u[2]
    return out


@jit
def controller_output(t, x, u, p, out):
    """Eq. (12): ``mu = F (r - h)``; :data:`CONTROLLER`, inputs :data:`CONTROLLER_INPUTS`.

    Examples
    --------
    >>> u = CONTROLLER_INPUTS.pack(r=[0.0, 0.0], h=[1.0, -2.0])
    >>> controller_output(0.0, np.zeros(0), u, CONTROLLER.pack(F=[0.5, 0.5]), np.empty(2)).tolist()
    [-0.5, 1.0]
    """
    r, h = CONTROLLER_INPUTS.r, CONTROLLER_INPUTS.h
    out[0] = p[CONTROLLER.F] * (u[r] - u[h])
    out[1] = p[CONTROLLER.F + 1] * (u[r + 1] - u[h + 1])
    return out
