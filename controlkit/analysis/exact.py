"""Exact Jacobians of controlkit's kernels, derived by hand from their equations.

:func:`controlkit.analysis.linearize` differentiates a block exactly when both of its
kernels appear here (the spacecraft paper's plant, linearizer, output map and outer
controller, eq. 1-12; the MEC's compensator, nominal model and constant gain, eq. 13-15;
the generic state output, identity, integrator, low-pass filter and saturation). Every
other block (the FRIT tuner, the CMG's plant and controller, a user's function) is
differentiated by central differences (:mod:`controlkit.analysis.jacobians`).

Each entry maps a kernel ``f(t, x, u, p, out)`` to ``jacobian(t, x, u, p) -> (F_x, F_u)``:
``(A, B)`` for an update or right-hand side kernel, ``(C, D)`` for an output kernel.
The tests hold every one against central differences of its kernel.
"""

from __future__ import annotations

import numpy as np

from .._jit import python_function
from ..kernels import common, mec
from ..kernels import spacecraft as sc

# plain Python: called here with other argument types than the kernels call them, the
# compiled versions would be compiled again for those (seconds, once per machine)
_momentum_at = python_function(sc.momentum_at)
_rotation = python_function(sc.rotation)


def _omega(w) -> np.ndarray:
    """``W(w)`` with ``Q(q) w = W(w) q / 2`` (eq. 4 is bilinear in ``q`` and ``w``)."""
    w0, w1, w2 = w
    return np.array([[0.0, -w0, -w1, -w2],
                     [w0, 0.0, w2, -w1],
                     [w1, -w2, 0.0, w0],
                     [w2, w1, -w0, 0.0]])


def _rate_matrix(q) -> np.ndarray:
    """``Q(q)`` of eq. (4), 4 x 3."""
    q0, q1, q2, q3 = q
    return 0.5 * np.array([[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]])


def _rotated_momentum_jacobian(q, H) -> np.ndarray:
    """``d(R_bs(q)^T H) / dq``, 3 x 4: the entries of ``R_bs`` are quadratic in ``q``."""
    q0, q1, q2, q3 = q
    # dR[i, j] = gradient of R_bs[i, j] with respect to (q0, q1, q2, q3)
    dR = 2.0 * np.array([
        [[0, 0, -2 * q2, -2 * q3], [-q3, q2, q1, -q0], [q2, q3, q0, q1]],
        [[q3, q2, q1, q0], [0, -2 * q1, 0, -2 * q3], [-q1, -q0, q3, q2]],
        [[-q2, q3, -q0, q1], [q1, q0, q3, q2], [0, -2 * q1, -2 * q2, 0]],
    ])
    return np.einsum("jik,j->ik", dR, np.asarray(H, dtype=float))


def _plant_rhs(t, x, u, p):
    """Eq. (2)-(4): ``q' = Q(q) w_b``, ``w_b = J_t^-1 (R_bs(q)^T H0(t) - b1 u1 - b2 u2)``.

    ``dq'/dq = W(w_b)/2 + Q(q) J_t^-1 d(R^T H0)/dq`` and ``dq'/du = -Q(q) J_t^-1 [b1 b2]``.
    ``w_b`` is read back from the kernel's ``q'``: the columns of ``Q(q)`` are orthogonal,
    of length ``|q|/2``, so ``w_b = 4 Q(q)^T q' / |q|^2``.
    """
    J_inv = p[sc.PLANT.slice("J_t_inv")].reshape(3, 3)
    b = np.column_stack([p[sc.PLANT.slice("b1")], p[sc.PLANT.slice("b2")]])
    H = np.array(_momentum_at(t, p, sc.PLANT.H0))
    Q = _rate_matrix(x)
    w = 4.0 * Q.T @ sc.plant_rhs(t, x, u, p, np.empty(4)) / (x @ x)
    return 0.5 * _omega(w) + Q @ J_inv @ _rotated_momentum_jacobian(x, H), -Q @ J_inv @ b


