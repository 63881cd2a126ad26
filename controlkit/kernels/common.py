"""Kernels of the generic blocks: state output, constant source, integrator, saturation."""

from __future__ import annotations

from .._block import layout
from .._jit import jit

#: Parameters of the discrete integrator: its sampling period.
INTEGRATOR = layout("integrator parameters", Ts=1)


@jit
def state_output(t, x, u, p, out):
    """Output equal to the state (any block whose outputs are its states)."""
    out[:] = x
    return out


@jit
def constant_output(t, x, u, p, out):
    """Output the parameters (a constant source)."""
    out[:] = p
    return out


@jit
def integrator_update(t, x, u, p, out):
    """``x[k+1] = x[k] + Ts u[k]``; parameters :data:`INTEGRATOR`."""
    for i in range(x.shape[0]):
        out[i] = x[i] + p[INTEGRATOR.Ts] * u[i]
    return out


@jit
def saturation_output(t, x, u, p, out):
    """``clip(u_i, -p_i, p_i)``."""
    for i in range(u.shape[0]):
        out[i] = min(p[i], max(-p[i], u[i]))
    return out
