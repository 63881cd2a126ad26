"""Explicit Runge-Kutta integration that takes the steps scipy's ``solve_ivp`` takes.

The three explicit methods of :func:`scipy.integrate.solve_ivp` -- ``"RK23"``
(Bogacki-Shampine 3(2)), ``"RK45"`` (Dormand-Prince 5(4), python-control's default)
and ``"DOP853"`` (Hairer's 8(5,3)) -- rewritten as loops that numba compiles, so that a
compiled right-hand side is integrated without a Python call per stage. "The same
steps" is meant literally: the initial step, the error norm, the acceptance test, the
step-size factors, the clipping at the end of the interval and the dense output are
scipy 1.17's (``scipy/integrate/_ivp``), operation for operation. With ``exact=True``
even the linear combinations of stages are formed by the BLAS calls numpy makes for
scipy, and the results are scipy's to the last bit (see "Arithmetic" below).

A method is its tableau: :data:`RK23`, :data:`RK45` and :data:`DOP853` are
:class:`Tableau` records, found by name in :data:`METHODS` and by number in
:data:`TABLEAUX`, which the compiled code holds as constants.

The integrator is a step machine (:func:`machine`) that never calls the right-hand
side itself: it returns "evaluate it at this time and state into this row" and is
called again with the result (reverse communication). So it is compiled once, for
every right-hand side and every type of arguments, and cached on disk; what a caller
compiles is the few-line loop :func:`solve_interval`, which numba pastes into it. One
:func:`solve_interval` call does what one ``solve_ivp(fun, (t0, t1), y0, t_eval=...)``
call does -- fresh initial step, stop exactly at ``t1`` -- writing the states at the
requested times into a preallocated array. A sampled-data loop calls it once per
sample interval and updates its discrete states in between. :func:`solve_ivp` is a
Python-level convenience with scipy's argument checks around one call.

Only numpy, math and numba are used (and the standard library); without numba (or with
``CONTROLKIT_DISABLE_NUMBA=1``) the same functions run as plain Python.

References
----------
.. [1] E. Hairer, S. P. Norsett, G. Wanner, "Solving Ordinary Differential Equations I:
   Nonstiff Problems", 2nd ed., Springer, 1993, Sec. II.4 (initial step, step-size
   control) and II.5-II.6 (DOP853, dense output).
.. [2] J. R. Dormand, P. J. Prince, "A family of embedded Runge-Kutta formulae",
   J. Comput. Appl. Math. 6(1), 19-26, 1980.
.. [3] L. F. Shampine, "Some practical Runge-Kutta formulas", Math. Comp. 46(173),
   135-150, 1986 (the RK45 dense output).
.. [4] P. Bogacki, L. F. Shampine, "A 3(2) pair of Runge-Kutta formulas",
   Appl. Math. Lett. 2(4), 321-325, 1989.
.. [5] SciPy 1.17, ``scipy/integrate/_ivp/{rk,common,base,ivp}.py``.
"""

from __future__ import annotations

import math
import os
import warnings
from collections import namedtuple

import numpy as np

try:
    if os.environ.get("CONTROLKIT_DISABLE_NUMBA", "") not in ("", "0"):
        raise ImportError("disabled by CONTROLKIT_DISABLE_NUMBA")
    import numba
except ImportError:
    numba = None

#: True when the integrator is compiled with numba.
HAVE_NUMBA = numba is not None


def jit(function=None, *, inline=False):
    """Compile ``function`` with numba (cached on disk) when available; else return it.

    ``inline=True`` asks numba to paste the function into its caller before typing
    (``inline="always"``). A function that receives the right-hand side as an argument
    needs it when its caller holds that right-hand side as a global: pasted in, the
    right-hand side stays a compile-time constant of the caller, which can then be
    cached on disk (a compiled function passed as a runtime value is not cacheable).
    """
    if function is None:
        return lambda f: jit(f, inline=inline)
    if numba is None:
        return function
    if inline:
        return numba.njit(cache=True, inline="always")(function)
    return numba.njit(cache=True)(function)


if numba is not None:
    from numba.core import cgutils
    from numba.extending import intrinsic

    @intrinsic
    def _void_pointer(typingctx, address):
        """An integer address as a ``void*`` (for ``numba.carray``)."""
        if not isinstance(address, numba.types.Integer):
            return None

        def codegen(context, builder, signature, arguments):
            return builder.inttoptr(arguments[0], cgutils.voidptr_t)

        return numba.types.voidptr(address), codegen


# ----------------------------------------------------------------------------------------
# Constants of the step-size controller (scipy's rk.py and common.py)
# ----------------------------------------------------------------------------------------

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

# Status codes returned by solve_interval.
#: The interval was integrated to its end.
SUCCESS = 0
#: The step needed fell below ten times the spacing of floats at the current time.
STEP_TOO_SMALL = -1
#: The state or the right-hand side became non-finite (NaN or infinite).
NON_FINITE = -2
#: An argument is out of range (see :data:`STATUS_MESSAGES`).
INVALID_ARGUMENT = -3

#: What each status code means.
STATUS_MESSAGES = {
    SUCCESS: "The solver successfully reached the end of the integration interval.",
    STEP_TOO_SMALL: "Required step size is less than spacing between numbers.",
    NON_FINITE: "The state or its derivative became non-finite (NaN or infinite).",
    INVALID_ARGUMENT: (
        "Invalid argument: max_step must be > 0, first_step in [0, |t1 - t0|], "
        "atol >= 0 of the state's size, t0 and t1 finite, the evaluation times "
        "strictly monotone inside [t0, t1], and the work arrays of the method's size."
    ),
}

# Kinds of error estimate and of dense output a tableau can ask for.
#: One embedded formula: ``err = h sum_j E_j k_j``.
ERROR_EMBEDDED = 0
#: DOP853's blend of a 5th- and a 3rd-order estimate.
ERROR_DOP853 = 1
#: Dense output ``y_old + h sum_r Q_r x^(r+1)`` with ``Q = K^T P``.
DENSE_POWERS = 0
#: DOP853's 7th-order interpolant built from three extra stages.
DENSE_DOP853 = 1

# Layout of the workspace (see :class:`Workspace`). Scalars first, at fixed slots of
# ``work.floats`` and ``work.ints``; then, in ``work.floats``, eight vectors of the state's
# size, the interpolant's coefficients, the log of step times and the evaluation scratch.
#: ``floats`` slot: time at which the caller must evaluate the right-hand side.
T_REQUEST = 0
#: ``floats`` slot: last time reached (the end of the last accepted step).
TIME_REACHED = 1
#: ``floats`` slot: step size proposed for the next step.
NEXT_STEP = 2
#: ``floats`` slot: time of the step that failed (NaN when none failed).
TIME_FAILED = 3
_T = 4
_T_OLD = 5
_T_NEW = 6
_H = 7
_H_ABS = 8
_MIN_STEP = 9
_T0 = 10
_T1 = 11
_DIRECTION = 12
_RTOL = 13
_MAX_STEP = 14
_FIRST_STEP = 15
_H0 = 16
_D1 = 17
_RTOL_GIVEN = 18
#: Number of scalar slots at the start of ``work.floats``.
N_FLOAT_SLOTS = 19

# The vectors after the scalars, in this order (each of the state's size).
_Y = 0
_Y_NEW = 1
_Y_OLD = 2
_Y_STAGE = 3
_SCALE = 4
_ERR = 5
_ERR_LOW = 6
_ATOL = 7
_N_VECTORS = 8
#: Rows of the stage array (enough for every method).
STAGE_ROWS = 16
#: Rows of the interpolant's coefficients (DOP853 has seven, RK45 four, RK23 three).
DENSE_ROWS = 7

#: ``ints`` slot: evaluations of the right-hand side requested in this call.
NFEV = 0
#: ``ints`` slot: accepted steps.
N_ACCEPTED = 1
#: ``ints`` slot: rejected trial steps.
N_REJECTED = 2
#: ``ints`` slot: steps whose interpolant served an evaluation time.
N_DENSE = 3
#: ``ints`` slot: status of the call (once the machine returned :data:`FINISHED`).
STATUS = 4
#: ``ints`` slot: index of the first evaluation time not served yet.
NEXT_EVAL = 5
_PHASE = 6
_STAGE = 7
_REJECTED = 8
_LAST_ERROR_FINITE = 9
_EVAL_END = 10
_STOP = 11
_METHOD = 12
_EXACT = 13
_CLOSED_RIGHT = 14
_LOG_SIZE = 15
_EVAL_CAPACITY = 16
#: Number of slots of ``work.ints``.
N_INT_SLOTS = 17

