"""The three explicit methods of ``solve_ivp`` as tableaux, and the step-size constants.

scipy's ``RungeKutta`` class (``scipy/integrate/_ivp/rk.py``, scipy 1.17) is defined by
its coefficients alone: a method *is* its tableau. Here :data:`RK23`, :data:`RK45` and
:data:`DOP853` are :class:`Tableau` records, found by name in :data:`METHODS` and by
number in :data:`TABLEAUX` (the form compiled code selects them in: numba freezes the
tuple and its arrays as constants of the step machine, which takes the method as a
run-time index, :data:`METHOD_INDEX`).
The sources of the coefficients are listed in :mod:`controlkit.engines.fast.rk`.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np

from . import dop853_coefficients

# Constants of the step-size controller (scipy's rk.py and common.py).
#: Machine epsilon of float64.
EPS = float(np.finfo(np.float64).eps)
#: Smallest relative tolerance accepted; smaller values are raised to it (as scipy does).
RTOL_FLOOR = 100 * EPS
#: Factor applied to the asymptotically optimal step.
SAFETY = 0.9
#: Largest decrease of the step after a rejection.
MIN_FACTOR = 0.2
#: Largest increase of the step after an acceptance.
MAX_FACTOR = 10.0

# Kinds of error estimate and of dense output a tableau can ask for.
#: One embedded formula: ``err = h sum_j E_j k_j``.
ERROR_EMBEDDED = 0
#: DOP853's blend of a 5th- and a 3rd-order estimate.
ERROR_DOP853 = 1
#: Dense output ``y_old + h sum_r Q_r x^(r+1)`` with ``Q = K^T P``.
DENSE_POWERS = 0
#: DOP853's 7th-order interpolant built from three extra stages.
DENSE_DOP853 = 1


Tableau = namedtuple(
    "Tableau",
    [
        "n_stages",
        "n_rows",
        "error_kind",
        "dense_kind",
        "estimator_order",
        "error_exponent",
        "C",
        "A",
        "B",
        "E",
        "E_low",
        "dense",
        "stiffness_weights",
        "stiffness_bound",
    ],
)
Tableau.__doc__ = """An explicit Runge-Kutta pair with its error estimate and dense output.

For a step of length ``h`` from ``(t, y)`` with ``f = F(t, y)`` the stages are

.. math::

    k_0 = f, \\qquad
    k_s = F\\Big(t + c_s h,\\; y + h \\sum_{j<s} a_{sj} k_j\\Big), \\quad s = 1..S-1, \\qquad
    y_{new} = y + h \\sum_{j<S} b_j k_j, \\qquad k_S = F(t + h, y_{new})

(``k_S`` is reused as the next step's ``k_0``, "first same as last"). The error
estimate is ``h sum_{j<=S} e_j k_j`` (DOP853 blends two, see ``error_kind``) and the
dense output over the step is built from the same stages (``dense_kind``).

Attributes
----------
n_stages : int
    ``S``, the stages of one step (evaluations per trial step).
n_rows : int
    Rows of the stage array ``K``: ``S + 1``, plus the extra stages of the dense output.
error_kind : int
    :data:`ERROR_EMBEDDED` or :data:`ERROR_DOP853`.
dense_kind : int
    :data:`DENSE_POWERS` or :data:`DENSE_DOP853`.
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
    ``P`` (``(S+1) x p``) for :data:`DENSE_POWERS`, ``D`` (``4 x n_rows``) for
    :data:`DENSE_DOP853`.
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


def _tableau(*, n_stages, error_kind, dense_kind, estimator_order, C, A, B, E, E_low, dense,
             stiffness_bound=0.0):
    """Pack a tableau as C-contiguous float64 arrays (numba freezes such globals)."""
    C = np.ascontiguousarray(C, dtype=np.float64)
    A = np.ascontiguousarray(A, dtype=np.float64)
    n_rows = C.shape[0] if C.shape[0] > n_stages else n_stages + 1
    weights = np.zeros(n_stages)
    if stiffness_bound:
        assert C[n_stages - 1] == 1.0, "the stiffness test needs a last stage at t + h"
        weights = np.asarray(B, dtype=np.float64) - A[n_stages - 1, :n_stages]
    return Tableau(
        n_stages=int(n_stages),
        n_rows=int(n_rows),
        error_kind=int(error_kind),
        dense_kind=int(dense_kind),
        estimator_order=int(estimator_order),
        error_exponent=-1 / (estimator_order + 1),
        C=C,
        A=A,
        B=np.ascontiguousarray(B, dtype=np.float64),
        E=np.ascontiguousarray(E, dtype=np.float64),
        E_low=np.ascontiguousarray(E_low, dtype=np.float64),
        dense=np.ascontiguousarray(dense, dtype=np.float64),
        stiffness_weights=np.ascontiguousarray(weights),
        stiffness_bound=float(stiffness_bound),
    )


#: Bogacki-Shampine 3(2) with its cubic Hermite dense output (Bogacki & Shampine 1989).
RK23 = _tableau(
    n_stages=3,
    error_kind=ERROR_EMBEDDED,
    dense_kind=DENSE_POWERS,
    estimator_order=2,
    C=[0, 1 / 2, 3 / 4],
    A=[[0, 0, 0], [1 / 2, 0, 0], [0, 3 / 4, 0]],
    B=[2 / 9, 1 / 3, 4 / 9],
    E=[5 / 72, -1 / 12, -1 / 9, 1 / 8],
    E_low=[0.0, 0.0, 0.0, 0.0],
    dense=[[1, -4 / 3, 5 / 9], [0, 1, -2 / 3], [0, 4 / 3, -8 / 9], [0, -1, 1]],
)

#: Dormand-Prince 5(4) (Dormand & Prince 1980) with Shampine's quartic dense output
#: (Shampine 1986).
RK45 = _tableau(
    n_stages=6,
    error_kind=ERROR_EMBEDDED,
    dense_kind=DENSE_POWERS,
    estimator_order=4,
    C=[0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1],
    A=[
        [0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0],
    ],
    B=[35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84],
    E=[-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40],
    E_low=[0.0] * 7,
    dense=[
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [
            0,
            131558114200 / 32700410799,
            -68118460800 / 10900136933,
            87487479700 / 32700410799,
        ],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [
            0,
            127303824393 / 49829197408,
            -318862633887 / 49829197408,
            701980252875 / 199316789632,
        ],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ],
    stiffness_bound=3.25,
)


#: Hairer's DOP853: 8th order, 5th/3rd-order error estimate, 7th-order dense output
#: (Hairer, Norsett & Wanner 1993, Sec. II.5-II.6).
DOP853 = _tableau(
    n_stages=12,
    error_kind=ERROR_DOP853,
    dense_kind=DENSE_DOP853,
    estimator_order=7,
    C=dop853_coefficients.C,
    A=dop853_coefficients.A,
    B=dop853_coefficients.B,
    E=dop853_coefficients.E5,
    E_low=dop853_coefficients.E3,
    dense=dop853_coefficients.D,
    stiffness_bound=6.1,
)

#: The methods by the names ``solve_ivp`` knows them by.
METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853}

#: The tableaux by number, the form compiled code selects them in (frozen as constants).
TABLEAUX = (RK23, RK45, DOP853)
#: The number of each method in :data:`TABLEAUX`.
METHOD_INDEX = {name: TABLEAUX.index(tableau) for name, tableau in METHODS.items()}
