"""Kernels of the control moment gyroscope blocks (thesis eq. 1-45).

Signature and rules: see the block contract in :mod:`controlkit._block`.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit

# inertias packed as [IR1y, IR1x, IG2x, IG2y, IG2z, IG3x, IG4x]


@jit
def plant_rhs(t, x, u, p, out):
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


@jit
def reference_output(t, x, u, p, out):
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


@jit
def switch(s, phi):
    if phi == 0.0:
        if s > 0.0:
            return 1.0
        if s < 0.0:
            return -1.0
        return 0.0
    return min(1.0, max(-1.0, s / phi))


@jit
def smc_equations(x, u, p):
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
                  + eta1 * switch(s1, phi)) * J2
    z2 = q4 - q4d
    s2 = w4 - (-C3 * z2 + q4d_dot)
    w4s_dot = -C3 * (w4 - q4d_dot) + q4d_ddot
    u1 = -(z2 + f4 - (1 + x[3] / D) * w4s_dot + C4 * s2 + eta2 * switch(s2, phi)
                  + x[1] * w1 * s / D + x[2] * w4 / D) / g4
    return (u1, u2,
            w2 * s1 / gamma1,
            w1 * s2 * s / D / gamma2,
            w4 * s2 / D / gamma3,
            -w4s_dot * s2 / D / gamma4)


@jit
def all_zero(u, n):
    for i in range(n):
        if u[i] != 0.0:
            return False
    return True


@jit
def smc_output(t, x, u, p, out):
    """``[T1_cmd, T2_cmd, a1..a4]``; zero torque for all-zero measurements (trial sweep)."""
    out[2:6] = x
    if all_zero(u, 6):
        out[0] = 0.0
        out[1] = 0.0
        return out
    law = smc_equations(x, u, p)
    out[0] = law[0]
    out[1] = law[1]
    return out


@jit
def smc_update(t, x, u, p, out):
    """Forward-Euler integration of the adaptation laws at ``Ts = p[19]``."""
    if all_zero(u, 6):
        out[:] = x
        return out
    law = smc_equations(x, u, p)
    for i in range(4):
        out[i] = x[i] + p[19] * law[2 + i]
    return out