#: Returned by :func:`machine` when the interval is done (or failed).
FINISHED = -1

# Phases of the step machine: what the last request was for (or where to go on).
_PHASE_BEGIN = 0
_PHASE_F0 = 1
_PHASE_F1 = 2
_PHASE_STAGE = 3
_PHASE_F_NEW = 4
_PHASE_EXTRA = 5
_PHASE_STEP = 6
_PHASE_TRIAL = 7
_PHASE_ACCEPTED = 8
_PHASE_STEP_END = 9
_PHASE_DONE = 10
_PHASE_BAD_SIZES = 11


# ----------------------------------------------------------------------------------------
# Tableaux
# ----------------------------------------------------------------------------------------

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
    ],
)
Tableau.__doc__ = """An explicit Runge-Kutta pair with its error estimate and dense output.

For a step of length ``h`` from ``(t, y)`` with ``f = F(t, y)`` the stages are

.. math::

    k_0 = f, \\qquad
    k_s = F\\Big(t + c_s h,\\; y + h \\sum_{j<s} a_{sj} k_j\\Big), \\quad s = 1..S-1, \\qquad
    y_{new} = y + h \\sum_{j<S} b_j k_j, \\qquad k_S = F(t + h, y_{new})

(``k_S`` is reused as the next step's ``k_0``, "first same as last").

Fields
------
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
    Nodes (``n_rows``), coefficients (``n_rows x n_rows``, lower triangle; the rows
    past ``S`` are the extra stages of DOP853's dense output) and weights (``S``).
E, E_low : numpy.ndarray
    Error weights over ``k_0..k_S``; ``E_low`` is DOP853's 3rd-order one (zeros else).
dense : numpy.ndarray
    ``P`` (``(S+1) x p``) for :data:`DENSE_POWERS`, ``D`` (``4 x n_rows``) for
    :data:`DENSE_DOP853`.
"""


def _tableau(*, n_stages, error_kind, dense_kind, estimator_order, C, A, B, E, E_low, dense):
    """Pack a tableau as C-contiguous float64 arrays (numba freezes such globals)."""
    C = np.ascontiguousarray(C, dtype=np.float64)
    A = np.ascontiguousarray(A, dtype=np.float64)
    n_rows = C.shape[0] if C.shape[0] > n_stages else n_stages + 1
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
    )


#: Bogacki-Shampine 3(2) with its cubic Hermite dense output [4].
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

#: Dormand-Prince 5(4) [2] with Shampine's quartic dense output [3].
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
)


def _dop853():
    """Hairer's DOP853 coefficients (his Fortran code ``dop853.f``; as in scipy [5]).

    Stages 0-11 make the step, row 12 holds the weights (the step's last stage
    evaluates ``F(t + h, y_new)``), rows 13-15 are the extra stages of the dense output.
    The coefficients are listed row by row as ``{column: value}``; the decimal
    strings are those of the Fortran source, so they round to the same doubles.
    """
    nodes = [
        0.0,
        0.526001519587677318785587544488e-01,
        0.789002279381515978178381316732e-01,
        0.118350341907227396726757197510,
        0.281649658092772603273242802490,
        0.333333333333333333333333333333,
        0.25,
        0.307692307692307692307692307692,
        0.651282051282051282051282051282,
        0.6,
        0.857142857142857142857142857142,
        1.0,
        1.0,
        0.1,
        0.2,
        0.777777777777777777777777777778,
    ]
    rows = {
        1: {0: 5.26001519587677318785587544488e-2},
        2: {0: 1.97250569845378994544595329183e-2, 1: 5.91751709536136983633785987549e-2},
        3: {0: 2.95875854768068491816892993775e-2, 2: 8.87627564304205475450678981324e-2},
        4: {
            0: 2.41365134159266685502369798665e-1,
            2: -8.84549479328286085344864962717e-1,
            3: 9.24834003261792003115737966543e-1,
        },
        5: {
            0: 3.7037037037037037037037037037e-2,
            3: 1.70828608729473871279604482173e-1,
            4: 1.25467687566822425016691814123e-1,
        },
        6: {
            0: 3.7109375e-2,
            3: 1.70252211019544039314978060272e-1,
            4: 6.02165389804559606850219397283e-2,
            5: -1.7578125e-2,
        },
        7: {
            0: 3.70920001185047927108779319836e-2,
            3: 1.70383925712239993810214054705e-1,
            4: 1.07262030446373284651809199168e-1,
            5: -1.53194377486244017527936158236e-2,
            6: 8.27378916381402288758473766002e-3,
        },
        8: {
            0: 6.24110958716075717114429577812e-1,
            3: -3.36089262944694129406857109825,
            4: -8.68219346841726006818189891453e-1,
            5: 2.75920996994467083049415600797e1,
            6: 2.01540675504778934086186788979e1,
            7: -4.34898841810699588477366255144e1,
        },
        9: {
            0: 4.77662536438264365890433908527e-1,
            3: -2.48811461997166764192642586468,
            4: -5.90290826836842996371446475743e-1,
            5: 2.12300514481811942347288949897e1,
            6: 1.52792336328824235832596922938e1,
            7: -3.32882109689848629194453265587e1,
            8: -2.03312017085086261358222928593e-2,
        },
        10: {
            0: -9.3714243008598732571704021658e-1,
            3: 5.18637242884406370830023853209,
            4: 1.09143734899672957818500254654,
            5: -8.14978701074692612513997267357,
            6: -1.85200656599969598641566180701e1,
            7: 2.27394870993505042818970056734e1,
            8: 2.49360555267965238987089396762,
            9: -3.0467644718982195003823669022,
        },
        11: {
            0: 2.27331014751653820792359768449,
            3: -1.05344954667372501984066689879e1,
            4: -2.00087205822486249909675718444,
            5: -1.79589318631187989172765950534e1,
            6: 2.79488845294199600508499808837e1,
            7: -2.85899827713502369474065508674,
            8: -8.87285693353062954433549289258,
            9: 1.23605671757943030647266201528e1,
            10: 6.43392746015763530355970484046e-1,
        },
        12: {
            0: 5.42937341165687622380535766363e-2,
            5: 4.45031289275240888144113950566,
            6: 1.89151789931450038304281599044,
            7: -5.8012039600105847814672114227,
            8: 3.1116436695781989440891606237e-1,
            9: -1.52160949662516078556178806805e-1,
            10: 2.01365400804030348374776537501e-1,
            11: 4.47106157277725905176885569043e-2,
        },
        13: {
            0: 5.61675022830479523392909219681e-2,
            6: 2.53500210216624811088794765333e-1,
            7: -2.46239037470802489917441475441e-1,
            8: -1.24191423263816360469010140626e-1,
            9: 1.5329179827876569731206322685e-1,
            10: 8.20105229563468988491666602057e-3,
            11: 7.56789766054569976138603589584e-3,
            12: -8.298e-3,
        },
        14: {
            0: 3.18346481635021405060768473261e-2,
            5: 2.83009096723667755288322961402e-2,
            6: 5.35419883074385676223797384372e-2,
            7: -5.49237485713909884646569340306e-2,
            10: -1.08347328697249322858509316994e-4,
            11: 3.82571090835658412954920192323e-4,
            12: -3.40465008687404560802977114492e-4,
            13: 1.41312443674632500278074618366e-1,
        },
        15: {
            0: -4.28896301583791923408573538692e-1,
            5: -4.69762141536116384314449447206,
            6: 7.68342119606259904184240953878,
            7: 4.06898981839711007970213554331,
            8: 3.56727187455281109270669543021e-1,
            12: -1.39902416515901462129418009734e-3,
            13: 2.9475147891527723389556272149,
            14: -9.15095847217987001081870187138,
        },
    }
    coefficients = np.zeros((16, 16))
    for row, entries in rows.items():
        for column, value in entries.items():
            coefficients[row, column] = value
    weights = coefficients[12, :12].copy()

    # 5th-order error weights over k_0..k_12, and the 3rd-order ones (the weights minus
    # the 3rd-order formula's, computed as the Fortran code does).
    error5 = np.zeros(13)
    for column, value in {
        0: 0.1312004499419488073250102996e-1,
        5: -0.1225156446376204440720569753e1,
        6: -0.4957589496572501915214079952,
        7: 0.1664377182454986536961530415e1,
        8: -0.3503288487499736816886487290,
        9: 0.3341791187130174790297318841,
        10: 0.8192320648511571246570742613e-1,
        11: -0.2235530786388629525884427845e-1,
    }.items():
        error5[column] = value
    error3 = np.zeros(13)
    error3[:12] = weights
    error3[0] -= 0.244094488188976377952755905512
    error3[8] -= 0.733846688281611857341361741547
    error3[11] -= 0.220588235294117647058823529412e-1

    # Coefficients of the 4th..7th terms of the interpolant over k_0..k_15.
    interpolant = np.zeros((4, 16))
    for row, entries in enumerate(
        [
            {
                0: -0.84289382761090128651353491142e1,
                5: 0.56671495351937776962531783590,
                6: -0.30689499459498916912797304727e1,
                7: 0.23846676565120698287728149680e1,
                8: 0.21170345824450282767155149946e1,
                9: -0.87139158377797299206789907490,
                10: 0.22404374302607882758541771650e1,
                11: 0.63157877876946881815570249290,
                12: -0.88990336451333310820698117400e-1,
                13: 0.18148505520854727256656404962e2,
                14: -0.91946323924783554000451984436e1,
                15: -0.44360363875948939664310572000e1,
            },
            {
                0: 0.10427508642579134603413151009e2,
                5: 0.24228349177525818288430175319e3,
                6: 0.16520045171727028198505394887e3,
                7: -0.37454675472269020279518312152e3,
                8: -0.22113666853125306036270938578e2,
                9: 0.77334326684722638389603898808e1,
                10: -0.30674084731089398182061213626e2,
                11: -0.93321305264302278729567221706e1,
                12: 0.15697238121770843886131091075e2,
                13: -0.31139403219565177677282850411e2,
                14: -0.93529243588444783865713862664e1,
                15: 0.35816841486394083752465898540e2,
            },
            {
                0: 0.19985053242002433820987653617e2,
                5: -0.38703730874935176555105901742e3,
                6: -0.18917813819516756882830838328e3,
                7: 0.52780815920542364900561016686e3,
                8: -0.11573902539959630126141871134e2,
                9: 0.68812326946963000169666922661e1,
                10: -0.10006050966910838403183860980e1,
                11: 0.77771377980534432092869265740,
                12: -0.27782057523535084065932004339e1,
                13: -0.60196695231264120758267380846e2,
                14: 0.84320405506677161018159903784e2,
                15: 0.11992291136182789328035130030e2,
            },
            {
                0: -0.25693933462703749003312586129e2,
                5: -0.15418974869023643374053993627e3,
                6: -0.23152937917604549567536039109e3,
                7: 0.35763911791061412378285349910e3,
                8: 0.93405324183624310003907691704e2,
                9: -0.37458323136451633156875139351e2,
                10: 0.10409964950896230045147246184e3,
                11: 0.29840293426660503123344363579e2,
                12: -0.43533456590011143754432175058e2,
                13: 0.96324553959188282948394950600e2,
                14: -0.39177261675615439165231486172e2,
                15: -0.14972683625798562581422125276e3,
            },
        ]
    ):
        for column, value in entries.items():
            interpolant[row, column] = value

    return _tableau(
        n_stages=12,
        error_kind=ERROR_DOP853,
        dense_kind=DENSE_DOP853,
        estimator_order=7,
        C=nodes,
        A=coefficients,
        B=weights,
        E=error5,
        E_low=error3,
        dense=interpolant,
    )


