"""Kernels of the control moment gyroscope blocks (thesis eq. 1-45).

Signature and rules: see the block contract in :class:`controlkit.blocks.contract.KernelBlock`. The
packed vectors are declared here, once, by name; the blocks pack them and
the kernels read them through these layouts.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit
from .common import copy_into
from .layout import layout

#: Angles and rates of rotor 1, gimbal 2 and gimbal 4: the plant's state and outputs.
STATE = layout("CMG state", q1=1, q2=1, q4=1, w1=1, w2=1, w4=1)
#: Motor torques, the plant's inputs.
TORQUES = layout("CMG torques", T1=1, T2=1)
#: The commanded gimbal angles with two derivatives (section 6).
REFERENCE = layout("CMG reference", q2d=1, q2d_dot=1, q2d_ddot=1, q4d=1, q4d_dot=1, q4d_ddot=1)
#: The seven inertias of eq. (1)-(3), in the order of ``controlkit.blocks.cmg.Inertias``.
INERTIAS = layout("CMG inertias", IR1y=1, IR1x=1, IG2x=1, IG2y=1, IG2z=1, IG3x=1, IG4x=1)
#: Plant parameters: inertias, the change ``delta_IG4x`` and the friction coefficients.
PLANT = layout("CMG plant parameters", **INERTIAS.sizes, delta_IG4x=1,
               b1=1, b2=1, b4=1, c1=1, c2=1, c4=1, w_c=1)
#: Controller parameters: nominal inertias, the gains of eq. (47), the boundary layer,
#: the smallest ``|sin q2|`` it accepts and its sampling period.
SMC = layout("adaptive SMC parameters", **INERTIAS.sizes,
             C1=1, C2=1, eta1=1, gamma1=1, C3=1, C4=1, eta2=1, gamma2=1, gamma3=1, gamma4=1,
             boundary_layer=1, min_sin_q2=1, Ts=1)
#: The controller's inputs (measurements, then commands), states and outputs.
SMC_INPUTS = layout("adaptive SMC inputs", **STATE.sizes, **REFERENCE.sizes)
SMC_STATE = layout("adaptive SMC state", a1=1, a2=1, a3=1, a4=1)
SMC_OUTPUTS = layout("adaptive SMC outputs", T1_cmd=1, T2_cmd=1, **SMC_STATE.sizes)
# numba reads a layout's offsets only: sizes the kernels need are plain module ints
_N_MEASURED = STATE.size
_N_ESTIMATES = SMC_STATE.size


@jit
def inertia_terms(p, o):
    """``(I1, I2, J2)`` of eq. (2)-(3) from the :data:`INERTIAS` packed at ``p[o:]``.

    ``I1 = IG2y + IR1y - IR1x - IG2z``, ``I2 = IR1x + IG2z + IG3x + IG4x`` and
    ``J2 = IG2x + IR1x`` (the inertia about gimbal 2's axis).

    Examples
    --------
    >>> from controlkit.blocks.cmg import Inertias
    >>> [round(float(v), 4) for v in inertia_terms(Inertias().packed(), 0)]
    [0.0167, 0.1303, 0.024]
    """
    IR1y, IR1x = p[o + INERTIAS.IR1y], p[o + INERTIAS.IR1x]
    IG2x, IG2y, IG2z = p[o + INERTIAS.IG2x], p[o + INERTIAS.IG2y], p[o + INERTIAS.IG2z]
    IG3x, IG4x = p[o + INERTIAS.IG3x], p[o + INERTIAS.IG4x]
    return (IG2y + IR1y - IR1x - IG2z, IR1x + IG2z + IG3x + IG4x, IG2x + IR1x)


@jit
def friction(w, b, c, w_c):
    """Friction torque ``F = -b w - c tanh(w / w_c)`` on an axis turning at ``w``.

    Examples
    --------
    >>> friction(2.0, 0.005, 0.0, 0.01)  # viscous only
    -0.01
    """
    return -b * w - c * math.tanh(w / w_c)


@jit
def plant_rhs(t, x, u, p, out):
    """Eq. (1)-(3) solved for the accelerations; parameters :data:`PLANT`, state :data:`STATE`.

    Examples
    --------
    At rest, ``T2`` alone accelerates gimbal 2 by ``T2 / (IG2x + IR1x)``:

    >>> from controlkit.blocks.cmg import Friction, Inertias
    >>> p = PLANT.pack(**vars(Inertias()), delta_IG4x=0.0, **vars(Friction()))
    >>> x = STATE.pack(q1=0, q2=0.5, q4=0, w1=0, w2=0, w4=0)
    >>> x_dot = plant_rhs(0.0, x, TORQUES.pack(T1=0.0, T2=0.24), p, np.empty(6))
    >>> round(float(x_dot[STATE.w2]), 9)
    10.0
    """
    IR1y = p[PLANT.IR1y]
    I1, I2, J2 = inertia_terms(p, PLANT.IR1y)
    I2 = I2 + p[PLANT.delta_IG4x]
    q2, w1, w2, w4 = x[STATE.q2], x[STATE.w1], x[STATE.w2], x[STATE.w4]
    s = math.sin(q2)
    c = math.cos(q2)
    wc = p[PLANT.w_c]
    F1 = friction(w1, p[PLANT.b1], p[PLANT.c1], wc)
    F2 = friction(w2, p[PLANT.b2], p[PLANT.c2], wc)
    F4 = friction(w4, p[PLANT.b4], p[PLANT.c4], wc)
    r1 = u[TORQUES.T1] + F1 - IR1y * w2 * w4 * c
    r2 = u[TORQUES.T2] + F2 + IR1y * w1 * w4 * c + I1 * w4 * w4 * s * c
    r3 = F4 - I1 * w2 * w4 * math.sin(2 * q2) - IR1y * w1 * w2 * c
    m11 = IR1y
    m13 = IR1y * s
    m33 = I2 + I1 * s * s
    det = m11 * m33 - m13 * m13
    out[STATE.q1] = w1
    out[STATE.q2] = w2
    out[STATE.q4] = w4
    out[STATE.w1] = (m33 * r1 - m13 * r3) / det
    out[STATE.w2] = r2 / J2
    out[STATE.w4] = (m11 * r3 - m13 * r1) / det
    return out


@jit
def reference_output(t, x, u, p, out):
    """Section 6 commands with two derivatives (corrected misprints), :data:`REFERENCE`.

    Examples
    --------
    >>> e = np.zeros(0)
    >>> reference_output(0.0, e, e, e, np.empty(6)).round(4).tolist()
    [0.1745, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    r = out
    R = REFERENCE
    r[:] = 0.0
    if t <= 2.0:
        r[R.q2d] = math.pi / 18
        return r
    if t > 8.0:
        r[R.q2d] = math.pi / 3
        r[R.q4d] = 1.0
        return r
    phase = math.pi * t / 6 + math.pi / 6
    w = math.pi / 6
    s = math.sin(phase)
    c = math.cos(phase)
    A2 = 5 * math.pi / 36
    r[R.q2d] = -A2 * s + 7 * math.pi / 36
    r[R.q2d_dot] = -A2 * w * c
    r[R.q2d_ddot] = A2 * w * w * s
    r[R.q4d] = -0.5 * s + 0.5
    r[R.q4d_dot] = -0.5 * w * c
    r[R.q4d_ddot] = 0.5 * w * w * s
    return r


@jit
def switch(s, phi):
    """``sgn(s)`` for ``phi = 0``, else the boundary layer ``sat(s / phi)``.

    Examples
    --------
    >>> switch(0.5, 0.0), switch(0.005, 0.01)  # sgn, then sat(s / phi)
    (1.0, 0.5)
    """
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

    State :data:`SMC_STATE`, inputs :data:`SMC_INPUTS`, parameters :data:`SMC`.
    NaN torques when ``|sin q2| < min_sin_q2``. A tuple, so that a compiled
    call allocates nothing.

    Examples
    --------
    >>> from controlkit.blocks.cmg import adaptive_smc
    >>> u = SMC_INPUTS.pack(q1=0, q2=0.5, q4=0, w1=0, w2=0, w4=0, q2d=0.5, q2d_dot=0,
    ...                     q2d_ddot=0, q4d=0, q4d_dot=0, q4d_ddot=0)  # on target, at rest
    >>> [abs(float(v)) for v in smc_equations(np.zeros(4), u, adaptive_smc().kernels.params)]
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    IR1y = p[SMC.IR1y]
    C1, C2, eta1, gamma1 = p[SMC.C1], p[SMC.C2], p[SMC.eta1], p[SMC.gamma1]
    C3, C4, eta2 = p[SMC.C3], p[SMC.C4], p[SMC.eta2]
    gamma2, gamma3, gamma4 = p[SMC.gamma2], p[SMC.gamma3], p[SMC.gamma4]
    phi = p[SMC.boundary_layer]
    U = SMC_INPUTS
    q2, q4, w1, w2, w4 = u[U.q2], u[U.q4], u[U.w1], u[U.w2], u[U.w4]
    q2d, q2d_dot, q2d_ddot = u[U.q2d], u[U.q2d_dot], u[U.q2d_ddot]
    q4d, q4d_dot, q4d_ddot = u[U.q4d], u[U.q4d_dot], u[U.q4d_ddot]
    a1, a2, a3, a4 = x[SMC_STATE.a1], x[SMC_STATE.a2], x[SMC_STATE.a3], x[SMC_STATE.a4]
    s = math.sin(q2)
    c = math.cos(q2)
    if abs(s) < p[SMC.min_sin_q2]:
        return (np.nan, np.nan, 0.0, 0.0, 0.0, 0.0)
    I1, I2, J2 = inertia_terms(p, SMC.IR1y)
    D = I2 + (I1 - IR1y) * s * s
    f2 = (IR1y * w1 * w4 * c + I1 * w4 * w4 * s * c) / J2
    f4 = (IR1y * w2 * w4 * s * c - I1 * w2 * w4 * math.sin(2 * q2) - IR1y * w1 * w2 * c) / D
    g4 = -s / D
    z1 = q2 - q2d
    s1 = w2 - (-C1 * z1 + q2d_dot)
    u2 = -(a1 * w2 + z1 + f2 - q2d_ddot + C1 * (w2 - q2d_dot) + C2 * s1
           + eta1 * switch(s1, phi)) * J2
    z2 = q4 - q4d
    s2 = w4 - (-C3 * z2 + q4d_dot)
    w4s_dot = -C3 * (w4 - q4d_dot) + q4d_ddot
    u1 = -(z2 + f4 - (1 + a4 / D) * w4s_dot + C4 * s2 + eta2 * switch(s2, phi)
           + a2 * w1 * s / D + a3 * w4 / D) / g4
    return (u1, u2,
            w2 * s1 / gamma1,
            w1 * s2 * s / D / gamma2,
            w4 * s2 / D / gamma3,
            -w4s_dot * s2 / D / gamma4)


@jit
def all_zero(u, n):
    """Whether ``u[0:n]`` is all zeros (python-control's first trial sweep).

    Examples
    --------
    >>> all_zero(np.array([0.0, 0.0, 1.0]), 2), all_zero(np.array([0.0, 0.0, 1.0]), 3)
    (True, False)
    """
    for i in range(n):
        if u[i] != 0.0:
            return False
    return True


@jit
def smc_output(t, x, u, p, out):
    """:data:`SMC_OUTPUTS`; zero torque for all-zero measurements (the trial sweep).

    Examples
    --------
    >>> from controlkit.blocks.cmg import adaptive_smc
    >>> p = adaptive_smc().kernels.params
    >>> smc_output(0.0, np.ones(4), np.zeros(12), p, np.empty(6)).tolist()  # trial sweep
    [0.0, 0.0, 1.0, 1.0, 1.0, 1.0]
    """
    a = SMC_OUTPUTS.a1
    copy_into(x, out[a:a + _N_ESTIMATES])
    if all_zero(u, _N_MEASURED):
        out[SMC_OUTPUTS.T1_cmd] = 0.0
        out[SMC_OUTPUTS.T2_cmd] = 0.0
        return out
    law = smc_equations(x, u, p)
    out[SMC_OUTPUTS.T1_cmd] = law[0]
    out[SMC_OUTPUTS.T2_cmd] = law[1]
    return out


@jit
def smc_update(t, x, u, p, out):
    """Forward-Euler integration of the adaptation laws at the period ``p[SMC.Ts]``.

    Examples
    --------
    Gimbal 2 moving off its command (``s1 > 0``) raises the friction estimate ``a1``
    by ``Ts w2 s1 / gamma1``:

    >>> from controlkit.blocks.cmg import adaptive_smc, reference
    >>> smc = adaptive_smc()
    >>> u = np.concatenate([[0, 0.2, 0, 0, 0.1, 0], reference(0.0)])
    >>> a = smc_update(0.0, smc.x0, u, smc.kernels.params, np.empty(4))
    >>> a.round(6).tolist()
    [0.001764, 0.0, 0.0, 0.0]
    """
    if all_zero(u, _N_MEASURED):
        return copy_into(x, out)
    law = smc_equations(x, u, p)
    for i in range(_N_ESTIMATES):
        out[i] = x[i] + p[SMC.Ts] * law[2 + i]
    return out
