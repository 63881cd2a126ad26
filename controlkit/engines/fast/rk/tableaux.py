"""The three explicit methods of ``solve_ivp`` as tableaux, and the step-size constants.

A method *is* its tableau, read from scipy's own classes (``RK23``, ``RK45``, ``DOP853``:
their ``C``, ``A``, ``B``, ``E``, ``P`` and DOP853's ``E5``, ``E3``, ``D``, ``A_EXTRA``,
``C_EXTRA``), so they are the doubles scipy steps with, whatever its version. Found by name
in :data:`METHODS` and by number in :data:`TABLEAUX`: numba freezes the tuple as constants
of the step machine, which takes the method as a run-time index (:data:`METHOD_INDEX`).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
import scipy.integrate

# Constants of the step-size controller (scipy's rk.py and common.py).
#: Smallest relative tolerance accepted; smaller values are raised to it (as scipy does).
RTOL_FLOOR = 100 * float(np.finfo(np.float64).eps)
#: Factor applied to the asymptotically optimal step.
SAFETY = 0.9
#: Largest decrease of the step after a rejection.
MIN_FACTOR = 0.2
#: Largest increase of the step after an acceptance.
MAX_FACTOR = 10.0


Tableau = namedtuple("Tableau", ["n_stages", "n_rows", "dop853", "estimator_order",
                                 "error_exponent", "C", "A", "B", "E", "E_low", "dense",
                                 "stiffness_weights", "stiffness_bound"])
Tableau.__doc__ = """An explicit Runge-Kutta pair with its error estimate and dense output.

For a step of length ``h`` from ``(t, y)`` with ``f = F(t, y)`` the stages are

.. math::

    k_0 = f, \\qquad
    k_s = F\\Big(t + c_s h,\\; y + h \\sum_{j<s} a_{sj} k_j\\Big), \\quad s = 1..S-1, \\qquad
    y_{new} = y + h \\sum_{j<S} b_j k_j, \\qquad k_S = F(t + h, y_{new})

(``k_S`` is reused as the next step's ``k_0``, "first same as last"). The error
estimate is ``h sum_{j<=S} e_j k_j`` (DOP853 blends two) and the dense output over the
step is built from the same stages.

Attributes
----------
n_stages : int
    ``S``, the stages of one step (evaluations per trial step).
n_rows : int
    Rows of the stage array ``K``: ``S + 1``, plus the extra stages of the dense output.
dop853 : bool
    DOP853's error estimate (a blend of a 5th- and a 3rd-order one) and 7th-order
    interpolant (from three extra stages); else one embedded estimate,
    ``err = h sum_j E_j k_j``, and the interpolant ``y_old + h sum_r Q_r x^(r+1)`` with
    ``Q = K^T P``.
estimator_order : int
    ``q``, order of the error estimate (the error scales as ``h^(q+1)``).
error_exponent : float
    ``-1 / (q + 1)``.
C, A, B : numpy.ndarray
    Nodes (``S``; DOP853: ``n_rows``), coefficients (lower triangle; DOP853's rows past
    ``S`` are the extra stages of its dense output) and weights (``S``).
E, E_low : numpy.ndarray
    Error weights over ``k_0..k_S``; ``E_low`` is DOP853's 3rd-order one (zeros else).
dense : numpy.ndarray
    ``P`` (``(S+1) x p``), or DOP853's ``D`` (``4 x n_rows``).
stiffness_weights : numpy.ndarray
    ``w_j = b_j - a_{S-1,j}`` (``S``): ``y_new - y_{S-1} = h sum_j w_j k_j``, the
    difference between the new state and the argument of the last stage, which both
    sit at ``t + h`` when ``c_{S-1} = 1`` (Hairer's stiffness test, see
    ``stiffness_bound``).
stiffness_bound : float
    The bound on the estimate ``|h lambda| = |k_S - k_{S-1}| / |sum_j w_j k_j|`` of the
    step size times the Jacobian's largest eigenvalue along the step above which a step
    is limited by stability rather than accuracy: 3.25 for RK45 and 6.1 for DOP853, the
    values of Hairer's codes DOPRI5 and DOP853 (Hairer & Wanner, *Solving Ordinary
    Differential Equations II*, 2nd ed., Sec. IV.2); 0 for RK23, whose last stage is not
    at ``t + h`` (no test).

Examples
--------
Dormand-Prince 5(4): six stages, a 7th row for the "first same as last" stage; its
weights satisfy the first two order conditions, ``sum b_j = 1`` and
``sum b_j c_j = 1/2``:

>>> from controlkit.engines.fast.rk import METHODS
>>> RK45 = METHODS["RK45"]
>>> RK45.n_stages, RK45.n_rows, RK45.estimator_order
(6, 7, 4)
>>> round(float(RK45.B.sum()), 14), round(float(RK45.B @ RK45.C), 14)
(1.0, 0.5)
"""


def _tableau(method, *, stiffness_bound=0.0):
    """Pack scipy's ``method`` class as a tableau of C-contiguous float64 arrays.

    numba freezes such globals. ``A`` is square over the rows of the stage array: row
    ``S`` holds the weights (the step's last stage, ``F(t + h, y_new)``); DOP853's rows
    past it are the three extra stages of its dense output (scipy's ``A_EXTRA``).
    """
    S = method.n_stages
    dop853 = method is scipy.integrate.DOP853
    if dop853:
        C = np.concatenate([method.C, [1.0], method.C_EXTRA])
        A = np.zeros((C.shape[0], C.shape[0]))
        A[S, :S] = method.B
        A[S + 1 :] = method.A_EXTRA
    else:
        C = method.C
        A = np.zeros((S, S))
    A[:S, : method.A.shape[1]] = method.A
    weights = method.B - A[S - 1, :S] if stiffness_bound else np.zeros(S)
    assert not stiffness_bound or C[S - 1] == 1.0, "the stiffness test needs c_(S-1) = 1"
    packed = dict(C=C, A=A, B=method.B, E=method.E5 if dop853 else method.E,
                  E_low=method.E3 if dop853 else np.zeros(S + 1),
                  dense=method.D if dop853 else method.P, stiffness_weights=weights)
    return Tableau(
        n_stages=int(S),
        n_rows=int(C.shape[0] if dop853 else S + 1),
        dop853=dop853,
        estimator_order=int(method.error_estimator_order),
        error_exponent=-1 / (method.error_estimator_order + 1),
        stiffness_bound=float(stiffness_bound),
        **{name: np.ascontiguousarray(value, dtype=np.float64)
           for name, value in packed.items()},
    )


#: Bogacki-Shampine 3(2) with its cubic Hermite dense output (Bogacki & Shampine 1989).
RK23 = _tableau(scipy.integrate.RK23)
#: Dormand-Prince 5(4) (Dormand & Prince 1980) with Shampine's quartic dense output
#: (Shampine 1986); Hairer's stiffness bound of DOPRI5.
RK45 = _tableau(scipy.integrate.RK45, stiffness_bound=3.25)
#: Hairer's DOP853: 8th order, 5th/3rd-order error estimate, 7th-order dense output
#: (Hairer, Norsett & Wanner 1993, Sec. II.5-II.6); the stiffness bound of his code.
DOP853 = _tableau(scipy.integrate.DOP853, stiffness_bound=6.1)

#: The methods by the names ``solve_ivp`` knows them by.
METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853}

#: The tableaux by number, the form compiled code selects them in (frozen as constants).
TABLEAUX = (RK23, RK45, DOP853)
#: The number of each method in :data:`TABLEAUX`.
METHOD_INDEX = {name: TABLEAUX.index(tableau) for name, tableau in METHODS.items()}
