"""Control moment gyroscope (ECP Model 750): plant, references, adaptive SMC, saturation.

Equations are those of the thesis "Robust control of a control moment
gyroscope using sliding mode control and adaptive control" (2017), cited
as eq. (n), with the misprints corrected in the project spec (``cmg.md``):
the ``q2d`` middle segment, ``C4 s2`` in eq. (45), and the ``w1 w2`` term of ``f4``.

Bodies: rotor 1 (angle ``q1``, torque ``T1``), gimbal 2 (``q2``, torque ``T2``),
gimbal 3 locked, gimbal 4 (``q4``, no motor, driven through the rotor).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import control as ct
import numpy as np

from .. import _checks
from ..kernels import cmg as kernels
from ..kernels import common
from ..kernels.cmg import (
    INERTIAS,
    PLANT,
    REFERENCE,
    SMC,
    SMC_INPUTS,
    SMC_OUTPUTS,
    SMC_STATE,
    STATE,
    TORQUES,
)
from .contract import KernelBlock, drawn_as

STATES = STATE.labels()
REFERENCE_SIGNALS = REFERENCE.labels()
#: Motor torque ranges (N m): ``|T1| <= 0.6``, ``|T2| <= 2.4`` (section 6).
T1_MAX, T2_MAX = 0.6, 2.4
#: Sampling period of the controller (s); the ECP controller runs at about 9 ms.
TS_CMG = 0.001


def _field_values(obj) -> dict:
    return {f.name: getattr(obj, f.name) for f in fields(obj)}


@dataclass(frozen=True)
class Inertias:
    """The seven inertias of eq. (1)-(3), ECP Model 750 values by default (kg m^2).

    Attributes
    ----------
    IR1y, IR1x : float
        Rotor about its spin axis (ECP ``J_D``) and transverse (``I_D``).
    IG2x, IG2y, IG2z : float
        Inner gimbal 2 (ECP ``I_C``, ``J_C``, ``K_C``).
    IG3x : float
        Outer gimbal 3 (ECP ``K_B``).
    IG4x : float
        Gimbal 4, the frame (ECP ``K_A``).

    Examples
    --------
    >>> round(float(Inertias().I1), 4), round(float(Inertias().I2), 4)
    (0.0167, 0.1303)
    """

    IR1y: float = 0.0273
    IR1x: float = 0.0148
    IG2x: float = 0.0092
    IG2y: float = 0.0230
    IG2z: float = 0.0188
    IG3x: float = 0.0297
    IG4x: float = 0.0670

    def __post_init__(self):
        for f in fields(self):
            _checks.positive_scalar(f.name, getattr(self, f.name))

    def packed(self) -> np.ndarray:
        """The seven inertias packed as :data:`controlkit.kernels.cmg.INERTIAS`."""
        return INERTIAS.pack(**_field_values(self))

    @property
    def I1(self) -> float:
        """``I1 = IG2y + IR1y - IR1x - IG2z`` (eq. 3)."""
        return kernels.inertia_terms(self.packed(), 0)[0]

    @property
    def I2(self) -> float:
        """``I2 = IR1x + IG2z + IG3x + IG4x`` (eq. 3)."""
        return kernels.inertia_terms(self.packed(), 0)[1]

    @property
    def J2(self) -> float:
        """``IG2x + IR1x``, the inertia of gimbal 2's axis (eq. 2)."""
        return kernels.inertia_terms(self.packed(), 0)[2]


