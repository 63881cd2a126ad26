"""Two-wheel spacecraft: plant, input-output linearizer, output map and outer controller.

Equations and numbers are those of Endo, Sekiguchi and Nonaka, "Model Error
Compensator for Attitude Control of 2-Wheel Spacecraft with On-line FRIT
based Tuning" (2017), cited as eq. (n) and Table n. Departures from the
printed text are listed in ``docs`` (errata E1-E6 of the project spec).

The quaternion is scalar first, ``q = [q0, q1, q2, q3]``; ``R_bs(q)`` maps
body-frame vectors to the inertial frame (Hamilton convention), which is the
convention under which eq. (4) reads ``q' = Q(q) w_b`` with body rates.
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from .. import _checks
from ..kernels import common
from ..kernels import spacecraft as kernels
from ..kernels.spacecraft import (
    CONTROLLER,
    CONTROLLER_INPUTS,
    LINEARIZER,
    LINEARIZER_INPUTS,
    MOMENTUM,
    PLANT,
)
from .contract import KernelBlock, drawn_as

# --- Paper values (Tables 2 and 3) -------------------------------------------------

#: Nominal body inertia ``J_bn`` (Table 2), kg m^2.
J_BN = np.diag([4000.0, 5000.0, 6000.0])
#: Inertia of wheel 1 ``J_w1`` (Table 2), kg m^2.
J_W1 = np.diag([0.45, 0.225, 0.225])
#: Inertia of wheel 2 ``J_w2`` (Table 2), kg m^2.
J_W2 = np.diag([0.225, 0.45, 0.225])
#: Wheel axes ``v1``, ``v2`` (Table 2): the z wheel has failed.
V1 = np.array([1.0, 0.0, 0.0])
V2 = np.array([0.0, 1.0, 0.0])
#: Nominal total inertia ``J_m = J_bn + J_w1 + J_w2`` (eq. 3 with nominal values).
J_M = J_BN + J_W1 + J_W2
#: Inertia error ``Delta J`` (eq. 31, Table 2), kg m^2.
DELTA_J = np.diag([20.003, 25.003, 30.002])
#: Amplitude (N m s) and angular frequency (rad/s) of the true momentum ``H0(t)``.
H0_AMPLITUDE = 0.05
H0_FREQUENCY = 2 * np.pi * 1e-4
#: Outer-loop gain ``F1 = F2`` (Table 3).
F_PAPER = 0.0009
#: Sampling period of the whole loop (section 5.1), s.
TS_PAPER = 0.1
#: Pointing requirement (section 1), degrees.
POINTING_REQUIREMENT_DEG = 0.05


@dataclass(frozen=True)
class MomentumProfile:
    """A total angular momentum ``H(t) = c + a_s sin(w t) + a_c cos(w t)`` (N m s).

    Blocks given a profile (rather than an arbitrary function) run on the fast
    engine, which compiles the profile with the rest of the block.

    Attributes
    ----------
    constant, sine, cosine : tuple of 3 floats
        ``c``, ``a_s`` and ``a_c``.
    omega : float
        Angular frequency ``w`` (rad/s).

    Examples
    --------
    >>> MomentumProfile(constant=(0, 0, 0.1))(5.0).tolist()
    [0.0, 0.0, 0.1]
    """

    constant: tuple = (0.0, 0.0, 0.0)
    sine: tuple = (0.0, 0.0, 0.0)
    cosine: tuple = (0.0, 0.0, 0.0)
    omega: float = 0.0

    def packed(self) -> np.ndarray:
        """``[c, a_s, a_c, w]`` as the kernels read it."""
        parts = {name: _checks.vector(name, getattr(self, name), 3)
                 for name in ("constant", "sine", "cosine")}
        return MOMENTUM.pack(**parts, omega=float(self.omega))

    def __call__(self, t: float) -> np.ndarray:
        return np.array(kernels.momentum_at(t, self.packed(), 0))


#: True total angular momentum of the paper's scenario (Table 2), N m s:
#: ``H0(t) = 0.05 [sin(w t), cos(w t), sin(w t)]`` with ``w = 2 pi 1e-4`` rad/s.
paper_momentum = MomentumProfile(sine=(H0_AMPLITUDE, 0.0, H0_AMPLITUDE),
                                 cosine=(0.0, H0_AMPLITUDE, 0.0), omega=H0_FREQUENCY)


def _momentum_kernel(name, value, kernel, offset):
    """Check a momentum argument once and fit ``kernel`` to it.

    ``offset`` is where the block's parameter layout holds the profile. Returns
    the packed profile, ``H(t)``, ``fit(t, p)`` (the parameters to use at time
    ``t``), the kernel to call and, for a plain callable (which cannot be
    packed), why the block cannot be compiled: ``fit`` then sets the profile's
    constant to ``H(t)`` in a copy of ``p`` at each call.
    """
    H = _checks.momentum(name, value)
    if isinstance(value, MomentumProfile):
        return value.packed(), H, _as_is, kernel, None
    if not callable(value):
        return MomentumProfile(constant=tuple(H(0.0))).packed(), H, _as_is, kernel, None
    constant = slice(offset + MOMENTUM.constant, offset + MOMENTUM.constant + 3)

    def fit(t, p):
        local = p.copy()
        local[constant] = H(t)
        return local

    def repacked(t, x, u, p, out):
        return kernel(t, x, u, fit(t, p), out)

    reason = f"{name} is a Python function; give a MomentumProfile to compile it"
    return MomentumProfile().packed(), H, fit, repacked, reason


def _as_is(t, p):
    return p


# --- Pure math ---------------------------------------------------------------------


def rotation_matrix(q) -> np.ndarray:
    """Rotation matrix ``R_bs(q)`` of a scalar-first unit quaternion (body -> inertial).

    Examples
    --------
    >>> rotation_matrix([1.0, 0.0, 0.0, 0.0])
    array([[1., 0., 0.],
           [0., 1., 0.],
           [0., 0., 1.]])
    """
    return np.array(kernels.rotation(_checks.vector("q", q, 4))).reshape(3, 3)


def quaternion_rate_matrix(q) -> np.ndarray:
    """Kinematic matrix ``Q(q)`` of eq. (4): ``q' = Q(q) w_b``.

    Its columns are ``Q(q) e_j``, computed by the kernel the plant integrates.

    Examples
    --------
    >>> quaternion_rate_matrix([1.0, 0.0, 0.0, 0.0]) + 0.0
    array([[0. , 0. , 0. ],
           [0.5, 0. , 0. ],
           [0. , 0.5, 0. ],
           [0. , 0. , 0.5]])
    """
    q0, q1, q2, q3 = _checks.vector("q", q, 4)
    return np.column_stack([kernels.quaternion_rate(q0, q1, q2, q3, e) for e in np.eye(3)])


def quaternion_from_axis_angle(axis, angle_deg: float) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle_deg`` degrees about ``axis``.

    ``q = [cos(theta/2), k sin(theta/2)]`` with ``k = axis/|axis|`` (section 2.1).

    Examples
    --------
    >>> quaternion_from_axis_angle([0, 0, 1], 180.0).round(12)
    array([0., 0., 0., 1.])
    """
    k = _checks.vector("axis", axis, 3)
    n = np.linalg.norm(k)
    if n == 0:
        raise ValueError("axis must be a non-zero 3-vector")
    half = np.deg2rad(_checks.real_scalar("angle_deg", angle_deg)) / 2
    return np.concatenate([[np.cos(half)], np.sin(half) * k / n])


