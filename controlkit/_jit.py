"""Optional numba compilation of the kernels.

With numba installed (``pip install controlkit[fast]``) every kernel is
compiled once and cached on disk; without it, or with the environment
variable ``CONTROLKIT_DISABLE_NUMBA=1``, the same functions run as plain
Python. Both the python-control path and the fast engine call the kernels
through this module, so both compute with the same code.
"""

from __future__ import annotations

import os

try:
    if os.environ.get("CONTROLKIT_DISABLE_NUMBA", "") not in ("", "0"):
        raise ImportError("disabled by CONTROLKIT_DISABLE_NUMBA")
    import numba
except ImportError:
    numba = None

#: True when kernels are compiled with numba.
HAVE_NUMBA = numba is not None


def jit(function=None, *, inline=False):
    """Compile ``function`` with numba (cached) when available; else return it unchanged.

    Every kernel and every helper a kernel calls is decorated with ``@jit``.
    ``@jit(inline=True)`` marks a helper that takes a kernel as an argument
    (:func:`controlkit.kernels.common.rk4_step`): numba inlines it into its caller
    before typing, so the kernel it is handed is a constant there and the caller's
    compiled loop can still be cached on disk.

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.kernels.common import constant_output  # decorated with @jit
    >>> constant_output(0.0, np.zeros(0), np.zeros(0), np.array([1.5]), np.zeros(1)).tolist()
    [1.5]
    """
    if function is None:
        return lambda f: jit(f, inline=inline)
    if numba is None:
        return function
    if inline:
        return numba.njit(cache=True, inline="always")(function)
    return numba.njit(cache=True)(function)


def python_function(function):
    """The plain Python function behind a :func:`jit`-decorated one.

    Examples
    --------
    >>> from controlkit.kernels.common import rk4_step
    >>> python_function(rk4_step).__name__
    'rk4_step'
    """
    return getattr(function, "py_func", function)