@dataclass(frozen=True)
class Friction:
    """Friction torques ``F_i = -b_i w_i - c_i tanh(w_i / w_c)`` on axes 1, 2, 4.

    Viscous ``b_i`` (N m s/rad) plus a smooth Coulomb term ``c_i`` (N m); the
    tanh keeps the plant smooth for the integrator (it is the sign function
    for ``|w| >> w_c``). The thesis writes ``F_i = F_iv w_i + d_i`` (eq. 5):
    ``F_iv = -b_i`` and ``|d_i| <= c_i``. All zero by default.

    Examples
    --------
    >>> Friction(b2=0.005).torques([0.0, 2.0, 0.0]).tolist()
    [-0.0, -0.01, -0.0]
    """

    b1: float = 0.0
    b2: float = 0.0
    b4: float = 0.0
    c1: float = 0.0
    c2: float = 0.0
    c4: float = 0.0
    w_c: float = 0.01

    def __post_init__(self):
        for f in fields(self):
            _checks.positive_scalar(f.name, getattr(self, f.name), allow_zero=f.name != "w_c")

    def torques(self, w) -> np.ndarray:
        """``[F1, F2, F4]`` at the rates ``w = [w1, w2, w4]`` (the plant kernel's law)."""
        w = _checks.vector("w", w, 3)
        return np.array([kernels.friction(wi, b, c, self.w_c) for wi, b, c in
                         zip(w, (self.b1, self.b2, self.b4), (self.c1, self.c2, self.c4),
                             strict=True)])


def _plant_parameters(inertias: Inertias, delta_IG4x, friction: Friction) -> np.ndarray:
    return PLANT.pack(**_field_values(inertias), delta_IG4x=delta_IG4x,
                      **_field_values(friction))


def accelerations(x, torque, inertias: Inertias, delta_IG4x=0.0, friction=None):
    """``[w1', w2', w4']`` solving eq. (1)-(3) for the state ``x`` and torques ``[T1, T2]``.

    Examples
    --------
    >>> (accelerations([0, 0.5, 0, 0, 0, 0], [0.0, 0.24], Inertias()) + 0.0).round(6).tolist()
    [0.0, 10.0, 0.0]
    """
    p = _plant_parameters(inertias, delta_IG4x, friction or Friction())
    x, torque = _checks.vector("x", x, STATE.size), _checks.vector("torque", torque, 2)
    xdot = kernels.plant_rhs(0.0, x, torque, p, np.empty(STATE.size))
    return xdot[[STATE.w1, STATE.w2, STATE.w4]]


def axis4_momentum(x, inertias: Inertias, delta_IG4x=0.0):
    """Angular momentum about axis 4, ``p4 = IR1y sin(q2) w1 + (I2 + I1 sin^2 q2) w4``.

    Constant when axis 4 has no friction (eq. 3 is ``p4' = F4``); ``I2``
    includes ``delta_IG4x``.

    Examples
    --------
    >>> float(round(axis4_momentum([0, np.pi / 2, 0, 1.0, 0, 0], Inertias()), 6))
    0.0273
    """
    x = _checks.vector("x", x, STATE.size)
    q2, w1, w4 = x[STATE.q2], x[STATE.w1], x[STATE.w4]
    s = np.sin(q2)
    J = inertias
    return J.IR1y * s * w1 + (J.I2 + delta_IG4x + J.I1 * s * s) * w4


def cmg_plant(inertias=None, *, delta_IG4x=0.0, friction=None, name="cmg") -> ct.NonlinearIOSystem:
    """ECP Model 750 gyroscope with gimbal 3 locked, continuous time (eq. 1-3).

    ``M(q2) [w1', w2', w4']^T = [T1 + F1 - IR1y w2 w4 cos q2,
    T2 + F2 + IR1y w1 w4 cos q2 + I1 w4^2 sin q2 cos q2,
    F4 - I1 w2 w4 sin 2q2 - IR1y w1 w2 cos q2]``, with the full 3x3 mass matrix
    (not the reduced form 4), and ``q_i' = w_i``.

    Parameters
    ----------
    inertias : Inertias, optional
        The seven inertias (ECP Model 750 by default).
    delta_IG4x : float
        Change of gimbal 4's inertia (docking), kg m^2; the true inertia is
        ``IG4x + delta_IG4x`` (eq. 8). Must keep ``IG4x + delta_IG4x > 0``.
    friction : Friction, optional
        Friction on axes 1, 2 and 4; none by default.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Inputs ``T1, T2`` (N m); states and outputs ``q1, q2, q4, w1, w2, w4``.
        Attributes ``inertias``, ``delta_IG4x``, ``friction``.

    Examples
    --------
    >>> cmg_plant().dynamics(0.0, [0, 0.5, 0, 0, 0, 0], [0.0, 0.24]).round(6)[4]
    np.float64(10.0)
    """
    inertias = inertias if inertias is not None else Inertias()
    friction = friction if friction is not None else Friction()
    delta_IG4x = float(delta_IG4x)
    if not np.isfinite(delta_IG4x) or inertias.IG4x + delta_IG4x <= 0:
        raise ValueError(
            f"delta_IG4x must keep IG4x + delta_IG4x > 0 (IG4x = {inertias.IG4x}), "
            f"got {delta_IG4x}"
        )

    sys = KernelBlock(common.state_output, kernels.plant_rhs,
                       params=_plant_parameters(inertias, delta_IG4x, friction),
                       feedthrough=False, inputs=TORQUES.labels(), outputs=STATES, states=STATES,
                       name=name)
    sys.inertias, sys.delta_IG4x, sys.friction = inertias, delta_IG4x, friction
    return drawn_as(sys, "CMG", default_name="cmg")