#: Hairer's DOP853: 8th order, 5th/3rd-order error estimate, 7th-order dense output [1].
DOP853 = _dop853()

#: The methods by the names ``solve_ivp`` knows them by.
METHODS = {"RK23": RK23, "RK45": RK45, "DOP853": DOP853}

#: The tableaux by number, the form compiled code selects them in (frozen as constants).
TABLEAUX = (RK23, RK45, DOP853)
#: The number of each method in :data:`TABLEAUX`.
METHOD_INDEX = {name: TABLEAUX.index(tableau) for name, tableau in METHODS.items()}


# ----------------------------------------------------------------------------------------
# Workspace
# ----------------------------------------------------------------------------------------

Workspace = namedtuple("Workspace", ["floats", "stages", "stages_flat", "ints"])
Workspace.__doc__ = """What the integrator works in: four arrays, allocated once per state size.

The integrator keeps everything in a few flat arrays, read by index, rather than in
many small ones: compiled code then passes four pointers around instead of dozens of
arrays whose reference counts numba would update at every call (which cost more than
the arithmetic of a step).

Fields
------
floats : numpy.ndarray
    :data:`N_FLOAT_SLOTS` scalars (:data:`T_REQUEST`, :data:`TIME_REACHED`,
    :data:`NEXT_STEP`, :data:`TIME_FAILED`, ...), then eight vectors of the state's size
    (state, trial state, previous state, the state at which the caller evaluates the
    right-hand side, error scale, two error estimates, absolute tolerance), the
    interpolant's coefficients (``7 n``), the log of step times and the scratch for
    evaluating the interpolant at several times at once.
stages : numpy.ndarray, shape (16, n)
    The stages ``k_j``, one per row.
stages_flat : numpy.ndarray, shape (16 n,)
    The same memory, flat.
ints : numpy.ndarray of int64
    :data:`N_INT_SLOTS` integers: :data:`NFEV`, :data:`N_ACCEPTED`, :data:`N_REJECTED`,
    :data:`N_DENSE`, :data:`STATUS`, :data:`NEXT_EVAL`, ...
"""


@jit
def make_workspace(n, log_size=0, eval_capacity=0):
    """Allocate a :class:`Workspace` for ``n`` states.

    Parameters
    ----------
    n : int
        Number of states.
    log_size : int
        How many accepted step times to keep (:func:`step_times`; for tests).
    eval_capacity : int
        Most evaluation times one step may serve without the integrator allocating
        scratch for them (only the exact arithmetic of RK23/RK45 needs it).

    Examples
    --------
    >>> work = make_workspace(3)
    >>> work.stages.shape, work.ints.shape[0] == N_INT_SLOTS
    ((16, 3), True)
    """
    size = (N_FLOAT_SLOTS + (_N_VECTORS + DENSE_ROWS) * n + log_size
            + (4 + n) * eval_capacity)
    floats = np.zeros(size)
    stages_flat = np.zeros(STAGE_ROWS * n)
    ints = np.zeros(N_INT_SLOTS, dtype=np.int64)
    ints[_LOG_SIZE] = log_size
    ints[_EVAL_CAPACITY] = eval_capacity
    return Workspace(floats, stages_flat.reshape((STAGE_ROWS, n)), stages_flat, ints)


@jit(inline=True)
def _at(vector, n):
    """Offset in ``work.floats`` of vector number ``vector`` (``_Y``, ``_Y_NEW``, ...)."""
    return N_FLOAT_SLOTS + vector * n


@jit(inline=True)
def _dense_at(n):
    """Offset in ``work.floats`` of the interpolant's coefficients."""
    return N_FLOAT_SLOTS + _N_VECTORS * n


@jit(inline=True)
def _log_at(n):
    """Offset in ``work.floats`` of the log of step times."""
    return N_FLOAT_SLOTS + (_N_VECTORS + DENSE_ROWS) * n


# ----------------------------------------------------------------------------------------
# Arithmetic: numpy's dot products, reproduced
# ----------------------------------------------------------------------------------------
# scipy forms every linear combination of stages with numpy.dot, which hands it to
# OpenBLAS (gemv, gemm or ddot according to the operands' shapes; a 1-element operand is
# a plain product). OpenBLAS sums in its own order with fused multiply-adds, and the
# error estimate subtracts nearly equal numbers, so a different summation order moves
# the accepted step sizes by ~1e-13 relative; at loose tolerances (python-control's
# rtol = 1e-3) the step-size controller then carries that into differences of 1e-9 to
# 1e-7 in the states. With ``exact=True`` every combination below is the same BLAS call
# numpy makes (numba's numpy.dot calls the BLAS scipy ships, which on one machine picks
# the same kernel), so the results agree to the last bit; ``exact=False`` sums in
# plain loops: faster for small systems, equal to rounding.


@jit(inline=True)
def _py_min(a, b):
    """``min(a, b)`` with Python's rule: ``b`` only if ``b < a`` (a NaN ``b`` loses)."""
    return b if b < a else a


