"""The Jacobians of one block at an operating point: exact where they can be, else central
differences with a step chosen per variable.

:func:`block_jacobians` returns ``(A, B, C, D)`` of one block (no interconnect) at
``(t, x, u)``, with the method it used:

- ``"linear"``: a :class:`control.StateSpace` (summing junctions, transfer functions
  turned state space by ``interconnect``): its own matrices.
- ``"exact"``: a :class:`~controlkit.blocks.contract.KernelBlock` whose kernels have a
  Jacobian derived by hand (:mod:`controlkit.analysis.exact`).
- ``"rk4 (exact)"``: a continuous block sampled by
  :func:`~controlkit.blocks.sampling.sample_nlsys` with RK4: the derivative of the very
  RK4 map the block computes, chained through its four stages from the continuous block's
  Jacobians (exact to rounding when those are). With ``method="solve_ivp"``:
  ``"variational (solve_ivp)"``, the variational equations ``Phi' = A(t, x) Phi`` integrated
  beside the state with the block's DOP853 and tolerances.
- ``"central differences"``: anything else (a user's function, a kernel without a
  derived Jacobian). Column ``j`` is ``(f(z + h_j e_j) - f(z - h_j e_j)) / (2 h_j)`` with
  ``h_j = eps^(1/3) max(1, |z_j|)``, ``eps`` the machine epsilon (``h ~ 6e-6``): the
  truncation error is ``h^2 |f'''| / 6`` and the rounding error ``eps |f| / h``, both about
  ``1e-11`` relative for a function that varies on the scale of ``max(1, |z_j|)``. (The
  complex step would reach rounding level, but a user's ``np.clip``, ``abs`` or ``float()``
  silently breaks it, so it is not used.) python-control's own ``linearize`` takes
  forward differences with one step ``1e-6`` for every variable: errors of order ``1e-6``.
"""

from __future__ import annotations

import control as ct
import numpy as np
import scipy.integrate

from ..blocks.contract import KernelBlock
from ..blocks.sampling import SampledSystem
from .exact import EXACT

#: The step of the central differences relative to ``max(1, |z_j|)``: ``eps^(1/3)``
#: balances truncation (``h^2``) against rounding (``eps / h``).
RELATIVE_STEP = float(np.finfo(float).eps) ** (1.0 / 3.0)


def block_jacobians(block, t, x, u, params, *, step=None):
    """``(A, B, C, D, method)`` of one block at ``(t, x, u)``.

    Parameters
    ----------
    block : control.InputOutputSystem
        A block that is not an interconnect.
    t : float
        Time.
    x, u : numpy.ndarray
        The block's state and input.
    params : dict
        python-control's parameters as the block sees them in its diagram.
    step : float, optional
        A fixed step for the central differences instead of the per-variable one.

    Returns
    -------
    tuple
        ``A`` (n x n), ``B`` (n x m), ``C`` (p x n), ``D`` (p x m) and the method, one of
        the strings listed in the module's description.

    Examples
    --------
    >>> from controlkit.blocks.mec import nominal_model
    >>> A, B, C, D, how = block_jacobians(nominal_model(0.1), 0.0, np.zeros(2), np.zeros(2),
    ...                                   {})
    >>> B.tolist(), how
    ([[0.1, 0.0], [0.0, 0.1]], 'exact')
    """
    if isinstance(block, ct.StateSpace):
        return block.A, block.B, block.C, block.D, "linear"
    if isinstance(block, SampledSystem):
        return _sampled(block, t, x, u, params, step)
    exact = _exact(block)
    if exact is not None:
        output, update = exact
        p = block.kernels.params
        C, D = output(t, x, u, p)
        A, B = update(t, x, u, p) if update is not None else (np.zeros((0, 0)),
                                                               np.zeros((0, u.size)))
        return A, B, C, D, "exact"
    A, B = _differences(block, "dynamics", t, x, u, params, step, block.nstates)
    C, D = _differences(block, "output", t, x, u, params, step, block.noutputs)
    return A, B, C, D, "central differences"


