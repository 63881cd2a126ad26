"""Kernels of the model error compensator and the FRIT tuner (spacecraft paper, eq. 13-30).

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

#: Inputs of the compensator, in order: ``mu_n, hn, h, K`` (``K`` row-major).
MEC_INPUTS = layout("MEC inputs", mu_n=2, hn=2, h=2, K=4)
#: Inputs of the tuner, in order: ``mu, h, hn``.
TUNER_INPUTS = layout("FRIT tuner inputs", mu=2, h=2, hn=2)
#: Parameters of the tuner: ``F = (F1, F2)``, ``a_j = exp(-F_j Ts)``, forgetting
#: factor ``lambda_``, low-pass coefficient ``kappa``, thresholds ``psi``, and two
#: flags (1.0 or 0.0) for the readings the paper leaves open: ``feedthrough`` (the
#: ``M`` filters include the current sample) and ``joint`` (both rows freeze together);
#: then the safeguard (beyond the paper): its flag, the bounds ``p_min``, ``p_max`` on the
#: eigenvalues of each ``P_j``, the dead zone on the normalised prediction error, and the
#: radius ``rho`` of the stable set ``|| I - Ts K ||_2 <= rho`` with the period ``Ts``.
TUNER = layout("FRIT tuner parameters", F=2, a=2, lambda_=1, kappa=1, psi=2, feedthrough=1,
               joint=1, safeguard=1, p_min=1, p_max=1, deadzone=1, rho=1, Ts=1)
#: State of the tuner: the filtered regressors ``M_1 (hn - h)``, ``M_2 (hn - h)``,
#: ``M_j mu_j`` and ``M_j h_j``; the RLS estimate ``Khat`` and covariances ``P1``,
#: ``P2`` (row-major); the implemented, low-passed gain ``K``.
TUNER_STATE = layout("FRIT tuner state", Mxi1=2, Mxi2=2, Mmu=2, Mh=2, Khat=4, P1=4, P2=4,
                     K=4)


@jit
def mec_output(t, x, u, p, out):
    """Eq. (13)-(15): ``mu = mu_n + K (hn - h)``, ``K`` row-major (:data:`MEC_INPUTS`).

    Examples
    --------
    >>> import numpy as np
    >>> u = MEC_INPUTS.pack(mu_n=[1, 1], hn=[0.5, 0], h=[0, 0], K=[2, 0, 0, 2])
    >>> mec_output(0.0, np.zeros(0), u, np.zeros(0), np.empty(2)).tolist()
    [2.0, 1.0]
    """
    e0 = u[MEC_INPUTS.hn] - u[MEC_INPUTS.h]
    e1 = u[MEC_INPUTS.hn + 1] - u[MEC_INPUTS.h + 1]
    k = MEC_INPUTS.K
    out[0] = u[MEC_INPUTS.mu_n] + (u[k] * e0 + u[k + 1] * e1)
    out[1] = u[MEC_INPUTS.mu_n + 1] + (u[k + 2] * e0 + u[k + 3] * e1)
    return out


@jit
def frit_eta(x, F_j, h_j, j):
    """Row ``j`` of ``eta = M mu - F (h - M h)`` (eq. 20; erratum E1: eq. 25 prints ``+``).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.zeros(TUNER_STATE.size)
    >>> x[TUNER_STATE.Mmu], x[TUNER_STATE.Mh] = 0.5, 0.25  # row 0: M mu, M h
    >>> float(frit_eta(x, 2.0, 0.375, 0))  # 0.5 - 2 (0.375 - 0.25)
    0.25
    """
    return x[TUNER_STATE.Mmu + j] - F_j * (h_j - x[TUNER_STATE.Mh + j])


@jit
def tuner_filters(x, e, mu0, mu1, h0, h1, p, xn):
    """Advance the tuner's ``M_j`` filters by one sample into ``xn`` (ZOH-exact ``M``).

    ``m[k+1] = a_j m[k] + (1 - a_j) v[k]`` for ``v = hn - h``, ``mu_j`` and ``h_j``.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.zeros(TUNER.size); p[TUNER.slice("a")] = 0.5
    >>> xn = np.zeros(TUNER_STATE.size)
    >>> _ = tuner_filters(np.zeros(TUNER_STATE.size), (1.0, 0.0), 0.0, 0.0, 2.0, 0.0, p, xn)
    >>> xn[TUNER_STATE.slice("Mh")].tolist()  # halfway from 0 to h = (2, 0)
    [1.0, 0.0]
    """
    S = TUNER_STATE
    a0, a1 = p[TUNER.a], p[TUNER.a + 1]
    xn[S.Mxi1] = a0 * x[S.Mxi1] + (1 - a0) * e[0]
    xn[S.Mxi1 + 1] = a0 * x[S.Mxi1 + 1] + (1 - a0) * e[1]
    xn[S.Mxi2] = a1 * x[S.Mxi2] + (1 - a1) * e[0]
    xn[S.Mxi2 + 1] = a1 * x[S.Mxi2 + 1] + (1 - a1) * e[1]
    xn[S.Mmu] = a0 * x[S.Mmu] + (1 - a0) * mu0
    xn[S.Mmu + 1] = a1 * x[S.Mmu + 1] + (1 - a1) * mu1
    xn[S.Mh] = a0 * x[S.Mh] + (1 - a0) * h0
    xn[S.Mh + 1] = a1 * x[S.Mh + 1] + (1 - a1) * h1
    return xn


@jit
def tuner_frozen(e, p):
    """Which rows the threshold freezes this step, as a pair of booleans.

    Row reading (the default): row ``j`` is frozen while ``|hn_j - h_j| < psi_j``.
    Joint reading: both rows are frozen while ``|hn_j - h_j| < psi_j`` for both
    ``j`` (``max |hn - h| < psi`` when ``psi1 = psi2``), and both update otherwise.

    Examples
    --------
    >>> import numpy as np
    >>> p = np.zeros(TUNER.size); p[TUNER.slice("psi")] = 0.1
    >>> tuple(map(bool, tuner_frozen((0.05, 0.2), p)))
    (True, False)
    >>> p[TUNER.joint] = 1.0
    >>> tuple(map(bool, tuner_frozen((0.05, 0.2), p)))
    (False, False)
    """
    below0 = abs(e[0]) < p[TUNER.psi]
    below1 = abs(e[1]) < p[TUNER.psi + 1]
    if p[TUNER.joint] != 0.0:
        both = below0 and below1
        return both, both
    return below0, below1


@jit
def tuner_update(t, x, u, p, out):
    """One step of the FRIT tuner (eq. 24-30, errata E1-E2).

    Parameters :data:`TUNER`, state :data:`TUNER_STATE`, inputs :data:`TUNER_INPUTS`.

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.blocks.frit import frit_tuner
    >>> tuner = frit_tuner(F=1.0, Ts=np.log(2.0))  # a = exp(-F Ts) = 1/2
    >>> u = TUNER_INPUTS.pack(mu=[0, 0], h=[1.0, 1.0], hn=[1.0, 1.0])
    >>> x = tuner_update(0.0, tuner.x0, u, tuner.kernels.params, np.empty(TUNER_STATE.size))
    >>> x[TUNER_STATE.slice('Mh')].round(12).tolist()  # M h moves halfway to h
    [0.5, 0.5]
    """
    S = TUNER_STATE
    lam, kappa = p[TUNER.lambda_], p[TUNER.kappa]
    xn = copy_into(x, out)
    mu0, mu1 = u[TUNER_INPUTS.mu], u[TUNER_INPUTS.mu + 1]
    h0, h1 = u[TUNER_INPUTS.h], u[TUNER_INPUTS.h + 1]
    hn0, hn1 = u[TUNER_INPUTS.hn], u[TUNER_INPUTS.hn + 1]
    e = (hn0 - h0, hn1 - h1)
    h = (h0, h1)
    tuner_filters(x, e, mu0, mu1, h0, h1, p, xn)
    # the regressors of this step: the filters before this sample (ZOH reading) or
    # after it (feedthrough reading, the current sample included)
    src = xn if p[TUNER.feedthrough] != 0.0 else x
    safe = p[TUNER.safeguard] != 0.0
    # the paper's threshold psi on |hn - h|, or the safeguard's scale-free dead zone
    frozen = safeguard_dead_zone(x, src, h, p) if safe else tuner_frozen(e, p)
    updated = False
    for j in range(2):
        if frozen[j]:
            continue  # threshold or dead zone: row j frozen
        if safe:
            xi0, xi1, eta, norm = normalised_row(src, p, h[j], j)
            if norm == 0.0:
                continue  # no data in this row (joint reading: the other row had some)
        else:
            xi0, xi1 = src[S.Mxi1 + 2 * j], src[S.Mxi1 + 2 * j + 1]  # Mxi2 follows Mxi1
            eta = frit_eta(src, p[TUNER.F + j], h[j], j)
        k0 = S.Khat + 2 * j  # Khat row j
        pk = S.P1 + 4 * j    # P_j (P2 follows P1)
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
        if safe:
            bound_covariance(xn, pk, p[TUNER.p_min], p[TUNER.p_max])
            updated = True
            continue  # K follows below, once Khat is projected as a whole
        kk = S.K + 2 * j
        xn[kk] = (1 - kappa) * x[kk] + kappa * xn[k0]
        xn[kk + 1] = (1 - kappa) * x[kk + 1] + kappa * xn[k0 + 1]
    if updated:
        project_stable_gain(xn, S.Khat, p[TUNER.Ts], p[TUNER.rho])
        for i in range(4):  # a convex combination of two stable-set gains stays in the set
            xn[S.K + i] = (1 - kappa) * x[S.K + i] + kappa * xn[S.Khat + i]
    return out


@jit
def normalised_row(x, p, h_j, j):
    """Row ``j`` of the regression divided by ``|xi_j|``: ``(xi0, xi1, eta, |xi_j|)``.

    The safeguard's scale-free regression: ``xi_j = M_j (hn - h)`` and ``eta_j`` both carry
    the units of ``h``, so after the division the regressor is a unit vector and the
    target is in the units of ``K`` (1/s), whatever the units of ``h``. Where
    ``xi_j = 0`` the row holds no data and is returned unchanged with norm 0.

    Examples
    --------
    >>> import numpy as np
    >>> x = TUNER_STATE.pack(Mxi1=[3.0, 4.0], Mxi2=[0.0, 0.0], Mmu=[10.0, 0.0],
    ...                      Mh=[0.0, 0.0], Khat=np.zeros(4), P1=np.zeros(4), P2=np.zeros(4),
    ...                      K=np.zeros(4))
    >>> p = TUNER.pack(F=[1.0, 1.0], a=[0.5, 0.5], lambda_=1.0, kappa=1.0, psi=[0.0, 0.0],
    ...                feedthrough=0.0, joint=0.0, safeguard=1.0, p_min=0.0, p_max=1.0,
    ...                deadzone=0.0, rho=0.9, Ts=0.1)
    >>> tuple(map(float, normalised_row(x, p, 0.0, 0)))  # eta = M mu - F (h - M h) = 10, |xi| = 5
    (0.6, 0.8, 2.0, 5.0)
    """
    xi0, xi1 = x[TUNER_STATE.Mxi1 + 2 * j], x[TUNER_STATE.Mxi1 + 2 * j + 1]
    eta = frit_eta(x, p[TUNER.F + j], h_j, j)
    norm = math.sqrt(xi0 * xi0 + xi1 * xi1)
    if norm == 0.0:
        return xi0, xi1, eta, 0.0
    return xi0 / norm, xi1 / norm, eta / norm, norm


@jit
def safeguard_dead_zone(x, src, h, p):
    """Which rows the safeguard's dead zone freezes this step, as a pair of booleans.

    It takes the place of the paper's threshold ``psi``, which compares ``|hn_j - h_j|``
    with a number whose units the paper does not state. Row ``j`` is frozen while its
    normalised prediction error ``|eta_j - Khat_j xi_j| / |xi_j|`` (1/s, the same in any
    units of ``h``; :func:`normalised_row`) is at most ``deadzone``, or while
    ``xi_j = 0``. Joint reading: both rows are frozen while both would be, as for ``psi``.
    ``x`` holds ``Khat`` (before this step), ``src`` the regressors of this step.

    Examples
    --------
    >>> import numpy as np
    >>> x = TUNER_STATE.pack(Mxi1=[3.0, 4.0], Mxi2=[1.0, 0.0], Mmu=[10.0, 0.1],
    ...                      Mh=[0.0, 0.0], Khat=[2.0, 0.0, 0.0, 0.0], P1=np.zeros(4),
    ...                      P2=np.zeros(4), K=np.zeros(4))
    >>> p = TUNER.pack(F=[1.0, 1.0], a=[0.5, 0.5], lambda_=1.0, kappa=1.0, psi=[0.0, 0.0],
    ...                feedthrough=0.0, joint=0.0, safeguard=1.0, p_min=0.0, p_max=1.0,
    ...                deadzone=0.5, rho=0.9, Ts=0.1)
    >>> tuple(map(bool, safeguard_dead_zone(x, x, (0.0, 0.0), p)))  # |2 - 1.2|, |0.1 - 0|
    (False, True)
    >>> p[TUNER.joint] = 1.0
    >>> tuple(map(bool, safeguard_dead_zone(x, x, (0.0, 0.0), p)))
    (False, False)
    """
    inside = [True, True]
    for j in range(2):
        xi0, xi1, eta, norm = normalised_row(src, p, h[j], j)
        k0 = TUNER_STATE.Khat + 2 * j
        if norm > 0.0:
            inside[j] = abs(eta - (x[k0] * xi0 + x[k0 + 1] * xi1)) <= p[TUNER.deadzone]
    if p[TUNER.joint] != 0.0:
        both = inside[0] and inside[1]
        return both, both
    return inside[0], inside[1]


@jit
def bound_covariance(x, o, p_min, p_max):
    """Clip the eigenvalues of the symmetric 2x2 ``P`` at ``x[o:o+4]`` to ``[p_min, p_max]``.

    The safeguard's covariance bound: ``P`` cannot wind up in directions the data do not
    excite (``<= p_max``) nor collapse where they do (``>= p_min``, so the tuner keeps
    learning and re-tunes when the plant changes).

    Examples
    --------
    >>> import numpy as np
    >>> x = np.array([50.0, 0.0, 0.0, 1e-9])
    >>> bound_covariance(x, 0, 1e-3, 10.0).tolist()
    [10.0, 0.0, 0.0, 0.001]
    """
    a, b, d = x[o], 0.5 * (x[o + 1] + x[o + 2]), x[o + 3]
    mean, half = 0.5 * (a + d), math.sqrt(0.25 * ((a - d) * (a - d)) + b * b)  # (not ** 2:
    # Python squares with the C library's pow, compiled code multiplies; this is both)
    l1, l2 = mean + half, mean - half
    c1, c2 = min(max(l1, p_min), p_max), min(max(l2, p_min), p_max)
    if c1 == l1 and c2 == l2:
        return x
    if half == 0.0:  # P = l I: any basis
        v0, v1 = 1.0, 0.0
    elif abs(b) > 0.0:
        v0, v1 = b, l1 - a
        n = math.sqrt(v0 * v0 + v1 * v1)
        v0, v1 = v0 / n, v1 / n
    else:
        v0, v1 = (1.0, 0.0) if a >= d else (0.0, 1.0)
    # P = c1 v v^T + c2 w w^T with w = v rotated by 90 degrees
    x[o] = c1 * v0 * v0 + c2 * v1 * v1
    x[o + 1] = x[o + 2] = (c1 - c2) * v0 * v1
    x[o + 3] = c1 * v1 * v1 + c2 * v0 * v0
    return x


@jit
def project_stable_gain(x, o, Ts, rho):
    """Project the 2x2 gain at ``x[o:o+4]`` (row-major) onto ``|| I - Ts K ||_2 <= rho``.

    The sampled error loop of the MEC, ``e[k+1] = (I - Ts K) e[k] + ...``, is stable when
    the spectral radius of ``I - Ts K`` is below 1; the spectral norm bounds it, and unlike
    the spectral radius it defines a convex set (a norm ball around ``K = I / Ts``), so the
    projection is unique and the low-pass law (eq. 30), a convex combination, stays inside.
    The projection clips the singular values of ``M = I - Ts K`` to ``rho`` (nearest point
    in the Frobenius norm).

    Examples
    --------
    >>> import numpy as np
    >>> K = np.array([-1.0, 0.0, 0.0, 5.0])  # a negative eigenvalue: unstable error loop
    >>> project_stable_gain(K, 0, 0.1, 0.98).round(6).tolist()
    [0.2, 0.0, 0.0, 5.0]
    """
    m00, m01 = 1.0 - Ts * x[o], -Ts * x[o + 1]
    m10, m11 = -Ts * x[o + 2], 1.0 - Ts * x[o + 3]
    M = np.array([[m00, m01], [m10, m11]])
    U, s, Vt = np.linalg.svd(M)
    if s[0] <= rho:
        return x
    s0, s1 = min(s[0], rho), min(s[1], rho)
    for i in range(2):
        for k in range(2):
            m = U[i, 0] * s0 * Vt[0, k] + U[i, 1] * s1 * Vt[1, k]
            x[o + 2 * i + k] = ((1.0 if i == k else 0.0) - m) / Ts
    return x


@jit
def tuner_output(t, x, u, p, out):
    """The implemented gain ``K`` (the state's ``K``, row-major).

    It reads the state only (no feedthrough): ``K`` acts one sample after the
    data that produced it, so the MEC and the tuner form no algebraic loop.

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.blocks.frit import frit_tuner
    >>> tuner = frit_tuner(K0=0.25)  # K(0) = 0.25 I
    >>> K = tuner_output(0.0, tuner.x0, np.zeros(6), tuner.kernels.params, np.empty(4))
    >>> K.tolist()
    [0.25, 0.0, 0.0, 0.25]
    """
    return copy_into(x[TUNER_STATE.K:TUNER_STATE.K + 4], out)