@jit(inline=True)
def _py_max(a, b):
    """``max(a, b)`` with Python's rule: ``b`` only if ``b > a`` (a NaN ``b`` loses)."""
    return b if b > a else a


@jit(inline=True)
def _combine(K, K_flat, count, coefficients, f, out, n, exact):
    """``f[out:out+n] = sum_{j < count} c_j K[j]`` as ``numpy.dot(K[:count].T, c[:count])``.

    With one state numpy takes the dot product of two vectors (``K_flat``'s first
    ``count`` entries are then the column).
    """
    if exact and count > 1:
        if n == 1:
            f[out] = np.dot(K_flat[:count], coefficients[:count])
        else:
            np.dot(K[:count].T, coefficients[:count], f[out : out + n])
        return
    for i in range(n):
        total = 0.0
        for j in range(count):
            total += K[j, i] * coefficients[j]
        f[out + i] = total


@jit(inline=True)
def _stage_argument(K, K_flat, count, coefficients, f, base, h, n, exact):
    """``y_stage = f[base:base+n] + (sum_{j < count} c_j K[j]) h``: a stage's argument."""
    stage = _at(_Y_STAGE, n)
    _combine(K, K_flat, count, coefficients, f, stage, n, exact)
    for i in range(n):
        f[stage + i] = f[base + i] + f[stage + i] * h


@jit(inline=True)
def _sum_of_squares(f, start, n, exact):
    """``x . x`` for ``x = f[start:start+n]`` (numpy's ``x.dot(x)`` in ``norm``)."""
    if exact:
        x = f[start : start + n]
        return np.dot(x, x)
    total = 0.0
    for i in range(n):
        total += f[start + i] * f[start + i]
    return total


@jit(inline=True)
def _rms(f, start, n, exact):
    """scipy's RMS norm ``||x||_2 / sqrt(n)`` of ``x = f[start:start+n]``."""
    return math.sqrt(_sum_of_squares(f, start, n, exact)) / n**0.5


@jit(inline=True)
def _all_finite(f, start, count):
    """True when ``f[start:start+count]`` holds no NaN or infinity."""
    for i in range(count):
        if not math.isfinite(f[start + i]):
            return False
    return True


@jit(inline=True)
def _error_norm(method, K, K_flat, f, h, rtol, n, exact):
    """Scaled RMS error of the trial step; the step is accepted when this is below 1.

    ``sc_i = atol_i + max(|y_i|, |y_new,i|) rtol``. Embedded pair:
    ``||h sum_j e_j k_j / sc||``. DOP853 (``E5``, ``E3`` its two estimates over
    ``k_0..k_S``, ``n`` states):

    .. math::

        \\epsilon = |h| \\, \\|E_5 / sc\\|_2^2 \\big/
        \\sqrt{n \\, (\\|E_5 / sc\\|_2^2 + 0.01 \\|E_3 / sc\\|_2^2)}.

    A NaN anywhere makes the result NaN (the step is then rejected, as in scipy).
    """
    y = _at(_Y, n)
    y_new = _at(_Y_NEW, n)
    scale = _at(_SCALE, n)
    atol = _at(_ATOL, n)
    err = _at(_ERR, n)
    for i in range(n):
        a = abs(f[y + i])
        b = abs(f[y_new + i])
        # numpy.maximum: NaN when either is NaN
        biggest = a if (a >= b or a != a) else b
        f[scale + i] = f[atol + i] + biggest * rtol
    rows = method.n_stages + 1
    _combine(K, K_flat, rows, method.E, f, err, n, exact)
    if method.error_kind == ERROR_EMBEDDED:
        for i in range(n):
            f[err + i] = f[err + i] * h / f[scale + i]
        return _rms(f, err, n, exact)
    err_low = _at(_ERR_LOW, n)
    _combine(K, K_flat, rows, method.E_low, f, err_low, n, exact)
    for i in range(n):
        f[err + i] = f[err + i] / f[scale + i]
        f[err_low + i] = f[err_low + i] / f[scale + i]
    norm5 = math.sqrt(_sum_of_squares(f, err, n, exact)) ** 2
    norm3 = math.sqrt(_sum_of_squares(f, err_low, n, exact)) ** 2
    if norm5 == 0 and norm3 == 0:
        return 0.0
    denominator = norm5 + 0.01 * norm3
    return abs(h) * norm5 / math.sqrt(denominator * n)


@jit(inline=True)
def _build_interpolant(method, K, K_flat, f, h, n, exact):
    """Coefficients of the interpolant over the last step (its stages all in ``K``).

    Powers (RK23, RK45): ``Q = K^T P`` (``n x p``, row-major from the coefficients'
    offset) so that ``y(t_old + x h) = y_old + h Q (x, x^2, .., x^p)``.

    DOP853 (extra stages ``k_13..k_15`` already in ``K``), with ``dy = y - y_old``:
    ``F_0 = dy``, ``F_1 = h f_old - dy``, ``F_2 = 2 dy - h (f + f_old)``,
    ``F_{3..6} = h D K`` (rows of ``n``).
    """
    dense = _dense_at(n)
    rows = method.n_stages + 1
    if method.dense_kind == DENSE_POWERS:
        P = method.dense
        powers = P.shape[1]
        if exact:
            if n == 1:
                np.dot(K_flat[:rows], P, f[dense : dense + powers])
            else:
                Q = f[dense : dense + n * powers].reshape((n, powers))
                np.dot(K[:rows].T, P, Q)
            return
        for i in range(n):
            for r in range(powers):
                total = 0.0
                for j in range(rows):
                    total += K[j, i] * P[j, r]
                f[dense + i * powers + r] = total
        return
    S = method.n_stages
    y = _at(_Y, n)
    y_old = _at(_Y_OLD, n)
    for i in range(n):
        delta = f[y + i] - f[y_old + i]
        f[dense + i] = delta
        f[dense + n + i] = h * K[0, i] - delta
        f[dense + 2 * n + i] = 2 * delta - h * (K[S, i] + K[0, i])
    D = method.dense
    high = dense + 3 * n
    if exact:
        if n == 1:
            np.dot(D, K_flat[: method.n_rows], f[high : high + 4])
        else:
            np.dot(D, K[: method.n_rows], f[high : high + 4 * n].reshape((4, n)))
    else:
        for r in range(4):
            for i in range(n):
                total = 0.0
                for j in range(method.n_rows):
                    total += D[r, j] * K[j, i]
                f[high + r * n + i] = total
    for k in range(4 * n):
        f[high + k] = h * f[high + k]


@jit(inline=True)
def _evaluate_interpolant(method, f, t_old, h, t_eval, first, stop, y_eval, buffer_at,
                          capacity, n, exact):
    """States at ``t_eval[first:stop]`` from the interpolant over ``[t_old, t_old + h]``.

    With ``x = (t - t_old) / h``: powers, ``y_old + h Q (x, .., x^p)`` (all the times
    of the step in one product, as scipy evaluates them); DOP853, nested from the last
    coefficient,
    ``y_old + x(F_0 + (1-x)(F_1 + x(F_2 + (1-x)(F_3 + x(F_4 + (1-x)(F_5 + x F_6))))))``.
    """
    m = stop - first
    dense = _dense_at(n)
    y_old = _at(_Y_OLD, n)
    if method.dense_kind == DENSE_DOP853:
        for k in range(m):
            x = (t_eval[first + k] - t_old) / h
            for i in range(n):
                value = 0.0
                for r in range(7):
                    value += f[dense + (6 - r) * n + i]
                    if r % 2 == 0:
                        value *= x
                    else:
                        value *= 1 - x
                y_eval[first + k, i] = value + f[y_old + i]
        return
    powers = method.dense.shape[1]
    if not exact:
        for k in range(m):
            x = (t_eval[first + k] - t_old) / h
            for i in range(n):
                total = 0.0
                power = x
                for r in range(powers):
                    if r > 0:
                        power = power * x
                    total += f[dense + i * powers + r] * power
                y_eval[first + k, i] = h * total + f[y_old + i]
        return
    # numpy: p = cumprod of x over the powers, (powers x m); y = h * Q p + y_old.
    if (powers + n) * m <= capacity:
        scratch = f[buffer_at : buffer_at + (powers + n) * m]
    else:
        scratch = np.empty((powers + n) * m)
    p = scratch[: powers * m].reshape((powers, m))
    for k in range(m):
        x = (t_eval[first + k] - t_old) / h
        p[0, k] = x
        for r in range(1, powers):
            p[r, k] = p[r - 1, k] * x
    product = scratch[powers * m :]
    Q = f[dense : dense + n * powers]
    if n == 1 and m == 1:
        product[0] = np.dot(Q, scratch[:powers])
    elif n == 1:
        np.dot(Q, p, product)
    elif m == 1:
        np.dot(Q.reshape((n, powers)), scratch[:powers], product)
    else:
        np.dot(Q.reshape((n, powers)), p, product.reshape((n, m)))
    for k in range(m):
        for i in range(n):
            y_eval[first + k, i] = h * product[i * m + k] + f[y_old + i]