def body_rate(q, u, H0, J_t_inv, b1, b2) -> np.ndarray:
    """Body angular velocity ``w_b`` of eq. (2).

    ``w_b = J_t^-1 (R_bs(q)^T H0 - J_w1 v1 u1 - J_w2 v2 u2)``; ``b_l = J_wl v_l``.

    Examples
    --------
    >>> body_rate([1, 0, 0, 0], [0, 0], np.zeros(3), np.eye(3), V1, V2)
    array([0., 0., 0.])
    """
    p = PLANT.pack(J_t_inv=J_t_inv, b1=b1, b2=b2,
                   H0=MomentumProfile(constant=tuple(_checks.vector("H0", H0, 3))).packed())
    return np.array(kernels.body_rate(0.0, _checks.vector("q", q, 4), _checks.vector("u", u, 2),
                                      p))


def total_momentum(q, w_b, u, J_b, J_w1, J_w2, v1, v2) -> np.ndarray:
    """Total angular momentum in the inertial frame, the left side of eq. (1).

    ``R_bs(q) {J_b w_b + J_w1 (w_b + v1 u1) + J_w2 (w_b + v2 u2)}``.

    Examples
    --------
    >>> total_momentum([1, 0, 0, 0], np.zeros(3), [1.0, 0.0], J_BN, J_W1, J_W2, V1, V2)
    array([0.45, 0.  , 0.  ])
    """
    w_b, u = _checks.vector("w_b", w_b, 3), _checks.vector("u", u, 2)
    body = J_b @ w_b + J_w1 @ (w_b + v1 * u[0]) + J_w2 @ (w_b + v2 * u[1])
    return rotation_matrix(q) @ body


