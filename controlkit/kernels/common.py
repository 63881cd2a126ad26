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

    The block's value is its parameter vector: a gain ``K`` row-major, say.

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.blocks.mec import constant_gain
    >>> gain = constant_gain(0.5)  # K = 0.5 I, row-major
    >>> constant_output(0.0, np.zeros(0), np.zeros(0), gain.kernels.params, np.empty(4)).tolist()
    [0.5, 0.0, 0.0, 0.5]
    """
    out[:] = p
    return out


@jit
def integrator_update(t, x, u, p, out):
    """``x[k+1] = x[k] + Ts u[k]``; parameters :data:`INTEGRATOR`.

    The exact ZOH discretisation of ``x' = u`` (the MEC's ideal model ``L_n``).

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
    """``clip(u_i, -p_i, p_i)``: the parameters are the limits, one per input (> 0).

    Examples
    --------
    >>> import numpy as np
    >>> y = saturation_output(0.0, np.zeros(0), np.array([1.0, -3.0]), np.array([0.6, 2.4]),
    ...                       np.empty(2))
    >>> y.tolist()
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
    Two steps towards a unit input with ``a = 1/2``:

    >>> import numpy as np
    >>> y = np.zeros(1)
    >>> for k in range(2):
    ...     y = lowpass_update(0.0, y, np.ones(1), LOWPASS.pack(a=0.5), np.empty(1))
    >>> y.tolist()
    [0.75]
    """
    a = p[LOWPASS.a]
    for i in range(x.shape[0]):
        out[i] = a * x[i] + (1 - a) * u[i]
    return out