@jit(inline=True)
def _arguments_valid(t_eval, y_eval, f, K, st):
    """True when the loaded arguments are in range (see :func:`solve_interval`)."""
    n = K.shape[1]
    t0 = f[_T0]
    t1 = f[_T1]
    if not (math.isfinite(t0) and math.isfinite(t1)):
        return False
    if not (f[_MAX_STEP] > 0):
        return False
    first_step = f[_FIRST_STEP]
    if not (first_step >= 0) or first_step > abs(t1 - t0):
        return False
    atol = _at(_ATOL, n)
    for i in range(n):
        if not (f[atol + i] >= 0):
            return False
    if f[_RTOL_GIVEN] != f[_RTOL_GIVEN]:
        return False
    if st[_METHOD] < 0 or st[_METHOD] >= len(TABLEAUX):
        return False
    if K.shape[0] < STAGE_ROWS:
        return False
    i_eval = st[NEXT_EVAL]
    if i_eval < 0 or i_eval > t_eval.shape[0]:
        return False
    if i_eval < t_eval.shape[0] and (
        y_eval.shape[0] != t_eval.shape[0] or y_eval.shape[1] != n
    ):
        return False
    return True


@jit(inline=True)
def _evaluation_end(t0, t1, direction, t_eval, i_eval, closed_right):
    """One past the last evaluation time this interval serves, or -1 when they are bad.

    The interval serves ``t_eval[i_eval:end]``: the times ``t`` with ``t0 <= t < t1``
    (``t <= t1`` when ``closed_right``), read in the direction of integration; they
    must start at or after ``t0`` and be strictly monotone.
    """
    end = i_eval
    previous = t0
    while end < t_eval.shape[0]:
        t = t_eval[end]
        ahead = direction * (t - t1)
        if ahead > 0 or (ahead == 0 and not closed_right):
            break
        if end == i_eval:
            if direction * (t - t0) < 0:
                return -1
        elif not (direction * (t - previous) > 0):
            return -1
        previous = t
        end += 1
    return end


@jit(inline=True)
def _finish(st, status):
    """End the call with ``status``; :func:`machine` then returns :data:`FINISHED`."""
    st[STATUS] = status
    st[_PHASE] = _PHASE_DONE
    return FINISHED


@jit(inline=True)
def _request(f, st, t, row, phase):
    """Ask the caller for ``K[row] = rhs(t, y_stage)``, to be resumed in ``phase``."""
    f[T_REQUEST] = t
    st[_PHASE] = phase
    st[NFEV] += 1
    return row


# ----------------------------------------------------------------------------------------
# The step machine
# ----------------------------------------------------------------------------------------
# The integrator never calls the right-hand side: it asks its caller to ("reverse
# communication", as in RKSUITE or ODEPACK's DLSODE). machine() returns a row r >= 0
# meaning "evaluate rhs(floats[T_REQUEST], the stage input) into stages[r], then call
# me again", or FINISHED. It is therefore compiled once, whatever the right-hand side
# and its arguments, and cached on disk; the caller's loop around it (solve_interval) is
# a few lines. Called through a first-class function (machine_function()), the machine is
# not even compiled into its callers.


@jit
def load(method_index, t0, t1, y0, rtol, atol, max_step, first_step, i_eval, closed_right,
         work, exact):
    """Put an interval's arguments into ``work``; :func:`machine` then starts on it.

    Arguments as :func:`solve_interval`; ``method_index`` is ``METHOD_INDEX[name]``.
    """
    f = work.floats
    st = work.ints
    for k in range(_LOG_SIZE):
        st[k] = 0
    f[TIME_REACHED] = t0
    f[NEXT_STEP] = 0.0
    f[TIME_FAILED] = math.nan
    f[_T0] = t0
    f[_T1] = t1
    f[_RTOL_GIVEN] = rtol
    f[_MAX_STEP] = max_step
    f[_FIRST_STEP] = first_step
    st[_METHOD] = method_index
    st[NEXT_EVAL] = i_eval
    st[_CLOSED_RIGHT] = 1 if closed_right else 0
    st[_EXACT] = 1 if exact else 0
    n = work.stages.shape[1]
    if y0.shape[0] != n or atol.shape[0] != n:
        st[_PHASE] = _PHASE_BAD_SIZES
        return
    y = _at(_Y, n)
    at = _at(_ATOL, n)
    for i in range(n):
        f[y + i] = y0[i]
        f[at + i] = atol[i]
    st[_PHASE] = _PHASE_BEGIN


def _machine(t_eval, y_eval, f, K, K_flat, st):
    """Advance the loaded interval: the next request (a row ``r >= 0``) or :data:`FINISHED`.

    ``f, K, K_flat, st`` are a :class:`Workspace`'s four arrays. A request asks the
    caller for ``K[r] = rhs(f[T_REQUEST], stage_input(work))``. At :data:`FINISHED`,
    ``st[STATUS]`` holds the status, ``st[NEXT_EVAL]`` the first evaluation time not
    served and :func:`state` the state at ``f[TIME_REACHED]``.

    Most calls only form the next stage's argument; they are served here, in a small
    function, and the rest (:func:`_machine_general`, a large one whose every call costs
    setting up its many variables) only once or twice per step.
    """
    if st[_PHASE] == _PHASE_STAGE:
        method = TABLEAUX[st[_METHOD]]
        s = st[_STAGE] + 1
        if s < method.n_stages:
            n = K.shape[1]
            h = f[_H]
            st[_STAGE] = s
            _stage_argument(K, K_flat, s, method.A[s], f, _at(_Y, n), h, n, st[_EXACT] == 1)
            return _request(f, st, f[_T] + method.C[s] * h, s, _PHASE_STAGE)
    return _machine_general(t_eval, y_eval, f, K, K_flat, st)


