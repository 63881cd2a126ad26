"""The integrator's workspace: four flat arrays, and where each quantity lives in them.

Everything the step machine keeps between calls -- scalars, the state and its copies,
the stages, the interpolant, counters and status -- lives in one :class:`Workspace`,
allocated once per state size and reused for every interval (a sampled-data loop
allocates nothing per interval). Quantities are found by slot; the underscored slots
belong to the machine. This module also defines the status codes, the machine's phases
and :func:`load`, which starts an interval.

Why flat arrays: numba updates the reference count of every array a compiled function
receives, with atomic instructions, at every call. With the workspace as a tuple of
fourteen arrays that cost about 60% of the run time; with four arrays read by index
(and the machine viewing them through their addresses, :func:`.machine.machine`) it is
gone.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from ...._jit import jit
from .tableaux import TABLEAUX

# The slots of the scalars in ``work.floats`` and ``work.ints`` (the layout: Workspace).
#: ``floats`` slot: time at which the caller must evaluate the right-hand side.
T_REQUEST = 0
#: ``floats`` slot: last time reached (the end of the last accepted step).
TIME_REACHED = 1
(_T, _T_OLD, _T_NEW, _H, _H_ABS, _MIN_STEP, _T0, _T1, _RTOL, _MAX_STEP, _FIRST_STEP, _H0,
 _D1, _RTOL_GIVEN) = range(2, 16)
#: ``floats`` slot: the stiffness estimate ``|h lambda|`` of the last accepted step
#: (see :func:`set_horizon`; 0 for a method without the test).
STIFFNESS = 16
#: ``floats`` slot: the steps the whole run was projected to need when it stopped as
#: :data:`STIFF`.
PROJECTED_STEPS = 17
_RUN_START, _RUN_END = 18, 19
#: Number of scalar slots at the start of ``work.floats``.
N_FLOAT_SLOTS = 20

# The vectors after the scalars, in this order (each of the state's size).
_Y, _Y_NEW, _Y_OLD, _Y_STAGE, _SCALE, _ERR, _ERR_LOW, _ATOL, _N_VECTORS = range(9)
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
#: ``ints`` slot: status of the call (once the machine returned :data:`FINISHED`).
STATUS = 3
#: ``ints`` slot: index of the first evaluation time not served yet.
NEXT_EVAL = 4
_PHASE, _STAGE, _REJECTED, _LAST_ERROR_FINITE, _EVAL_END, _STOP, _METHOD, _CLOSED_RIGHT = \
    range(5, 13)
# the slots above are reset by :func:`load`, the ones below kept
_LOG_SIZE = 13
#: ``ints`` slot: accepted steps since :func:`set_horizon` (over all the intervals of a
#: run; :func:`load` keeps it).
RUN_ACCEPTED = 14
_STIFF_IN_ROW, _NONSTIFF_IN_ROW = 15, 16
#: Number of slots of ``work.ints``.
N_INT_SLOTS = 17

# Status codes returned by solve_interval.
#: The interval was integrated to its end.
SUCCESS = 0
#: The step needed fell below ten times the spacing of floats at the current time
#: (scipy's failure: the same message, time reached and evaluation count).
STEP_TOO_SMALL = -1
#: The state or the right-hand side became non-finite (NaN or infinite), never a silent
#: NaN: where scipy rejects NaN trials until the step is too small, the same steps, but
#: said why; where scipy hangs (its first step NaN), after one evaluation; where the
#: stages stay finite but their sums overflow (scipy's success with inf or NaN), at the
#: last finite state.
NON_FINITE = -2
#: An argument is out of range (see :data:`STATUS_MESSAGES`).
INVALID_ARGUMENT = -3
#: The problem is stiff for the method and the run would take too many steps.
STIFF = -4
#: The step size is NaN, where scipy's trials would go on forever (its error scale
#: ``atol + rtol |y|`` is 0 for a state at 0 with ``atol=0``).
STEP_NOT_A_NUMBER = -5
#: Not an end: the interval is paused after its evaluation budget, to be resumed.
PAUSED = 1

#: Accepted steps in a row that must look stiff before :data:`STIFF` may be declared
#: (Hairer's DOPRI5 and DOP853 print their "problem seems to become stiff" after 15).
STIFF_STEPS_IN_ROW = 15
#: Non-stiff-looking steps in a row that clear the count (6, as in DOPRI5).
NONSTIFF_STEPS_IN_ROW = 6
#: Accepted steps of a run before its progress is projected (the first steps, from the
#: starting step, are shorter than the rest).
STIFF_STEPS_BEFORE_PROJECTING = 1000
#: A run that looks stiff stops as :data:`STIFF` when the steps it would need, projected
#: from its progress so far, exceed this: at 1-3 us a step for a small diagram, half a
#: minute or more of a run that an implicit method (BDF, LSODA, Radau) does in a fraction
#: of a second. Below it the run goes on, as scipy's would.
STIFF_STEP_BUDGET = 10_000_000

#: What each status code means.
STATUS_MESSAGES = {
    SUCCESS: "The solver successfully reached the end of the integration interval.",
    STEP_TOO_SMALL: "Required step size is less than spacing between numbers.",
    NON_FINITE: "The state or its derivative became non-finite (NaN or infinite).",
    STIFF: ("The problem is stiff: the explicit method's step is held down by stability, "
            "not accuracy, and the run would need too many steps; use an implicit method "
            "(BDF, LSODA or Radau)."),
    PAUSED: "Paused after its evaluation budget; resume to go on.",
    STEP_NOT_A_NUMBER: ("The step size is not a number: the error scale atol + rtol |y| is "
                        "0 (a state at 0 with atol=0), where scipy's solver never ends."),
    INVALID_ARGUMENT: ("Invalid argument: max_step must be > 0, first_step in [0, t1 - t0], "
                       "atol >= 0 of the state's size, t0 <= t1 finite, the evaluation "
                       "times increasing inside [t0, t1], and the work arrays of the "
                       "method's size."),
}

# Phases of the step machine: what the last request was for (or where to go on).
(_PHASE_BEGIN, _PHASE_F0, _PHASE_F1, _PHASE_STAGE, _PHASE_F_NEW, _PHASE_EXTRA, _PHASE_STEP,
 _PHASE_TRIAL, _PHASE_ACCEPTED, _PHASE_STEP_END, _PHASE_DONE) = range(11)


Workspace = namedtuple("Workspace", ["floats", "stages", "stages_flat", "ints"])
Workspace.__doc__ = """What the integrator works in: four arrays, allocated once per state size.