def pointing_error_deg(q) -> np.ndarray:
    """Angle between body z (antenna) and inertial z, in degrees.

    ``arccos(1 - 2 (q1^2 + q2^2))``, evaluated as the equal
    ``2 arcsin(sqrt(q1^2 + q2^2))``, which keeps its precision for the tiny
    angles of a converged loop (the arccos form rounds below about 1e-6 deg to 0).
    ``q`` may be a 4-vector or a 4 x N array.

    Examples
    --------
    >>> float(pointing_error_deg([np.cos(0.05), np.sin(0.05), 0, 0]).round(6))
    5.729578
    """
    q = np.asarray(q, dtype=float)
    half_sine = np.sqrt(q[1] ** 2 + q[2] ** 2)
    return np.rad2deg(2.0 * np.arcsin(np.clip(half_sine, 0.0, 1.0)))


# --- Block factories ---------------------------------------------------------------

_Q_SIGNALS = [f"q[{i}]" for i in range(4)]
_U_SIGNALS = ["u[0]", "u[1]"]


def spacecraft_plant(
    J_b=J_BN, J_w1=J_W1, J_w2=J_W2, v1=V1, v2=V2, H0=(0.0, 0.0, 0.0), *, name="plant"
) -> ct.NonlinearIOSystem:
    """Two-wheel spacecraft, continuous time (eq. 1-8).

    ``q' = Q(q) J_t^-1 (R_bs(q)^T H0(t) - J_w1 v1 u1 - J_w2 v2 u2)``, with
    ``J_t = J_b + J_w1 + J_w2`` (eq. 2-5). The wheel speeds are the inputs
    (a kinematic model); the total angular momentum ``H0`` (eq. 1) is given.

    Parameters
    ----------
    J_b : array_like
        Body inertia, 3x3 symmetric positive definite or its diagonal (kg m^2).
        Default: the nominal ``J_bn`` of Table 2.
    J_w1, J_w2 : array_like
        Wheel inertias (kg m^2), Table 2 by default.
    v1, v2 : array_like
        Wheel axes in the body frame (normalised; must not be zero or parallel).
    H0 : array_like, MomentumProfile or callable
        Total angular momentum in the inertial frame (N m s): a constant
        3-vector, a :class:`MomentumProfile` (such as :data:`paper_momentum`)
        or any function ``t -> 3-vector`` (which the fast engine cannot compile:
        such a plant runs on the python-control path). Default zero.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Inputs ``u[0], u[1]`` (wheel speeds, rad/s); states and outputs
        ``q[0]..q[3]``; an initial state must be a finite unit quaternion (its
        ``check_state``). Extra attributes: ``J_t``, ``H0`` (a callable),
        ``body_rate(t, q, u)`` (eq. 2) and ``momentum(t, q, u)`` (left side of eq. 1).

    Examples
    --------
    >>> plant = spacecraft_plant()
    >>> plant.dynamics(0.0, [1, 0, 0, 0], [1.0, 0]).round(8).tolist()  # wheel 1 spins
    [0.0, -5.624e-05, 0.0, 0.0]
    """
    J_b = _checks.inertia("J_b", J_b)
    J_w1 = _checks.inertia("J_w1", J_w1)
    J_w2 = _checks.inertia("J_w2", J_w2)
    v1, v2 = _checks.wheel_axes(v1, v2)
    profile, H0_of_t, fit, rhs, uncompiled = _momentum_kernel("H0", H0, kernels.plant_rhs,
                                                              PLANT.H0)
    J_t = J_b + J_w1 + J_w2
    J_t_inv = np.linalg.inv(J_t)
    b1, b2 = J_w1 @ v1, J_w2 @ v2
    params = PLANT.pack(J_t_inv=J_t_inv, b1=b1, b2=b2, H0=profile)

    def rate(t, q, u):  # the very equation plant_rhs integrates
        q, u = _checks.vector("q", q, 4), _checks.vector("u", u, 2)
        return np.array(kernels.body_rate(t, q, u, fit(t, params)))

    sys = KernelBlock(
        common.state_output, rhs, params=params, feedthrough=False, uncompiled=uncompiled,
        inputs=_U_SIGNALS, outputs=_Q_SIGNALS, states=_Q_SIGNALS, name=name,
        check_state=_checks.unit_quaternion,
    )
    sys.J_t, sys.H0 = J_t, H0_of_t
    sys.body_rate = rate
    sys.momentum = lambda t, q, u: total_momentum(q, rate(t, q, u), u, J_b, J_w1, J_w2, v1, v2)
    return sys