@jit
def _machine_general(t_eval, y_eval, f, K, K_flat, st):
    """Every phase of the step machine (see :func:`_machine`), one after the other until
    the next request: validation and ``f0``; Hairer's starting step; a step's bounds,
    trial, stages, error norm and acceptance; the interpolant and the evaluation times
    it serves; the end of the interval or a failure.
    """
    phase = st[_PHASE]
    if phase == _PHASE_BAD_SIZES:
        return _finish(st, INVALID_ARGUMENT)
    if phase == _PHASE_DONE:
        return FINISHED
    n = K.shape[1]
    y = _at(_Y, n)
    y_new = _at(_Y_NEW, n)
    y_old = _at(_Y_OLD, n)
    y_stage = _at(_Y_STAGE, n)
    if phase == _PHASE_BEGIN:
        if not _arguments_valid(t_eval, y_eval, f, K, st):
            return _finish(st, INVALID_ARGUMENT)
        t0 = f[_T0]
        t1 = f[_T1]
        direction = 1.0 if t1 >= t0 else -1.0
        eval_end = _evaluation_end(t0, t1, direction, t_eval, st[NEXT_EVAL],
                                   st[_CLOSED_RIGHT] == 1)
        if eval_end < 0:
            return _finish(st, INVALID_ARGUMENT)
        st[_EVAL_END] = eval_end
        f[_T] = t0
        f[_DIRECTION] = direction
        f[_RTOL] = _py_max(f[_RTOL_GIVEN], RTOL_FLOOR)
        if not _all_finite(f, y, n):
            f[TIME_FAILED] = t0
            return _finish(st, NON_FINITE)
        for i in range(n):
            f[y_stage + i] = f[y + i]
        return _request(f, st, t0, 0, _PHASE_F0)

    method = TABLEAUX[st[_METHOD]]
    exact = st[_EXACT] == 1
    S = method.n_stages
    direction = f[_DIRECTION]
    while True:
        if phase == _PHASE_STAGE:
            # Stage st[_STAGE] is in K; the next stage, or the new state and its slope.
            s = st[_STAGE] + 1
            t = f[_T]
            h = f[_H]
            if s < S:
                st[_STAGE] = s
                _stage_argument(K, K_flat, s, method.A[s], f, y, h, n, exact)
                return _request(f, st, t + method.C[s] * h, s, _PHASE_STAGE)
            _combine(K, K_flat, S, method.B, f, y_new, n, exact)
            for i in range(n):
                f[y_new + i] = f[y + i] + h * f[y_new + i]
                f[y_stage + i] = f[y_new + i]
            return _request(f, st, t + h, S, _PHASE_F_NEW)

        elif phase == _PHASE_F_NEW:
            # f_new = rhs(t + h, y_new) is in K[S]: accept or reject.
            h_abs = f[_H_ABS]
            error = _error_norm(method, K, K_flat, f, f[_H], f[_RTOL], n, exact)
            if error < 1:
                if error == 0:
                    factor = MAX_FACTOR
                else:
                    factor = _py_min(MAX_FACTOR, SAFETY * error**method.error_exponent)
                if st[_REJECTED] == 1:
                    factor = _py_min(1.0, factor)
                f[_H_ABS] = h_abs * factor
                phase = _PHASE_ACCEPTED
            else:
                st[_LAST_ERROR_FINITE] = 1 if math.isfinite(error) else 0
                f[_H_ABS] = h_abs * _py_max(MIN_FACTOR, SAFETY * error**method.error_exponent)
                st[_REJECTED] = 1
                st[N_REJECTED] += 1
                phase = _PHASE_TRIAL

        elif phase == _PHASE_TRIAL:
            # A trial step of the proposed size, clipped at t1.
            t = f[_T]
            h_abs = f[_H_ABS]
            if h_abs < f[_MIN_STEP]:
                f[TIME_FAILED] = t
                f[NEXT_STEP] = h_abs
                if st[_LAST_ERROR_FINITE] == 1:
                    return _finish(st, STEP_TOO_SMALL)
                return _finish(st, NON_FINITE)
            h = h_abs * direction
            t_new = t + h
            if direction * (t_new - f[_T1]) > 0:
                t_new = f[_T1]
            h = t_new - t
            f[_H] = h
            f[_H_ABS] = abs(h)
            f[_T_NEW] = t_new
            st[_STAGE] = 1
            _stage_argument(K, K_flat, 1, method.A[1], f, y, h, n, exact)
            return _request(f, st, t + method.C[1] * h, 1, _PHASE_STAGE)

        elif phase == _PHASE_ACCEPTED:
            t_old = f[_T]
            t = f[_T_NEW]
            for i in range(n):
                f[y_old + i] = f[y + i]
                f[y + i] = f[y_new + i]
            if not (_all_finite(f, y, n) and _all_finite(K_flat, S * n, n)):
                for i in range(n):
                    f[y + i] = f[y_old + i]
                f[TIME_FAILED] = t
                return _finish(st, NON_FINITE)
            f[_T_OLD] = t_old
            f[_T] = t
            if st[N_ACCEPTED] < st[_LOG_SIZE]:
                f[_log_at(n) + st[N_ACCEPTED]] = t
            st[N_ACCEPTED] += 1
            f[TIME_REACHED] = t
            f[NEXT_STEP] = f[_H_ABS]
            # The evaluation times this step serves: t_e <= t, in the direction of travel.
            first = st[NEXT_EVAL]
            stop = first
            eval_end = st[_EVAL_END]
            while stop < eval_end and direction * (t_eval[stop] - t) <= 0:
                stop += 1
            st[_STOP] = stop
            phase = _PHASE_STEP_END
            if stop > first:
                st[N_DENSE] += 1
                if method.dense_kind == DENSE_DOP853:
                    s = S + 1
                    st[_STAGE] = s
                    _stage_argument(K, K_flat, s, method.A[s], f, y_old, f[_H], n, exact)
                    return _request(f, st, t_old + method.C[s] * f[_H], s, _PHASE_EXTRA)
                _build_interpolant(method, K, K_flat, f, f[_H], n, exact)
                if not _all_finite(f, _dense_at(n), n * method.dense.shape[1]):
                    f[TIME_FAILED] = t
                    return _finish(st, NON_FINITE)
                _evaluate_interpolant(method, f, t_old, t - t_old, t_eval, first, stop, y_eval,
                                      _log_at(n) + st[_LOG_SIZE], st[_EVAL_CAPACITY] * (4 + n),
                                      n, exact)
                st[NEXT_EVAL] = stop

        elif phase == _PHASE_STEP_END:
            if direction * (f[_T] - f[_T1]) >= 0:
                return _finish(st, SUCCESS)
            for i in range(n):
                K[0, i] = K[S, i]
            phase = _PHASE_STEP

        elif phase == _PHASE_STEP:
            # A new step from (t, y) with f in K[0]: bound the proposed size.
            t = f[_T]
            min_step = 10 * abs(math.nextafter(t, direction * math.inf) - t)
            h_abs = f[_H_ABS]
            if h_abs > f[_MAX_STEP]:
                h_abs = f[_MAX_STEP]
            elif h_abs < min_step:
                h_abs = min_step
            f[_H_ABS] = h_abs
            f[_MIN_STEP] = min_step
            st[_REJECTED] = 0
            st[_LAST_ERROR_FINITE] = 1
            phase = _PHASE_TRIAL

        elif phase == _PHASE_EXTRA:
            # DOP853's extra stage st[_STAGE] for its interpolant is in K.
            s = st[_STAGE] + 1
            t_old = f[_T_OLD]
            h = f[_H]
            if s < method.n_rows:
                st[_STAGE] = s
                _stage_argument(K, K_flat, s, method.A[s], f, y_old, h, n, exact)
                return _request(f, st, t_old + method.C[s] * h, s, _PHASE_EXTRA)
            _build_interpolant(method, K, K_flat, f, h, n, exact)
            if not _all_finite(f, _dense_at(n), DENSE_ROWS * n):
                f[TIME_FAILED] = f[_T]
                return _finish(st, NON_FINITE)
            _evaluate_interpolant(method, f, t_old, f[_T] - t_old, t_eval, st[NEXT_EVAL],
                                  st[_STOP], y_eval, _log_at(n) + st[_LOG_SIZE],
                                  st[_EVAL_CAPACITY] * (4 + n), n, exact)
            st[NEXT_EVAL] = st[_STOP]
            phase = _PHASE_STEP_END

        elif phase == _PHASE_F0:
            # f0 = rhs(t0, y0) is in K[0].
            t0 = f[_T0]
            t1 = f[_T1]
            if t1 == t0:
                # No step, and no time served: scipy takes an empty span for a backward
                # one and its slice of evaluation times comes out empty.
                f[TIME_REACHED] = t1
                return _finish(st, SUCCESS)
            if n == 0:
                st[NEXT_EVAL] = st[_EVAL_END]
                f[TIME_REACHED] = t1
                return _finish(st, SUCCESS)
            if not _all_finite(K_flat, 0, n):
                f[TIME_FAILED] = t0
                return _finish(st, NON_FINITE)
            if f[_FIRST_STEP] > 0:
                f[_H_ABS] = f[_FIRST_STEP]
                phase = _PHASE_STEP
                continue
            # Hairer's starting step [1, II.4] as scipy's select_initial_step: first half.
            interval = abs(t1 - t0)
            rtol = f[_RTOL]
            scale = _at(_SCALE, n)
            ratio = _at(_ERR, n)
            atol = _at(_ATOL, n)
            for i in range(n):
                f[scale + i] = f[atol + i] + abs(f[y + i]) * rtol
            for i in range(n):
                f[ratio + i] = f[y + i] / f[scale + i]
            d0 = _rms(f, ratio, n, exact)
            for i in range(n):
                f[ratio + i] = K[0, i] / f[scale + i]
            d1 = _rms(f, ratio, n, exact)
            if d0 < 1e-5 or d1 < 1e-5:
                h0 = 1e-6
            else:
                h0 = 0.01 * d0 / d1
            h0 = _py_min(h0, interval)
            for i in range(n):
                f[y_stage + i] = f[y + i] + h0 * direction * K[0, i]
            f[_H0] = h0
            f[_D1] = d1
            return _request(f, st, t0 + h0 * direction, 1, _PHASE_F1)

        elif phase == _PHASE_F1:
            # Second half: f1 = rhs(t0 + h0, y0 + h0 f0) is in K[1].
            h0 = f[_H0]
            d1 = f[_D1]
            scale = _at(_SCALE, n)
            ratio = _at(_ERR, n)
            for i in range(n):
                f[ratio + i] = (K[1, i] - K[0, i]) / f[scale + i]
            d2 = _rms(f, ratio, n, exact) / h0
            if d1 <= 1e-15 and d2 <= 1e-15:
                h1 = _py_max(1e-6, h0 * 1e-3)
            else:
                h1 = (0.01 / _py_max(d1, d2)) ** (1 / (method.estimator_order + 1))
            interval = abs(f[_T1] - f[_T0])
            f[_H_ABS] = _py_min(_py_min(_py_min(100 * h0, h1), interval), f[_MAX_STEP])
            phase = _PHASE_STEP

        else:
            return FINISHED


