"""Kernels of the model error compensator and the FRIT tuner (spacecraft paper, eq. 13-30).

Signature and rules: see the block contract in :mod:`controlkit._block`.
"""

from __future__ import annotations

from .._jit import jit


@jit
def mec_output(t, x, u, p, out):
    """Eq. (13)-(15): ``mu = mu_n + K (hn - h)``, ``K = u[6:10]`` row-major."""
    e0 = u[2] - u[4]
    e1 = u[3] - u[5]
    out[0] = u[0] + (u[6] * e0 + u[7] * e1)
    out[1] = u[1] + (u[8] * e0 + u[9] * e1)
    return out


@jit
def tuner_update(t, x, u, p, out):
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


@jit
def tuner_output(t, x, u, p, out):
    """The implemented gain ``K`` (state, row-major)."""
    out[:] = x[20:24]
    return out
