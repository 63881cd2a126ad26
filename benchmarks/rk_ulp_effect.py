"""How a last-bit difference in the right-hand side shows in the states of an adaptive
integration (benchmarks/README.md, "Compiled Runge-Kutta").

Van der Pol with ``2 tanh(y0)`` (a limit cycle): ours compiled with ``math.tanh`` (libm)
against scipy with the same Python function, and against scipy with ``numpy.tanh``
(numpy's own implementation, 1 ulp off libm for ~25% of arguments on this machine).
(Plain summation loops instead of numpy's BLAS calls were measured here too until the
integrator dropped them on 2026-11-28: README.md's column "loops vs scipy".) Ours is the
integrator compiled as a diagram's module calls it (``compiled_rk.py``). Run from the
repository root (a few seconds once the step machine is in the store)::

    python benchmarks/rk_ulp_effect.py
"""

import math

import numpy as np
import scipy.integrate
from compiled_rk import solve_ivp  # this folder's module

from controlkit._jit import jit


@jit
def vdp_tanh(t, y, args, out):
    """``y0' = y1``, ``y1' = 2 (1 - y0^2) y1 - 2 tanh(y0)``."""
    out[0] = y[1]
    out[1] = 2.0 * (1.0 - y[0] * y[0]) * y[1] - 2.0 * math.tanh(y[0])
    return out


def numpy_fun(t, y):
    """The same model with ``numpy.tanh``."""
    return np.array([y[1], 2.0 * (1.0 - y[0] * y[0]) * y[1] - 2.0 * np.tanh(y[0])])


def same_fun(t, y):
    """The compiled model's own Python code."""
    out = np.empty(2)
    vdp_tanh.py_func(t, y, None, out)
    return out


def relative(ours, theirs):
    return np.max(np.abs(ours - theirs) / np.maximum(1.0, np.abs(theirs)))


if __name__ == "__main__":
    args = (np.zeros(1), np.zeros(2), np.zeros((0, 2)))
    for horizon in (20.0, 200.0):
        T = np.linspace(0.0, horizon, 201)
        for method in ("RK45", "DOP853"):
            for rtol, atol in ((1e-3, 1e-6), (1e-8, 1e-10)):
                common = {"method": method, "t_eval": T, "rtol": rtol, "atol": atol}
                ours = solve_ivp(vdp_tanh, (0.0, horizon), [2.0, 0.0], args=args, **common)
                same = scipy.integrate.solve_ivp(same_fun, (0.0, horizon), [2.0, 0.0], **common)
                numpy = scipy.integrate.solve_ivp(numpy_fun, (0.0, horizon), [2.0, 0.0],
                                                  **common)
                print(f"T={horizon:g} {method} rtol={rtol:g}: exact vs scipy (same rhs) "
                      f"{relative(ours['y'], same.y):.1e}; exact vs scipy (numpy.tanh) "
                      f"{relative(ours['y'], numpy.y):.1e}")