def _exact(block):
    """The pair of exact Jacobians of a kernel block, or None."""
    kernels = getattr(block, "kernels", None) if isinstance(block, KernelBlock) else None
    if kernels is None or kernels.output not in EXACT:
        return None
    if kernels.update is not None and kernels.update not in EXACT:
        return None
    return EXACT[kernels.output], (None if kernels.update is None else EXACT[kernels.update])


def _differences(block, which, t, x, u, params, step, rows):
    """Central differences of ``block.dynamics`` or ``block.output`` in ``(x, u)``."""
    n = x.size
    z = np.concatenate([x, u])
    J = np.zeros((rows, z.size))
    if rows == 0 or (which == "dynamics" and block.nstates == 0):
        return J[:, :n], J[:, n:]
    function = getattr(block, which)
    labels = [f"state {s!r}" for s in block.state_labels] + [
        f"input {s!r}" for s in block.input_labels]
    for j in range(z.size):
        h = step if step is not None else RELATIVE_STEP * max(1.0, abs(z[j]))
        plus, minus = z.copy(), z.copy()
        plus[j] += h
        minus[j] -= h
        ends = [np.asarray(function(t, v[:n], v[n:], params), dtype=float).reshape(-1)
                for v in (plus, minus)]
        if not all(np.all(np.isfinite(e)) for e in ends):
            raise ValueError(f"block {block.name!r}: its {which} is not finite within "
                             f"{h:.2g} of the operating point along {labels[j]}, so it has "
                             f"no derivative there")
        J[:, j] = (ends[0] - ends[1]) / (plus[j] - minus[j])  # the step as represented
    return J[:, :n], J[:, n:]


def _sampled(block, t, x, u, params, step):
    """The derivative of a sampled block's map over one sample (RK4 or DOP853)."""
    continuous = block.continuous
    n, m = x.size, u.size
    lifted = np.hstack([np.zeros((m, n)), np.eye(m)])  # du/d(x, u)

    def jacobian(tau, xi):
        A, B, _, _, how = block_jacobians(continuous, tau, xi, u, params, step=step)
        return A, B, how

    def rhs(tau, xi):
        return np.asarray(continuous.dynamics(tau, xi, u, params), dtype=float)

    if block.method == "rk4":
        h = block.dt / block.substeps
        X = np.hstack([np.eye(n), np.zeros((n, m))])
        xk = np.array(x, dtype=float)
        for i in range(block.substeps):  # the stages of rk4_step, each with its derivative
            ti = t + i * h
            stages = []  # (k, dk/dz)
            for c, previous in ((0.0, None), (0.5, 0), (0.5, 1), (1.0, 2)):
                xs, dxs = (xk, X) if previous is None else (
                    xk + (c * h) * stages[previous][0], X + (c * h) * stages[previous][1])
                A, B, how = jacobian(ti + c * h, xs)
                stages.append((rhs(ti + c * h, xs), A @ dxs + B @ lifted))
            (k1, d1), (k2, d2), (k3, d3), (k4, d4) = stages
            xk = xk + (h / 6) * (k1 + 2 * k2 + 2 * k3 + k4)
            X = X + (h / 6) * (d1 + 2 * d2 + 2 * d3 + d4)
        method = "rk4 (exact)" if how in ("exact", "linear") else f"rk4 of {how}"
    else:
        def variational(tau, y):
            A, B, _ = jacobian(tau, y[:n])
            Phi = y[n:].reshape(n, n + m)
            return np.concatenate([rhs(tau, y[:n]), (A @ Phi + B @ lifted).ravel()])

        start = np.concatenate([x, np.hstack([np.eye(n), np.zeros((n, m))]).ravel()])
        sol = scipy.integrate.solve_ivp(variational, (t, t + block.dt), start, method="DOP853",
                                        rtol=block.rtol, atol=block.atol)
        if not sol.success:
            raise RuntimeError(f"block {block.name!r}: the variational equations failed: "
                               f"{sol.message}")
        X = sol.y[n:, -1].reshape(n, n + m)
        method = "variational (solve_ivp)"
    _, _, C, D, _ = block_jacobians(continuous, t, x, u, params, step=step)
    return X[:, :n], X[:, n:], C, D, method