#: How far the norm of the plant's quaternion may drift from 1 before a failure is read as
#: divergence of the loop (the integration keeps a unit quaternion to about 1e-12).
_UNIT_NORM_DRIFT = 1e-3


class SingularDecouplingError(ValueError):
    """The decoupling matrix ``dh/dq g(q)`` of eq. (11) is singular at the current attitude.

    Examples
    --------
    >>> try:
    ...     io_linearizer().output(0.0, [], [1e-3, 0, 0, 1, 0, 0])  # q0 = q3 = 0
    ... except SingularDecouplingError as error:
    ...     print(str(error)[:48])
    input-output linearization (eq. 11) is undefined
    """


def io_linearizer(
    J_m=J_M, H0n=(0.0, 0.0, 0.0), J_w1=J_W1, J_w2=J_W2, v1=V1, v2=V2,
    *, singular_tol=1e-6, name="linearizer",
) -> ct.NonlinearIOSystem:
    """Input-output linearizing controller of eq. (11), computed from the nominal model.

    ``u = -alpha(q) + beta(q) mu`` with ``beta = (dh/dq g(q))^-1`` and
    ``alpha = beta dh/dq f(q)``, ``f(q) = Q(q) J_m^-1 R_bs(q)^T H0n`` (eq. 6),
    ``g_l(q) = -Q(q) J_m^-1 J_wl v_l`` (eq. 7-8), ``h(q) = [q1, q2]`` (eq. 9).
    With an exact model the map ``mu -> h'`` is the identity (Fig. 2).

    Parameters
    ----------
    J_m : array_like
        Nominal *total* inertia (bodies and wheels, eq. 3), kg m^2.
        Default ``J_bn + J_w1 + J_w2`` of Table 2 (erratum E4).
    H0n : array_like, MomentumProfile or callable
        Nominal total angular momentum (N m s); the paper uses 0 (so alpha = 0).
    J_w1, J_w2, v1, v2 : array_like
        Nominal wheel inertias and axes.
    singular_tol : float
        The decoupling matrix is declared singular when its smallest singular
        value falls below ``singular_tol`` times its largest possible value.
        For the paper's wheels this is ``q0^2 + q3^2 < singular_tol^2``: a
        180 degree rotation about an axis in the body x-y plane.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Static (``dt=None``). Inputs ``mu[0], mu[1], q[0]..q[3]``; outputs
        ``u[0], u[1]``.

    Raises
    ------
    SingularDecouplingError
        (a ``ValueError``) during simulation, naming the attitude, when the
        decoupling matrix is singular. An all-zero ``q``, which python-control
        feeds in its first feedthrough sweep (erratum E6), is not an attitude:
        the block returns ``u = 0`` for it.

    Examples
    --------
    >>> lin = io_linearizer()
    >>> # u1 = mu1 / A11 with A11 = -0.5 * 0.45 / J_m,x
    >>> lin.output(0.0, [], [0.001, 0, 1, 0, 0, 0]).round(6).tolist()
    [-17.780778, -0.0]
    """
    J_m = _checks.inertia("J_m", J_m)
    J_w1 = _checks.inertia("J_w1", J_w1)
    J_w2 = _checks.inertia("J_w2", J_w2)
    v1, v2 = _checks.wheel_axes(v1, v2)
    singular_tol = _checks.positive_scalar("singular_tol", singular_tol)
    profile, _, _, output, uncompiled = _momentum_kernel("H0n", H0n, kernels.linearizer_output,
                                                         LINEARIZER.H0n)
    J_m_inv = np.linalg.inv(J_m)
    b1, b2 = J_w1 @ v1, J_w2 @ v2
    G = -J_m_inv @ np.column_stack([b1, b2])
    # |Q(q) x| <= |q| |x| / 2, so this bounds the largest singular value of dh/dq g.
    threshold = singular_tol * 0.5 * np.linalg.norm(G, 2)
    params = LINEARIZER.pack(G=G, J_m_inv=J_m_inv, H0n=profile, threshold=threshold)

    def refuse(t, x, u, y):
        q = u[LINEARIZER_INPUTS.slice("q")]
        if not np.all(np.isfinite(u)):
            raise _checks.diverged(
                t, f"the linearizer received non-finite inputs (mu = "
                   f"{u[LINEARIZER_INPUTS.slice('mu')].tolist()}, q = {q.tolist()})")
        norm = float(np.sqrt(np.sum((q / max(np.abs(q).max(), 1.0)) ** 2))
                     * max(np.abs(q).max(), 1.0))  # no overflow for |q| ~ 1e200
        if abs(norm - 1.0) > _UNIT_NORM_DRIFT:
            raise _checks.diverged(
                t, f"the plant's quaternion norm is {norm:.3g} (an attitude has norm 1)")
        raise SingularDecouplingError(
            f"input-output linearization (eq. 11) is undefined at attitude "
            f"q = {np.round(q, 9).tolist()} (t = {t:g} s): the decoupling matrix "
            f"dh/dq g(q) is singular (q0^2 + q3^2 = {q[0] ** 2 + q[3] ** 2:.3g} for the "
            f"paper's wheels: a 180 deg rotation about an axis in the body x-y plane)"
        )

    sys = KernelBlock(
        output, params=params, feedthrough=True, check=refuse, uncompiled=uncompiled,
        inputs=LINEARIZER_INPUTS.labels(), outputs=_U_SIGNALS, dt=None, name=name,
    )
    return drawn_as(sys, r"$\beta(q)\,\mu - \alpha(q)$", default_name="linearizer")