Attributes
----------
floats : numpy.ndarray
    :data:`N_FLOAT_SLOTS` scalars (:data:`T_REQUEST`, :data:`TIME_REACHED`, ...), then
    eight vectors of the state's size (state, trial state, previous state, the state at
    which the caller evaluates the right-hand side, error scale, two error estimates,
    absolute tolerance), the interpolant's coefficients (``7 n``), the log of step times
    and the scratch for evaluating the interpolant at several times at once.
stages : numpy.ndarray, shape (16, n)
    The stages ``k_j``, one per row.
stages_flat : numpy.ndarray, shape (16 n,)
    The same memory, flat.
ints : numpy.ndarray of int64
    :data:`N_INT_SLOTS` integers: :data:`NFEV`, :data:`N_ACCEPTED`, :data:`N_REJECTED`,
    :data:`STATUS`, :data:`NEXT_EVAL`, ...

Examples
--------
>>> from controlkit.engines.fast.rk import make_workspace
>>> work = make_workspace(2)
>>> work.stages.shape, work.stages_flat.shape, work.ints.dtype.name
((16, 2), (32,), 'int64')
>>> work.stages[1, 0] = 3.0  # the same memory as stages_flat
>>> float(work.stages_flat[2])
3.0
"""


@jit(inline=True)
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
        scratch for them (RK23/RK45's interpolant, evaluated as numpy does: at most four
        powers and ``n`` states per time, at the end of ``floats``).
    """
    floats = np.zeros(_log_at(n) + log_size + (4 + n) * eval_capacity)
    stages_flat = np.zeros(STAGE_ROWS * n)
    ints = np.zeros(N_INT_SLOTS, dtype=np.int64)
    ints[_LOG_SIZE] = log_size
    floats[_RUN_START] = math.nan
    floats[_RUN_END] = math.nan
    return Workspace(floats, stages_flat.reshape((STAGE_ROWS, n)), stages_flat, ints)


@jit(inline=True)
def set_horizon(work, t_start, t_end):
    """Tell the integrator the whole run's span, over which it projects its progress.

    A sampled-data run integrates many short intervals; the stiffness test
    (:data:`STIFF`) projects the steps the run needs from the steps taken since
    ``t_start`` and the time reached, towards ``t_end``. Without this call the interval
    being integrated is the span. Resets the run's step count and stiffness counters.

    Examples
    --------
    >>> work = make_workspace(1)
    >>> set_horizon(work, 0.0, 100.0)
    >>> float(work.floats[_RUN_END]), int(work.ints[RUN_ACCEPTED])
    (100.0, 0)
    """
    work.floats[_RUN_START] = t_start
    work.floats[_RUN_END] = t_end
    work.floats[STIFFNESS] = 0.0
    work.ints[RUN_ACCEPTED] = 0
    work.ints[_STIFF_IN_ROW] = 0
    work.ints[_NONSTIFF_IN_ROW] = 0


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