def reference(t):
    """Commanded gimbal angles of section 6 (corrected) with two derivatives.

    ``q2d``: pi/18 until 2 s, ``-(5 pi/36) sin(pi t/6 + pi/6) + 7 pi/36`` on
    ``2 < t <= 8``, then pi/3. ``q4d``: 0, ``-(1/2) sin(pi t/6 + pi/6) + 1/2``, then 1.
    Both are C^1 cosine blends.

    Returns
    -------
    ndarray
        ``[q2d, q2d', q2d'', q4d, q4d', q4d'']``.

    Examples
    --------
    >>> reference(8.0).round(6).tolist()  # C^1: the second derivatives jump at 8 s
    [1.047198, 0.0, -0.119623, 1.0, 0.0, -0.137078]
    """
    empty = np.zeros(0)
    return kernels.reference_output(_checks.real_scalar("t", t), empty, empty, empty,
                                    np.empty(REFERENCE.size))


def reference_generator(*, name="reference") -> ct.NonlinearIOSystem:
    """Source block of the gimbal commands :func:`reference` (section 6).

    Returns
    -------
    control.NonlinearIOSystem
        Static (``dt=None``), no inputs; outputs ``q2d, q2d_dot, q2d_ddot,
        q4d, q4d_dot, q4d_ddot``.

    Examples
    --------
    >>> reference_generator().output(0.0, [], []).round(4).tolist()
    [0.1745, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    sys = KernelBlock(kernels.reference_output, feedthrough=False, inputs=0,
                      outputs=REFERENCE_SIGNALS, dt=None, name=name)
    return drawn_as(sys, "references", default_name="reference")


#: Gains of eq. (47).
GAINS_THESIS = {"C1": 3.0, "C2": 4.0, "eta1": 1.0, "gamma1": 0.01,
                "C3": 3.0, "C4": 4.0, "eta2": 1.0, "gamma2": 0.001, "gamma3": 0.01,
                "gamma4": 0.01}


def smc_law(x, ref, a_hat, inertias: Inertias, gains, boundary_layer=0.0, min_sin_q2=1e-3):
    """Adaptive backstepping sliding-mode law (eq. 20-45): torques and estimate rates.

    Parameters
    ----------
    x : array_like
        Measured ``[q1, q2, q4, w1, w2, w4]``.
    ref : array_like
        ``[q2d, q2d', q2d'', q4d, q4d', q4d'']``.
    a_hat : array_like
        Estimates ``[a1, a2, a3, a4]``.
    inertias : Inertias
        Nominal inertias (``IG4x`` without its change).
    gains : dict
        ``C1..C4, eta1, eta2, gamma1..gamma4``.
    boundary_layer : float
        0 for ``sgn(s)``; ``phi > 0`` replaces it with ``sat(s / phi)``.
    min_sin_q2 : float
        ``u1`` divides by ``g4 = -sin(q2)/D``: below this ``|sin q2|`` the law refuses.

    Returns
    -------
    torque : ndarray
        ``[u1, u2] = [T1, T2]`` commanded (eq. 45 and 31).
    a_hat_dot : ndarray
        Adaptation laws (eq. 30, 42-44).

    Examples
    --------
    >>> u, _ = smc_law([0, np.pi/18, 0, 0, 0, 0], [np.pi/18, 0, 0, 0, 0, 0], np.zeros(4),
    ...                Inertias(), GAINS_THESIS)
    >>> np.abs(u).tolist()  # on both sliding surfaces: sgn(0) = 0, nothing to do
    [0.0, 0.0]
    """
    x = _checks.vector("x", x, STATE.size)
    ref = _checks.vector("ref", ref, REFERENCE.size)
    a_hat = _checks.vector("a_hat", a_hat, SMC_STATE.size)
    boundary_layer = _checks.positive_scalar("boundary_layer", boundary_layer, allow_zero=True)
    min_sin_q2 = _checks.positive_scalar("min_sin_q2", min_sin_q2)
    p = _controller_parameters(inertias, gains, boundary_layer, min_sin_q2, 0.0)
    law = kernels.smc_equations(a_hat, np.concatenate([x, ref]), p)
    if np.isnan(law[0]):
        _refuse_sin_q2(x[STATE.q2])
    return np.array(law[:2]), np.array(law[2:])


def _controller_parameters(inertias, gains, boundary_layer, min_sin_q2, Ts):
    return SMC.pack(**_field_values(inertias), **gains, boundary_layer=boundary_layer,
                    min_sin_q2=min_sin_q2, Ts=Ts)


#: A gimbal-2 angle beyond this (rad) is not an attitude the loop can reach: the loop diverged.
_Q2_DIVERGED = 2 * np.pi


def _explain_smc_failure(t, x, u, y):
    """The controller's torque is NaN: say whether the loop diverged or sin(q2) vanished."""
    measured = u[:STATE.size]
    if not np.all(np.isfinite(u)) or not np.all(np.isfinite(x)):
        raise _checks.diverged(t, f"the CMG controller received non-finite signals "
                                  f"(measurements {measured.tolist()}, estimates {x.tolist()})")
    q2 = measured[STATE.q2]
    if abs(q2) > _Q2_DIVERGED:
        raise _checks.diverged(t, f"gimbal 2 is at q2 = {q2:.3g} rad, more than a turn outside "
                                  f"its range 0 < q2 < pi/2")
    _refuse_sin_q2(q2)