def attitude_output(*, name="output") -> ct.NonlinearIOSystem:
    """Controlled output ``y = h(q) = [q1, q2]`` of eq. (9).

    Zeroing ``q1`` and ``q2`` points body z (the antenna) along inertial z.

    Returns
    -------
    control.NonlinearIOSystem
        Static. Inputs ``q[0]..q[3]``; outputs ``h[0], h[1]``.

    Examples
    --------
    >>> attitude_output().output(0.0, [], [0.9, 0.1, 0.2, 0.3]).tolist()
    [0.1, 0.2]
    """

    sys = KernelBlock(kernels.attitude_output, inputs=_Q_SIGNALS,
                      outputs=["h[0]", "h[1]"], dt=None, name=name)
    return drawn_as(sys, "$h(q)$", default_name="output")


def outer_controller(F=F_PAPER, *, output="mu", name="controller") -> ct.NonlinearIOSystem:
    """Outer loop of the linearized plant, ``mu = F (r - h)`` (eq. 12).

    With ``r = 0`` (an unconnected input) this is the paper's output zeroing
    ``mu = -F y``. In the MEC diagrams (Fig. 3-4) its output is ``mu_n``.

    Parameters
    ----------
    F : float or array_like
        ``diag(F1, F2)`` as a scalar, two values or a diagonal matrix; each >= 0
        (1/s). Default 0.0009 (Table 3).
    output : str
        Base name of the output signal, ``"mu"`` (Fig. 2) or ``"mu_n"`` (Fig. 3-4).
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Static. Inputs ``r[0], r[1], h[0], h[1]``; outputs ``<output>[0], <output>[1]``.

    Examples
    --------
    >>> outer_controller(0.5).output(0.0, [], [0, 0, 1.0, -2.0]).tolist()
    [-0.5, 1.0]
    """
    F = _checks.gain_pair("F", F)
    sys = KernelBlock(
        kernels.controller_output, params=CONTROLLER.pack(F=F), inputs=CONTROLLER_INPUTS.labels(),
        outputs=[f"{output}[0]", f"{output}[1]"], dt=None, name=name,
    )
    sys.F = F
    # drawn as Fig. 2-4 draw it: the junction r - h, then the gain F
    return drawn_as(sys, "$F$", default_name="controller", junction={"r": 1, "h": -1})
