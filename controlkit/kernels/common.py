"""Kernels of the generic blocks: state output, constant source, integrator, saturation,
first-order low-pass filter.

Signature and rules: see the block contract in :mod:`controlkit._block`.
"""

from __future__ import annotations

from .._block import layout
from .._jit import jit

#: Parameters of the discrete integrator: its sampling period.
INTEGRATOR = layout("integrator parameters", Ts=1)
#: Parameters of the low-pass filter: its pole ``a = exp(-Ts / tau)``.
LOWPASS = layout("low-pass filter parameters", a=1)


@jit
def state_output(t, x, u, p, out):
    """Output equal to the state (any block whose outputs are its states).

    Examples
    --------
    >>> import numpy as np
    >>> state_output(0.0, np.array([1.0, 2.0]), np.zeros(0), np.zeros(0), np.empty(2)).tolist()
    [1.0, 2.0]
    """
    out[:] = x
    return out


@jit
def constant_output(t, x, u, p, out):
    """Output the parameters (a constant source).

    Examples
    --------
    >>> import numpy as np
    >>> constant_output(0.0, np.zeros(0), np.zeros(0), np.array([3.0]), np.empty(1)).tolist()
    [3.0]
    """
    out[:] = p
    return out


@jit
def integrator_update(t, x, u, p, out):
    """``x[k+1] = x[k] + Ts u[k]``; parameters :data:`INTEGRATOR`.

    Examples
    --------
    >>> import numpy as np
    >>> p = INTEGRATOR.pack(Ts=0.1)
    >>> integrator_update(0.0, np.array([1.0]), np.array([2.0]), p, np.empty(1)).tolist()
    [1.2]
    """
    for i in range(x.shape[0]):
        out[i] = x[i] + p[INTEGRATOR.Ts] * u[i]
    return out


@jit
def saturation_output(t, x, u, p, out):
    """``clip(u_i, -p_i, p_i)``.

    Examples
    --------
    >>> import numpy as np
    >>> limits = np.array([0.6, 2.4])
    >>> saturation_output(0.0, np.zeros(0), np.array([1.0, -3.0]), limits, np.empty(2)).tolist()
    [0.6, -2.4]
    """
    for i in range(u.shape[0]):
        out[i] = min(p[i], max(-p[i], u[i]))
    return out


@jit
def lowpass_update(t, x, u, p, out):
    """``y[k+1] = a y[k] + (1 - a) u[k]``, the exact ZOH step of ``tau y' = u - y``.

    Examples
    --------
    >>> import numpy as np
    >>> p = LOWPASS.pack(a=0.75)
    >>> lowpass_update(0.0, np.array([0.0]), np.array([1.0]), p, np.empty(1)).tolist()
    [0.25]
    """
    a = p[LOWPASS.a]
    for i in range(x.shape[0]):
        out[i] = a * x[i] + (1 - a) * u[i]
    return out