def _linearizer_output(t, x, u, p):
    """Eq. (11): ``u = A(q)^-1 (mu - f(q))`` with ``A = Q_12(q) G``, ``f = Q_12(q) w_n(q)``.

    ``du/dmu = A^-1`` and ``du/dq = -A^-1 (dA/dq u + df/dq)``; ``Q_12`` is rows 1-2 of
    ``Q(q)``, ``G = -J_m^-1 [b1 b2]`` and ``w_n = J_m^-1 R_bs(q)^T H0n(t)``.
    """
    q = u[sc.LINEARIZER_INPUTS.slice("q")]
    y = sc.linearizer_output(t, x, u, p, np.empty(2))
    if not np.dot(q, q) > 0.0 or not np.all(np.isfinite(y)):
        raise ValueError(f"the linearizer of eq. (11) has no derivative at q = {q.tolist()}: "
                         "not an attitude, or its decoupling matrix is singular there")
    G = p[sc.LINEARIZER.slice("G")].reshape(3, 2)
    J_inv = p[sc.LINEARIZER.slice("J_m_inv")].reshape(3, 3)
    H = np.array(_momentum_at(t, p, sc.LINEARIZER.H0n))
    rows = slice(1, 3)
    A = _rate_matrix(q)[rows] @ G
    w_n = J_inv @ (np.array(_rotation(q)).reshape(3, 3).T @ H)
    dA_times_y = sum(y[c] * 0.5 * _omega(G[:, c])[rows] for c in range(2))
    df = 0.5 * _omega(w_n)[rows] + _rate_matrix(q)[rows] @ J_inv @ _rotated_momentum_jacobian(
        q, H)
    A_inv = np.linalg.inv(A)
    return np.zeros((2, 0)), np.hstack([A_inv, -A_inv @ (dA_times_y + df)])


def _attitude_output(t, x, u, p):
    """Eq. (9): ``h = [q1, q2]``."""
    return np.zeros((2, 0)), np.eye(2, 4, 1)


def _controller_output(t, x, u, p):
    """Eq. (12): ``mu = F (r - h)``."""
    F = np.diag(p[sc.CONTROLLER.slice("F")])
    return np.zeros((2, 0)), np.hstack([F, -F])


def _mec_output(t, x, u, p):
    """Eq. (13)-(15): ``mu = mu_n + K (hn - h)``, bilinear in ``K`` and ``hn - h``."""
    K = u[mec.MEC_INPUTS.slice("K")].reshape(2, 2)
    e = u[mec.MEC_INPUTS.slice("hn")] - u[mec.MEC_INPUTS.slice("h")]
    dK = np.kron(np.eye(2), e)  # d(K e)/d(K row-major)
    return np.zeros((2, 0)), np.hstack([np.eye(2), K, -K, dK])


def _state_output(t, x, u, p):
    """``y = x``."""
    return np.eye(x.size), np.zeros((x.size, u.size))


def _identity_output(t, x, u, p):
    """``y = u``."""
    return np.zeros((u.size, x.size)), np.eye(u.size)


def _constant_output(t, x, u, p):
    """``y = p``: a source."""
    return np.zeros((p.size, x.size)), np.zeros((p.size, u.size))


def _saturation_output(t, x, u, p):
    """``y = clip(u, -p, p)``: slope 1 inside the limits (on them too), 0 beyond."""
    return np.zeros((u.size, x.size)), np.diag((np.abs(u) <= p).astype(float))


def _integrator_update(t, x, u, p):
    """``x[k+1] = x[k] + Ts u[k]``."""
    return np.eye(x.size), p[common.INTEGRATOR.Ts] * np.eye(x.size, u.size)


def _lowpass_update(t, x, u, p):
    """``y[k+1] = a y[k] + (1 - a) u[k]``."""
    a = p[common.LOWPASS.a]
    return a * np.eye(x.size), (1.0 - a) * np.eye(x.size, u.size)


#: Kernel to its exact Jacobian ``jacobian(t, x, u, p) -> (F_x, F_u)``.
#:
#: Examples: ``EXACT[controlkit.kernels.common.integrator_update]`` gives ``(I, Ts I)``.
EXACT = {
    sc.plant_rhs: _plant_rhs,
    sc.linearizer_output: _linearizer_output,
    sc.attitude_output: _attitude_output,
    sc.controller_output: _controller_output,
    mec.mec_output: _mec_output,
    common.state_output: _state_output,
    common.identity_output: _identity_output,
    common.constant_output: _constant_output,
    common.saturation_output: _saturation_output,
    common.integrator_update: _integrator_update,
    common.lowpass_update: _lowpass_update,
}