#: The machine on arrays (what plain Python runs; compiled, each call would update the
#: reference counts of its six arrays, see :func:`machine`).
machine_on_arrays = jit(_machine)
_machine_inline = jit(_machine, inline=True)

if numba is not None:

    @jit
    def machine(t_eval_at, m, y_eval_at, floats_at, floats_size, stages_at, n, ints_at):
        """:func:`machine_on_arrays` on arrays given by address (compiled callers).

        numba updates the reference count of every array a compiled function receives,
        with atomic instructions, at each call; for a function called once per
        evaluation of the right-hand side that cost more than the step's arithmetic.
        Given addresses, the machine views the memory with ``numba.carray`` (views that
        own nothing, whose reference counting compiles to nothing). The caller keeps the
        arrays alive: :func:`solve_interval` does.
        """
        t_eval = numba.carray(_void_pointer(t_eval_at), (m,), np.float64)
        y_eval = numba.carray(_void_pointer(y_eval_at), (m, n), np.float64)
        f = numba.carray(_void_pointer(floats_at), (floats_size,), np.float64)
        K = numba.carray(_void_pointer(stages_at), (STAGE_ROWS, n), np.float64)
        K_flat = numba.carray(_void_pointer(stages_at), (STAGE_ROWS * n,), np.float64)
        st = numba.carray(_void_pointer(ints_at), (N_INT_SLOTS,), np.int64)
        return _machine_inline(t_eval, y_eval, f, K, K_flat, st)

else:
    machine = machine_on_arrays


@jit(inline=True)
def stage_input(work):
    """The state at which the caller evaluates the right-hand side when asked to."""
    n = work.stages.shape[1]
    start = _at(_Y_STAGE, n)
    return work.floats[start : start + n]


@jit
def state(work):
    """The state at the last time reached (a view into ``work``)."""
    n = work.stages.shape[1]
    start = _at(_Y, n)
    return work.floats[start : start + n]


@jit
def step_times(work):
    """The accepted step times the workspace kept (a view; see :func:`make_workspace`)."""
    n = work.stages.shape[1]
    kept = min(work.ints[N_ACCEPTED], work.ints[_LOG_SIZE])
    return work.floats[_log_at(n) : _log_at(n) + kept]


def _solve_interval(machine_function, rhs, args, method_index, t0, t1, y0, rtol, atol,
                    max_step, first_step, t_eval, i_eval, closed_right, y_eval, y_end, work,
                    exact):
    """Integrate ``y' = rhs(t, y)`` over ``[t0, t1]`` as one ``solve_ivp`` call would.

    Each step from ``(t, y)`` with derivative ``f`` and proposed size ``h`` (first one:
    Hairer's starting step, or ``first_step``) is the loop of scipy's ``RungeKutta``:

    .. math::

        h &\\leftarrow \\operatorname{clip}(h,\\ h_{min},\\ h_{max}), \\quad
        h_{min} = 10\\,|\\mathrm{nextafter}(t) - t|; \\qquad
        t_{new} = \\min(t + h, t_1), \\\\
        \\epsilon &= \\text{scaled RMS error of the trial step}, \\\\
        \\epsilon < 1 &: \\text{accept}, \\ h \\leftarrow h \\cdot
        \\min(10, 0.9\\,\\epsilon^{-1/(q+1)}) \\ (\\text{at most } h
        \\text{ after a rejection in this step; } 10 \\text{ if } \\epsilon = 0), \\\\
        \\epsilon \\ge 1 &: \\text{reject}, \\ h \\leftarrow h \\cdot
        \\max(0.2,\\ 0.9\\,\\epsilon^{-1/(q+1)}), \\text{ fail below } h_{min}.

    After each accepted step ending at ``t``, the evaluation times not yet served with
    ``t_e <= t`` (in the direction of integration) are read from that step's
    interpolant -- also a time equal to the step's end, and ``t1`` itself; a time equal
    to ``t0`` comes out exactly ``y0``. This is scipy's ``searchsorted(...,
    side="right")`` rule.

    Parameters
    ----------
    machine_function : callable
        :func:`machine` itself (compiled into the caller), or the first-class function
        :func:`machine_function` returns (called through a pointer: nothing of the
        machine is compiled into the caller).
    rhs : callable
        ``rhs(t, y, args, out)`` writes ``y'`` into ``out`` (a 1-D float64 array). A numba
        function (a global of the compiled caller, a first-class function from
        :func:`first_class`, or a dispatcher) or, without numba, any Python function.
    args : tuple
        Passed to ``rhs`` untouched (parameters, input tables, scratch arrays).
    method_index : int
        ``METHOD_INDEX[name]``: 0 RK23, 1 RK45, 2 DOP853 (the tableaux :data:`TABLEAUX`).
    t0, t1 : float
        The interval; ``t1 < t0`` integrates backwards; ``t1 == t0`` takes no step and,
        as in scipy, serves no evaluation time.
    y0 : numpy.ndarray, shape (n,)
        State at ``t0`` (read only).
    rtol : float
        Relative tolerance, raised to :data:`RTOL_FLOOR` if smaller (silently here).
    atol : numpy.ndarray, shape (n,)
        Absolute tolerance per state (``np.full(n, atol)`` for a scalar).
    max_step : float
        Largest step (``numpy.inf``: unbounded); > 0.
    first_step : float
        First step; 0 lets the integrator choose; else in ``(0, |t1 - t0|]``.
    t_eval : numpy.ndarray, shape (m,)
        Evaluation times, strictly monotone in the direction of integration.
    i_eval : int
        First index of ``t_eval`` this call serves; ``t_eval[i_eval]`` at or after ``t0``.
    closed_right : bool
        Whether a time equal to ``t1`` is served here (True for a lone interval and the
        last of a sequence; False leaves it to the next interval, which serves it at its
        start, after the caller's discrete update).
    y_eval : numpy.ndarray, shape (m, n)
        Receives the state at ``t_eval[i]`` in row ``i``.
    y_end : numpy.ndarray, shape (n,)
        Receives the state at ``t1`` (at the last time reached on failure); may be ``y0``.
    work : Workspace
        From :func:`make_workspace`; its counters are reset.
    exact : bool
        True: form the stage combinations with the BLAS calls numpy makes (bit for bit
        scipy's result); False: plain loops (faster for small systems, equal to rounding).

    Returns
    -------
    status : int
        :data:`SUCCESS`, :data:`STEP_TOO_SMALL`, :data:`NON_FINITE` or
        :data:`INVALID_ARGUMENT` (meanings in :data:`STATUS_MESSAGES`).
    next_eval : int
        Index of the first evaluation time not served.
    """
    load(method_index, t0, t1, y0, rtol, atol, max_step, first_step, i_eval, closed_right,
         work, exact)
    floats = work.floats
    ints = work.ints
    n = work.stages.shape[1]
    if not (t_eval.flags.c_contiguous and y_eval.flags.c_contiguous):
        ints[STATUS] = INVALID_ARGUMENT
        return ints[STATUS], i_eval
    floats_at = floats.ctypes.data
    stages_at = work.stages.ctypes.data
    # Views that own nothing (see machine): handing them to rhs costs no atomic updates.
    floats_view = numba.carray(_void_pointer(floats_at), (floats.shape[0],), np.float64)
    y_stage = floats_view[_at(_Y_STAGE, n) : _at(_Y_STAGE, n) + n]
    stages = numba.carray(_void_pointer(stages_at), (STAGE_ROWS, n), np.float64)
    m = t_eval.shape[0]
    t_eval_at, y_eval_at, size, ints_at = (t_eval.ctypes.data, y_eval.ctypes.data,
                                           floats.shape[0], ints.ctypes.data)
    # the arguments spelled out, not *args: this loop is pasted into callers that are
    # themselves pasted into others, where numba cannot call a function value with *args
    row = machine_function(t_eval_at, m, y_eval_at, floats_at, size, stages_at, n, ints_at)
    while row >= 0:
        rhs(floats[T_REQUEST], y_stage, args, stages[row])
        row = machine_function(t_eval_at, m, y_eval_at, floats_at, size, stages_at, n,
                               ints_at)
    if ints[STATUS] != INVALID_ARGUMENT:
        start = _at(_Y, n)
        for i in range(n):
            y_end[i] = floats[start + i]
    return ints[STATUS], ints[NEXT_EVAL]