@jit(inline=True)
def stage_input(work):
    """The state at which the caller evaluates the right-hand side when asked to (a view).

    When the machine returns a row ``r >= 0``, the caller evaluates
    ``rhs(work.floats[T_REQUEST], stage_input(work), args, work.stages[r])``.
    """
    n = work.stages.shape[1]
    start = _at(_Y_STAGE, n)
    return work.floats[start : start + n]


@jit(inline=True)
def state(work):
    """The state at the last time reached, ``work.floats[TIME_REACHED]`` (a view)."""
    n = work.stages.shape[1]
    start = _at(_Y, n)
    return work.floats[start : start + n]


@jit(inline=True)
def step_times(work):
    """The first ``log_size`` accepted step times, in order (a view; :func:`make_workspace`)."""
    n = work.stages.shape[1]
    kept = min(work.ints[N_ACCEPTED], work.ints[_LOG_SIZE])
    return work.floats[_log_at(n) : _log_at(n) + kept]


@jit(inline=True)
def _arguments_valid(t_eval, y_eval, f, K, st):
    """True when the loaded arguments are in range (see :func:`solve_interval`)."""
    n = K.shape[1]
    t0 = f[_T0]
    t1 = f[_T1]
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 >= t0):  # (forward only)
        return False
    if not (f[_MAX_STEP] > 0):
        return False
    first_step = f[_FIRST_STEP]
    if not (first_step >= 0) or first_step > t1 - t0:
        return False
    atol = _at(_ATOL, n)
    for i in range(n):
        if not (f[atol + i] >= 0):
            return False
    if f[_RTOL_GIVEN] != f[_RTOL_GIVEN]:
        return False
    if st[_METHOD] < 0 or st[_METHOD] >= len(TABLEAUX):
        return False
    i_eval = st[NEXT_EVAL]
    if i_eval < 0 or i_eval > t_eval.shape[0]:
        return False
    if i_eval < t_eval.shape[0] and (y_eval.shape[0] != t_eval.shape[0] or y_eval.shape[1] != n):
        return False
    return True


@jit(inline=True)
def _evaluation_end(t0, t1, t_eval, i_eval, closed_right):
    """One past the last evaluation time this interval serves, or -1 when they are bad.

    The interval serves ``t_eval[i_eval:end]``: the times ``t`` with ``t0 <= t < t1``
    (``t <= t1`` when ``closed_right``); they must start at or after ``t0`` and increase.
    """
    end = i_eval
    previous = t0
    while end < t_eval.shape[0]:
        t = t_eval[end]
        if t > t1 or (t == t1 and not closed_right):
            break
        if end == i_eval:
            if t < t0:
                return -1
        elif not (t > previous):
            return -1
        previous = t
        end += 1
    return end


@jit
def load(method_index, t0, t1, y0, rtol, atol, max_step, first_step, i_eval, closed_right, work):
    """Put an interval's arguments into ``work``; :func:`machine` then starts on it.

    Arguments as :func:`solve_interval`; ``method_index`` is ``METHOD_INDEX[name]``.
    The counters are reset (the run's step count and stiffness counters too, unless
    :func:`set_horizon` gave the run a span); arguments are checked when the machine
    starts (a state or tolerance of the wrong size makes it finish at once with
    ``INVALID_ARGUMENT``).

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.engines.fast.rk import METHOD_INDEX
    >>> work = make_workspace(2)
    >>> work.ints[NFEV] = 7  # left over from the previous interval
    >>> load(METHOD_INDEX["RK45"], 0.0, 2.0, np.array([1.0, 0.0]), 1e-3, np.full(2, 1e-6),
    ...      np.inf, 0.0, 0, True, work)
    >>> int(work.ints[NFEV]), float(work.floats[TIME_REACHED]), state(work).tolist()
    (0, 0.0, [1.0, 0.0])
    """
    f = work.floats
    st = work.ints
    for k in range(_LOG_SIZE):
        st[k] = 0
    f[TIME_REACHED] = t0
    f[_T0] = t0
    f[_T1] = t1
    f[_RTOL_GIVEN] = rtol
    f[_MAX_STEP] = max_step
    f[_FIRST_STEP] = first_step
    if not math.isfinite(f[_RUN_END]):  # no run span set: this interval is the run
        st[RUN_ACCEPTED] = 0
        st[_STIFF_IN_ROW] = 0
        st[_NONSTIFF_IN_ROW] = 0
    st[_METHOD] = method_index
    st[NEXT_EVAL] = i_eval
    st[_CLOSED_RIGHT] = 1 if closed_right else 0
    n = work.stages.shape[1]
    if y0.shape[0] != n or atol.shape[0] != n:
        st[STATUS] = INVALID_ARGUMENT
        st[_PHASE] = _PHASE_DONE
        return
    y = _at(_Y, n)
    at = _at(_ATOL, n)
    for i in range(n):
        f[y + i] = y0[i]
        f[at + i] = atol[i]
    st[_PHASE] = _PHASE_BEGIN

