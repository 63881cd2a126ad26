"""Kernels of the generic blocks: state output, constant source, integrator, saturation,
first-order low-pass filter.

Signature and rules: see the block contract in :class:`controlkit.blocks.contract.KernelBlock`.
"""

from __future__ import annotations

from .._jit import jit
from .layout import layout


def _copy_python(src, out):
    out[:] = src
    return out


@jit(inline=True, python=_copy_python)
def copy_into(src, out):
    """``out[:] = src`` for two vectors of one size (``ValueError`` if they differ).

    Compiled code copies element by element: for a slice assignment numba compiles its
    shape-mismatch message (string formatting) the first time a process meets one, 2-3 s
    of a diagram's first compile (numba 0.6x); Python runs the slice assignment.

    Examples
    --------
    >>> import numpy as np
    >>> copy_into(np.array([1.0, 2.0]), np.empty(2)).tolist()
    [1.0, 2.0]
    >>> copy_into(np.ones(3), np.empty(2))
    Traceback (most recent call last):
    ...
    ValueError: could not broadcast input array from shape (3,) into shape (2,)
    """
    if src.size != out.size:
        raise ValueError("copy_into: the two vectors differ in size")
    for i in range(out.size):
        out[i] = src[i]
    return out


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
    return copy_into(x, out)


@jit
def identity_output(t, x, u, p, out):
    """Output equal to the input (a zero-order hold when the block is discrete).

    Examples
    --------
    >>> import numpy as np
    >>> identity_output(0.0, np.zeros(0), np.array([1.0, 2.0]), np.zeros(0),
    ...                 np.empty(2)).tolist()
    [1.0, 2.0]
    """
    return copy_into(u, out)


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
    return copy_into(p, out)


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


@jit(inline=True)
def rk4_step(rhs, t, x, u, p, h, work, out):
    """One classical Runge-Kutta step of ``x' = rhs(t, x, u, p)`` with the input ``u`` held.

    .. math::

        k_1 &= f(t, x), \\quad k_2 = f(t + h/2,\\ x + (h/2) k_1), \\quad
        k_3 = f(t + h/2,\\ x + (h/2) k_2), \\quad k_4 = f(t + h,\\ x + h k_3), \\\\
        x^+ &= x + (h/6)(k_1 + 2 k_2 + 2 k_3 + k_4)

    This is the only RK4 of controlkit: :func:`controlkit.blocks.sampling.sample_nlsys` calls
    it from Python (with its plain-Python version) and the fast engine's compiled loop
    calls it inlined, so both paths do the same operations in the same order.

    Parameters
    ----------
    rhs : callable
        A kernel ``rhs(t, x, u, p, out)`` writing ``x'`` into ``out``.
    t : float
        Time at the start of the step.
    x : numpy.ndarray
        State at ``t``.
    u, p : numpy.ndarray
        Input (held over the step) and parameters, handed to ``rhs``.
    h : float
        Step length.
    work : tuple of five numpy.ndarray
        Scratch arrays of ``x``'s size (``k1..k4`` and the trial state), so that a
        compiled loop allocates nothing per step.
    out : numpy.ndarray
        Receives ``x^+``; may be ``x`` itself.

    Returns
    -------
    numpy.ndarray
        ``out``.

    Examples
    --------
    ``x' = x`` from 1 over one step of 0.1: the Taylor series of ``e^0.1`` to fourth order.

    >>> import numpy as np
    >>> from controlkit._jit import python_function
    >>> def grow(t, x, u, p, out):
    ...     out[:] = x
    ...     return out
    >>> work = tuple(np.empty(1) for _ in range(5))
    >>> step = python_function(rk4_step)
    >>> step(grow, 0.0, np.ones(1), None, None, 0.1, work, np.empty(1)).round(12).tolist()
    [1.105170833333]
    """
    k1, k2, k3, k4, xt = work
    rhs(t, x, u, p, k1)
    for j in range(x.shape[0]):
        xt[j] = x[j] + (h / 2) * k1[j]
    rhs(t + h / 2, xt, u, p, k2)
    for j in range(x.shape[0]):
        xt[j] = x[j] + (h / 2) * k2[j]
    rhs(t + h / 2, xt, u, p, k3)
    for j in range(x.shape[0]):
        xt[j] = x[j] + h * k3[j]
    rhs(t + h, xt, u, p, k4)
    for j in range(x.shape[0]):
        out[j] = x[j] + (h / 6) * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j])
    return out