def _solve_interval_python(machine_function, rhs, args, method_index, t0, t1, y0, rtol,
                           atol, max_step, first_step, t_eval, i_eval, closed_right, y_eval,
                           y_end, work, exact):
    """:func:`solve_interval` without numba: the machine runs on the arrays themselves."""
    load(method_index, t0, t1, y0, rtol, atol, max_step, first_step, i_eval, closed_right,
         work, exact)
    floats, stages, stages_flat, ints = work
    y_stage = stage_input(work)
    row = machine_function(t_eval, y_eval, floats, stages, stages_flat, ints)
    while row >= 0:
        rhs(floats[T_REQUEST], y_stage, args, stages[row])
        row = machine_function(t_eval, y_eval, floats, stages, stages_flat, ints)
    if ints[STATUS] != INVALID_ARGUMENT:
        y_end[:] = state(work)
    return ints[STATUS], ints[NEXT_EVAL]


solve_interval = (jit(_solve_interval, inline=True) if numba is not None
                  else _solve_interval_python)


# ----------------------------------------------------------------------------------------
# Python-level helpers
# ----------------------------------------------------------------------------------------


def first_class(rhs, args):
    """``rhs`` as a numba first-class function typed for ``args`` (plain ``rhs`` without numba).

    The signature is ``rhs(float64, float64[::1], typeof(args), float64[::1])``. A
    compiled caller receiving this object as an argument is typed by that signature
    alone (not by which function it is), so it is compiled once per type of ``args``,
    cached on disk, and reused by every right-hand side of that type.

    Parameters
    ----------
    rhs : numba dispatcher
        ``rhs(t, y, args, out)``.
    args : tuple
        An example of the arguments (only their types are used).

    Returns
    -------
    object
        A ``numba`` ``CompileResultWAP`` (typed as ``FunctionType``).
    """
    if numba is None:
        return rhs
    from numba.core import types
    from numba.core.types.function_type import CompileResultWAP

    vector = types.float64[::1]
    argument_types = (types.float64, vector, numba.typeof(args), vector)
    rhs.compile(argument_types)
    return CompileResultWAP(rhs.overloads[argument_types])


_MACHINE_FUNCTION = []


def machine_function():
    """:func:`machine` as a numba first-class function (plain :func:`machine` without numba).

    A compiled caller that receives this object as an argument calls the machine
    through a pointer: the machine's code (compiled once, cached on disk) is then not
    compiled again into each caller, which keeps a new diagram's compile time to its
    own right-hand side and loop. Built once per process.
    """
    if numba is None:
        return machine
    if not _MACHINE_FUNCTION:
        from numba.core.types.function_type import CompileResultWAP

        address = numba.types.uintp
        size = numba.types.intp
        argument_types = (address, size, address, address, size, address, size, address)
        machine.compile(argument_types)
        _MACHINE_FUNCTION.append(CompileResultWAP(machine.overloads[argument_types]))
    return _MACHINE_FUNCTION[0]


def validate_like_scipy(t_span, y0, rtol, atol, max_step, first_step, t_eval):
    """scipy's argument checks, with its messages; returns the arrays the integrator takes.

    Raises
    ------
    ValueError
        As ``solve_ivp`` does: ``max_step``/``first_step`` not positive, ``first_step``
        beyond the interval, ``atol`` of the wrong shape or negative, ``y0`` not 1-D or
        not finite, ``t_eval`` not 1-D, outside ``t_span`` or not sorted.
    """
    t0, t1 = map(float, t_span)
    y0 = np.asarray(y0, dtype=np.float64)
    if y0.ndim != 1:
        raise ValueError("`y0` must be 1-dimensional.")
    if not np.isfinite(y0).all():
        raise ValueError("All components of the initial state `y0` must be finite.")
    n = y0.shape[0]
    if max_step <= 0:
        raise ValueError("`max_step` must be positive.")
    if first_step is None:
        first_step = 0.0
    else:
        if first_step <= 0:
            raise ValueError("`first_step` must be positive.")
        if first_step > abs(t1 - t0):
            raise ValueError("`first_step` exceeds bounds.")
    if np.any(np.asarray(rtol) < RTOL_FLOOR):
        warnings.warn(
            "At least one element of `rtol` is too small. "
            f"Setting `rtol = np.maximum(rtol, {RTOL_FLOOR})`.",
            stacklevel=3,
        )
        rtol = np.maximum(rtol, RTOL_FLOOR)
    atol = np.asarray(atol, dtype=np.float64)
    if atol.ndim > 0 and atol.shape != (n,):
        raise ValueError("`atol` has wrong shape.")
    if np.any(atol < 0):
        raise ValueError("`atol` must be positive.")
    atol = np.ascontiguousarray(np.broadcast_to(atol, (n,)), dtype=np.float64)
    if t_eval is not None:
        t_eval = np.ascontiguousarray(t_eval, dtype=np.float64)
        if t_eval.ndim != 1:
            raise ValueError("`t_eval` must be 1-dimensional.")
        if np.any(t_eval < min(t0, t1)) or np.any(t_eval > max(t0, t1)):
            raise ValueError("Values in `t_eval` are not within `t_span`.")
        d = np.diff(t_eval)
        if (t1 > t0 and np.any(d <= 0)) or (t1 < t0 and np.any(d >= 0)):
            raise ValueError("Values in `t_eval` are not properly sorted.")
    return t0, t1, y0, float(rtol), atol, float(max_step), float(first_step), t_eval


def solve_ivp(rhs, t_span, y0, method="RK45", t_eval=None, args=(), rtol=1e-3, atol=1e-6,
              max_step=np.inf, first_step=None, log_steps=0, exact=True):
    """One interval, checked as scipy checks it: the drop-in for ``solve_ivp(..., t_eval)``.

    Parameters are ``scipy.integrate.solve_ivp``'s (``method`` one of :data:`METHODS`),
    except that ``rhs(t, y, args, out)`` writes into ``out`` and ``args`` is passed as
    one tuple. ``t_eval=None`` evaluates nothing (the final state is returned).
    ``log_steps`` keeps the times of the first ``log_steps`` accepted steps; ``exact``
    chooses the arithmetic (see :func:`solve_interval`).

    Returns
    -------
    dict
        ``t`` (the evaluation times served), ``y`` (shape ``(n, len(t))``, scipy's
        layout), ``y_end``, ``status`` (0 success; -1 step too small; -2 non-finite;
        -3 invalid argument), ``message``, ``success``, ``nfev``, ``n_accepted``,
        ``n_rejected``, ``t_reached``, ``step_times``.
    """
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {sorted(METHODS)}, got {method!r}.")
    t0, t1, y0, rtol, atol, max_step, first_step, t_eval = validate_like_scipy(
        t_span, y0, rtol, atol, max_step, first_step, t_eval
    )
    n = y0.shape[0]
    if numba is not None and isinstance(rhs, numba.core.registry.CPUDispatcher):
        rhs = first_class(rhs, args)
    if t_eval is None:
        t_eval = np.zeros(0)
    y_eval = np.full((t_eval.shape[0], n), np.nan)
    y_end = np.empty(n)
    work = make_workspace(n, int(log_steps), t_eval.shape[0])
    status, served = solve_interval(machine_function(), rhs, args, METHOD_INDEX[method], t0,
                                    t1, y0, rtol, atol, max_step, first_step, t_eval, 0,
                                    True, y_eval, y_end, work, bool(exact))
    status = int(status)
    return {
        "t": t_eval[:served],
        "y": y_eval[:served].T,
        "y_end": y_end,
        "status": status,
        "message": STATUS_MESSAGES[status],
        "success": status == SUCCESS,
        "nfev": int(work.ints[NFEV]),
        "n_accepted": int(work.ints[N_ACCEPTED]),
        "n_rejected": int(work.ints[N_REJECTED]),
        "t_reached": float(work.floats[TIME_REACHED]),
        "step_times": step_times(work).copy(),
    }
