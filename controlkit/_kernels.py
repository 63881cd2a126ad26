"""Numeric kernels of the blocks: one plain function per update or output equation.

Every kernel has the signature ``f(t, x, u, p, out) -> out``: ``p`` is a flat
float64 parameter vector packed by the block factory, and the result is
written into the caller's ``out`` (a compiled step then allocates nothing). They are written
in the subset of Python and NumPy that numba compiles, so the same source
serves both paths: the python-control blocks call them as ordinary Python,
and the fast engine (:mod:`controlkit.engine`) compiles them with numba.

A kernel that meets an undefined point (a singular decoupling matrix, a
vanishing ``sin q2``) returns NaN in its first output instead of raising; the
block's Python wrapper turns that into a clear ``ValueError``, and the fast
engine stops and asks the wrapper to do the same.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import kernel

# --- spacecraft (eq. 1-12) ----------------------------------------------------------

#: Length of a packed momentum profile ``H(t) = c + a_s sin(w t) + a_c cos(w t)``.
MOMENTUM_SIZE = 10


@kernel
def momentum_at(t, p, o):
    """Momentum profile packed at ``p[o:o+10]`` as ``[c(3), a_s(3), a_c(3), w]``."""
    w = p[o + 9]
    s = math.sin(w * t)
    c = math.cos(w * t)
    return (p[o] + p[o + 3] * s + p[o + 6] * c,
            p[o + 1] + p[o + 4] * s + p[o + 7] * c,
            p[o + 2] + p[o + 5] * s + p[o + 8] * c)


@kernel
def _body_from_inertial(q, H):
    """``R_bs(q)^T H``: an inertial vector expressed in the body frame (a tuple)."""
    q0, q1, q2, q3 = q[0], q[1], q[2], q[3]
    return (((1 - 2 * (q2 * q2 + q3 * q3)) * H[0] + 2 * (q1 * q2 + q0 * q3) * H[1]
             + 2 * (q1 * q3 - q0 * q2) * H[2]),
            (2 * (q1 * q2 - q0 * q3) * H[0] + (1 - 2 * (q1 * q1 + q3 * q3)) * H[1]
             + 2 * (q2 * q3 + q0 * q1) * H[2]),
            (2 * (q1 * q3 + q0 * q2) * H[0] + 2 * (q2 * q3 - q0 * q1) * H[1]
             + (1 - 2 * (q1 * q1 + q2 * q2)) * H[2]))


@kernel
def _mat3_vec(p, o, v):
    """``A v`` for a 3x3 matrix stored row-major at ``p[o:o+9]`` (a tuple)."""
    return (p[o] * v[0] + p[o + 1] * v[1] + p[o + 2] * v[2],
            p[o + 3] * v[0] + p[o + 4] * v[1] + p[o + 5] * v[2],
            p[o + 6] * v[0] + p[o + 7] * v[1] + p[o + 8] * v[2])


@kernel
def _quaternion_rate(q0, q1, q2, q3, w):
    """``Q(q) w`` of eq. (4), as a tuple."""
    return (0.5 * (-q1 * w[0] - q2 * w[1] - q3 * w[2]),
            0.5 * (q0 * w[0] - q3 * w[1] + q2 * w[2]),
            0.5 * (q3 * w[0] + q0 * w[1] - q1 * w[2]),
            0.5 * (-q2 * w[0] + q1 * w[1] + q0 * w[2]))


@kernel
def spacecraft_rhs(t, x, u, p, out):
    """Plant eq. (2)-(4); ``p = [J_t^-1 (9), J_w1 v1 (3), J_w2 v2 (3), H0 profile (10)]``."""
    v = _body_from_inertial(x, momentum_at(t, p, 15))
    v = (v[0] - p[9] * u[0] - p[12] * u[1],
         v[1] - p[10] * u[0] - p[13] * u[1],
         v[2] - p[11] * u[0] - p[14] * u[1])
    w = _mat3_vec(p, 0, v)
    rate = _quaternion_rate(x[0], x[1], x[2], x[3], w)
    for i in range(4):
        out[i] = rate[i]
    return out


@kernel
def state_output(t, x, u, p, out):
    """Output equal to the state."""
    out[:] = x
    return out


@kernel
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
    _, a, c, _ = _quaternion_rate(q0, q1, q2, q3, (p[0], p[2], p[4]))
    _, b, d, _ = _quaternion_rate(q0, q1, q2, q3, (p[1], p[3], p[5]))
    det = a * d - b * c
    frob = a * a + b * b + c * c + d * d
    largest = math.sqrt(0.5 * (frob + math.sqrt(max(frob * frob - 4.0 * det * det, 0.0))))
    smallest = abs(det) / largest if largest > 0.0 else 0.0
    if smallest < p[25] * math.sqrt(norm_sq):
        out[0] = np.nan
        out[1] = np.nan
        return out
    w = _mat3_vec(p, 6, _body_from_inertial(u[2:6], momentum_at(t, p, 15)))
    _, f1, f2, _ = _quaternion_rate(q0, q1, q2, q3, w)
    r0 = u[0] - f1
    r1 = u[1] - f2
    out[0] = (d * r0 - b * r1) / det
    out[1] = (a * r1 - c * r0) / det
    return out


@kernel
def attitude_output_kernel(t, x, u, p, out):
    """Eq. (9): ``h = [q1, q2]`` from the input ``q``."""
    out[0] = u[1]
    out[1] = u[2]
    return out


@kernel
def outer_controller_kernel(t, x, u, p, out):
    """Eq. (12): ``mu = F (r - h)``; ``p = [F1, F2]``."""
    out[0] = p[0] * (u[0] - u[2])
    out[1] = p[1] * (u[1] - u[3])
    return out


# --- MEC and FRIT (eq. 13-30) -----------------------------------------------------------


@kernel
def integrator_update(t, x, u, p, out):
    """``x[k+1] = x[k] + Ts u[k]``; ``p = [Ts]``."""
    for i in range(x.shape[0]):
        out[i] = x[i] + p[0] * u[i]
    return out


@kernel
def mec_output(t, x, u, p, out):
    """Eq. (13)-(15): ``mu = mu_n + K (hn - h)``, ``K = u[6:10]`` row-major."""
    e0 = u[2] - u[4]
    e1 = u[3] - u[5]
    out[0] = u[0] + (u[6] * e0 + u[7] * e1)
    out[1] = u[1] + (u[8] * e0 + u[9] * e1)
    return out


@kernel
def constant_output(t, x, u, p, out):
    """Output the parameters (a constant source)."""
    out[:] = p
    return out


@kernel
def frit_update(t, x, u, p, out):
    """One step of the FRIT tuner (eq. 24-30, errata E1-E2).

    ``p = [F1, F2, a1, a2, lambda, kappa, psi1, psi2]`` with ``a_j = exp(-F_j Ts)``;
    state layout as ``controlkit.blocks.mec.TUNER_STATES``.
    """
    lam, kappa = p[4], p[5]
    out[:] = x
    xn = out
    mu0, mu1, h0, h1, hn0, hn1 = u[0], u[1], u[2], u[3], u[4], u[5]
    e = (hn0 - h0, hn1 - h1)
    h = (h0, h1)
    for j in range(2):
        if abs(e[j]) < p[6 + j]:
            continue  # threshold: row j frozen
        xi0, xi1 = x[2 * j], x[2 * j + 1]
        eta = x[4 + j] - p[j] * (h[j] - x[6 + j])
        k0 = 8 + 2 * j   # Khat row j
        pk = 12 + 4 * j  # P_j
        P00, P01, P10, P11 = x[pk], x[pk + 1], x[pk + 2], x[pk + 3]
        Px0 = P00 * xi0 + P01 * xi1
        Px1 = P10 * xi0 + P11 * xi1
        den = lam + (xi0 * Px0 + xi1 * Px1)
        err = eta - (x[k0] * xi0 + x[k0 + 1] * xi1)
        xn[k0] = x[k0] + err * Px0 / den
        xn[k0 + 1] = x[k0 + 1] + err * Px1 / den
        xn[pk] = (P00 - Px0 * Px0 / den) / lam
        xn[pk + 1] = (P01 - Px0 * Px1 / den) / lam
        xn[pk + 2] = (P10 - Px1 * Px0 / den) / lam
        xn[pk + 3] = (P11 - Px1 * Px1 / den) / lam
        kk = 20 + 2 * j
        xn[kk] = (1 - kappa) * x[kk] + kappa * xn[k0]
        xn[kk + 1] = (1 - kappa) * x[kk + 1] + kappa * xn[k0 + 1]
    a0, a1 = p[2], p[3]
    xn[0] = a0 * x[0] + (1 - a0) * e[0]
    xn[1] = a0 * x[1] + (1 - a0) * e[1]
    xn[2] = a1 * x[2] + (1 - a1) * e[0]
    xn[3] = a1 * x[3] + (1 - a1) * e[1]
    xn[4] = a0 * x[4] + (1 - a0) * mu0
    xn[5] = a1 * x[5] + (1 - a1) * mu1
    xn[6] = a0 * x[6] + (1 - a0) * h0
    xn[7] = a1 * x[7] + (1 - a1) * h1
    return out


@kernel
def frit_output(t, x, u, p, out):
    """The implemented gain ``K`` (state, row-major)."""
    out[:] = x[20:24]
    return out


# --- CMG (thesis eq. 1-45) ------------------------------------------------------------
# inertias packed as [IR1y, IR1x, IG2x, IG2y, IG2z, IG3x, IG4x]


@kernel
def cmg_rhs(t, x, u, p, out):
    """Eq. (1)-(3) solved for the accelerations.

    ``p = [inertias (7), delta_IG4x, b1, b2, b4, c1, c2, c4, w_c]``.
    """
    IR1y, IR1x, IG2x, IG2y, IG2z, IG3x, IG4x = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    I1 = IG2y + IR1y - IR1x - IG2z
    I2 = IR1x + IG2z + IG3x + IG4x + p[7]
    q2, w1, w2, w4 = x[1], x[3], x[4], x[5]
    s = math.sin(q2)
    c = math.cos(q2)
    wc = p[14]
    F1 = -p[8] * w1 - p[11] * math.tanh(w1 / wc)
    F2 = -p[9] * w2 - p[12] * math.tanh(w2 / wc)
    F4 = -p[10] * w4 - p[13] * math.tanh(w4 / wc)
    r1 = u[0] + F1 - IR1y * w2 * w4 * c
    r2 = u[1] + F2 + IR1y * w1 * w4 * c + I1 * w4 * w4 * s * c
    r3 = F4 - I1 * w2 * w4 * math.sin(2 * q2) - IR1y * w1 * w2 * c
    m11 = IR1y
    m13 = IR1y * s
    m33 = I2 + I1 * s * s
    det = m11 * m33 - m13 * m13
    out[0] = w1
    out[1] = w2
    out[2] = w4
    out[3] = (m33 * r1 - m13 * r3) / det
    out[4] = r2 / (IG2x + IR1x)
    out[5] = (m11 * r3 - m13 * r1) / det
    return out


@kernel
def cmg_reference(t, x, u, p, out):
    """Section 6 commands with two derivatives (corrected misprints)."""
    r = out
    r[:] = 0.0
    if t <= 2.0:
        r[0] = math.pi / 18
        return r
    if t > 8.0:
        r[0] = math.pi / 3
        r[3] = 1.0
        return r
    phase = math.pi * t / 6 + math.pi / 6
    w = math.pi / 6
    s = math.sin(phase)
    c = math.cos(phase)
    A2 = 5 * math.pi / 36
    r[0] = -A2 * s + 7 * math.pi / 36
    r[1] = -A2 * w * c
    r[2] = A2 * w * w * s
    r[3] = -0.5 * s + 0.5
    r[4] = -0.5 * w * c
    r[5] = 0.5 * w * w * s
    return r


@kernel
def _switch(s, phi):
    if phi == 0.0:
        if s > 0.0:
            return 1.0
        if s < 0.0:
            return -1.0
        return 0.0
    return min(1.0, max(-1.0, s / phi))


@kernel
def smc_law(x, u, p):
    """Eq. (20)-(45): ``(u1, u2, a1', a2', a3', a4')``, the torques and the estimate rates.

    ``x = [a1..a4]``; ``u = [q1, q2, q4, w1, w2, w4, q2d, q2d', q2d'', q4d, q4d', q4d'']``;
    ``p = [inertias (7), C1, C2, eta1, gamma1, C3, C4, eta2, gamma2, gamma3, gamma4,
    boundary_layer, min_sin_q2, Ts]``. NaN torques when ``|sin q2| < min_sin_q2``.
    A tuple, so that a compiled call allocates nothing.
    """
    IR1y, IR1x, IG2x, IG2y, IG2z, IG3x, IG4x = p[0], p[1], p[2], p[3], p[4], p[5], p[6]
    C1, C2, eta1, gamma1 = p[7], p[8], p[9], p[10]
    C3, C4, eta2, gamma2, gamma3, gamma4 = p[11], p[12], p[13], p[14], p[15], p[16]
    phi = p[17]
    q2, q4, w1, w2, w4 = u[1], u[2], u[3], u[4], u[5]
    q2d, q2d_dot, q2d_ddot, q4d, q4d_dot, q4d_ddot = u[6], u[7], u[8], u[9], u[10], u[11]
    s = math.sin(q2)
    c = math.cos(q2)
    if abs(s) < p[18]:
        return (np.nan, np.nan, 0.0, 0.0, 0.0, 0.0)
    I1 = IG2y + IR1y - IR1x - IG2z
    I2 = IR1x + IG2z + IG3x + IG4x
    J2 = IG2x + IR1x
    D = I2 + (I1 - IR1y) * s * s
    f2 = (IR1y * w1 * w4 * c + I1 * w4 * w4 * s * c) / J2
    f4 = (IR1y * w2 * w4 * s * c - I1 * w2 * w4 * math.sin(2 * q2) - IR1y * w1 * w2 * c) / D
    g4 = -s / D
    z1 = q2 - q2d
    s1 = w2 - (-C1 * z1 + q2d_dot)
    u2 = -(x[0] * w2 + z1 + f2 - q2d_ddot + C1 * (w2 - q2d_dot) + C2 * s1
                  + eta1 * _switch(s1, phi)) * J2
    z2 = q4 - q4d
    s2 = w4 - (-C3 * z2 + q4d_dot)
    w4s_dot = -C3 * (w4 - q4d_dot) + q4d_ddot
    u1 = -(z2 + f4 - (1 + x[3] / D) * w4s_dot + C4 * s2 + eta2 * _switch(s2, phi)
                  + x[1] * w1 * s / D + x[2] * w4 / D) / g4
    return (u1, u2,
            w2 * s1 / gamma1,
            w1 * s2 * s / D / gamma2,
            w4 * s2 / D / gamma3,
            -w4s_dot * s2 / D / gamma4)


@kernel
def _all_zero(u, n):
    for i in range(n):
        if u[i] != 0.0:
            return False
    return True


@kernel
def smc_output(t, x, u, p, out):
    """``[T1_cmd, T2_cmd, a1..a4]``; zero torque for all-zero measurements (trial sweep)."""
    out[2:6] = x
    if _all_zero(u, 6):
        out[0] = 0.0
        out[1] = 0.0
        return out
    law = smc_law(x, u, p)
    out[0] = law[0]
    out[1] = law[1]
    return out


@kernel
def smc_update(t, x, u, p, out):
    """Forward-Euler integration of the adaptation laws at ``Ts = p[19]``."""
    if _all_zero(u, 6):
        out[:] = x
        return out
    law = smc_law(x, u, p)
    for i in range(4):
        out[i] = x[i] + p[19] * law[2 + i]
    return out


@kernel
def saturation_output(t, x, u, p, out):
    """``clip(u_i, -p_i, p_i)``."""
    for i in range(u.shape[0]):
        out[i] = min(p[i], max(-p[i], u[i]))
    return out