def _refuse_sin_q2(q2):
    raise ValueError(
        f"the CMG controller divides by sin(q2) (g4 = -sin(q2)/D, eq. 45) and "
        f"q2 = {q2:.6g} rad makes it vanish; keep gimbal 2 in 0 < q2 < pi/2"
    )


def adaptive_smc(
    inertias=None, *, Ts=TS_CMG, boundary_layer=0.0, a_hat0=(0.0, 0.0, 0.0, 0.0),
    name="smc", **gains,
) -> ct.NonlinearIOSystem:
    """Adaptive backstepping sliding-mode controller of the CMG (eq. 20-45), sampled at ``Ts``.

    Gimbal 2 (``u2 = T2``, eq. 31) and gimbal 4 (``u1 = T1``, eq. 45, through the
    rotor's reaction) each get a backstepping virtual rate ``w*``, a sliding
    surface ``s = w - w*`` and a switching term ``eta sgn(s)`` that rejects the
    bounded friction remainder ``|D_i| < eta_i``. Four estimates adapt by
    eq. (30), (42)-(44): ``a1`` (gimbal-2 viscous friction), ``a2`` (rotor viscous),
    ``a3`` (gimbal-4 viscous) and ``a4`` (the change ``delta IG4x`` of gimbal 4's inertia).
    They are integrated by forward Euler at ``Ts``; the torques are computed from
    the sampled state and held.

    Chattering: with ``sgn`` (``boundary_layer=0``) the switching term flips
    sign every sample once on the surface, so the torque chatters at the sampling
    rate with amplitude ``eta_i / g_i`` (0.024 N m on gimbal 2) and the estimates
    keep integrating that noise. A boundary layer ``phi > 0`` replaces ``sgn(s)``
    by ``sat(s / phi)``: the torque is smooth, but inside the layer the friction
    remainder is no longer switched away, and the adaptation laws (which have no
    dead zone or projection) integrate what is left: the estimates drift. In the
    thesis case with ``phi = 0.01`` we measured ``a3`` reaching 35 and ``a4`` 177
    within 12 s, T1 saturated more than half the time and a 0.06 rad error on
    ``q4``; with ``sgn`` the estimates stay below 0.04.

    Parameters
    ----------
    inertias : Inertias, optional
        Nominal inertias the controller uses (ECP Model 750 by default).
    Ts : float
        Sampling period (s), default 1 ms.
    boundary_layer : float
        0 (``sgn``) or the width ``phi > 0`` of a saturation boundary layer.
    a_hat0 : array_like
        Initial estimates ``[a1, a2, a3, a4]``.
    name : str
        System name.
    **gains : float
        Any of ``C1, C2, C3, C4, eta1, eta2, gamma1, gamma2, gamma3, gamma4``
        (default eq. 47); the ``C`` and ``eta`` gains >= 0, the ``gamma`` gains > 0.

    Returns
    -------
    control.NonlinearIOSystem
        Discrete. Inputs ``q1, q2, q4, w1, w2, w4, q2d, q2d_dot, q2d_ddot, q4d,
        q4d_dot, q4d_ddot``; outputs ``T1_cmd, T2_cmd, a1, a2, a3, a4``;
        states ``a1..a4`` (attribute ``x0``).

    Raises
    ------
    ValueError
        During simulation, if ``sin(q2)`` vanishes (the law divides by it).
        python-control's first feedthrough sweep feeds all-zero measurements
        (erratum E6 of the spacecraft spec applies here too): the block returns
        zero torque for that exact input instead of raising.

    Examples
    --------
    >>> smc = adaptive_smc()
    >>> smc.nstates, smc.output_labels[:2]
    (4, ['T1_cmd', 'T2_cmd'])
    """
    inertias = inertias if inertias is not None else Inertias()
    unknown = set(gains) - set(GAINS_THESIS)
    if unknown:
        raise ValueError(f"unknown gain(s) {sorted(unknown)}; gains: {sorted(GAINS_THESIS)}")
    g = {**GAINS_THESIS, **gains}
    for key, value in g.items():
        g[key] = _checks.positive_scalar(key, value, allow_zero=not key.startswith("gamma"))
    Ts = _checks.positive_scalar("Ts", Ts)
    boundary_layer = _checks.positive_scalar("boundary_layer", boundary_layer, allow_zero=True)
    a_hat0 = _checks.vector("a_hat0", a_hat0, 4)

    sys = KernelBlock(
        kernels.smc_output, kernels.smc_update,
        params=_controller_parameters(inertias, g, boundary_layer, 1e-3, Ts),
        check=_explain_smc_failure,
        inputs=SMC_INPUTS.labels(), outputs=SMC_OUTPUTS.labels(),
        states=SMC_STATE.labels(), dt=Ts, name=name,
    )
    sys.x0, sys.gains, sys.inertias = a_hat0, g, inertias
    return drawn_as(sys, "adaptive SMC", default_name="smc")


def torque_saturation(T1_max=T1_MAX, T2_max=T2_MAX, *, name="saturation") -> ct.NonlinearIOSystem:
    """Motor torque limits: ``T_i = clip(T_i_cmd, -T_i_max, T_i_max)``.

    Parameters
    ----------
    T1_max, T2_max : float
        Limits (N m), > 0; default 0.6 and 2.4 (section 6).
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Static. Inputs ``T1_cmd, T2_cmd``; outputs ``T1, T2``.

    Examples
    --------
    >>> torque_saturation().output(0.0, [], [1.0, -1.0]).tolist()
    [0.6, -1.0]
    """
    limits = np.array([_checks.positive_scalar("T1_max", T1_max),
                       _checks.positive_scalar("T2_max", T2_max)])
    sys = KernelBlock(common.saturation_output, params=limits,
                       inputs=["T1_cmd", "T2_cmd"], outputs=["T1", "T2"], dt=None, name=name)
    sys.limits = limits
    return drawn_as(sys, "torque limits", default_name="saturation")
