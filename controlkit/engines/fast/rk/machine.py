"""The step machine: scipy's ``RungeKutta`` loop, driven by its caller.

:func:`machine` returns a row ``r >= 0``, meaning "evaluate
``rhs(floats[T_REQUEST], stage_input(work))`` into ``stages[r]``, then call me again", or
:data:`FINISHED` (reverse communication, as RKSUITE and ODEPACK's DLSODE do; why:
:mod:`controlkit.engines.fast.rk`, *Design*). The caller's loop around it is
:func:`controlkit.engines.fast.rk.solve_interval`.

What it does between requests is scipy 1.17's ``solve_ivp`` for an explicit method,
operation for operation (``scipy/integrate/_ivp/{rk,common,base,ivp}.py``). Each step
from ``(t, y)`` with derivative ``f`` and proposed size ``h`` (the first one: Hairer's
starting step, Hairer, Norsett & Wanner 1993, Sec. II.4, or ``first_step``) is

.. math::

    h &\\leftarrow \\operatorname{clip}(h,\\ h_{min},\\ h_{max}), \\quad
    h_{min} = 10\\,|\\mathrm{nextafter}(t) - t|; \\qquad
    t_{new} = \\min(t + h, t_1), \\\\
    \\epsilon &= \\text{scaled RMS error of the trial step}, \\\\
    \\epsilon < 1 &: \\text{accept}, \\ h \\leftarrow h \\cdot
    \\min(10, 0.9\\,\\epsilon^{-1/(q+1)}) \\ (\\text{at most } h
    \\text{ after a rejection in this step; } 10 \\text{ if } \\epsilon = 0), \\\\
    \\epsilon \\ge 1 &: \\text{reject}, \\ h \\leftarrow h \\cdot
    \\max(0.2,\\ 0.9\\,\\epsilon^{-1/(q+1)}), \\text{ fail below } h_{min}

(``SAFETY``, ``MIN_FACTOR``, ``MAX_FACTOR``; ``q`` the order of the error estimate).
After each accepted step, its interpolant serves the evaluation times ``t_e <= t`` not
served yet (scipy's ``searchsorted(side="right")``). It integrates forward only (``t1 >=
t0``): the engine's runs do.
"""

from __future__ import annotations

import math

from .... import _jit
from ...._jit import jit
from .arithmetic import (
    _all_finite,
    _build_interpolant,
    _combine,
    _divided,
    _error_norm,
    _evaluate_interpolant,
    _py_max,
    _py_min,
    _rms,
    _stage_argument,
)
from .stiffness import _too_stiff
from .tableaux import MAX_FACTOR, MIN_FACTOR, RTOL_FLOOR, SAFETY, TABLEAUX
from .workspace import (
    _ATOL,
    _CLOSED_RIGHT,
    _D1,
    _ERR,
    _EVAL_END,
    _FIRST_STEP,
    _H,
    _H0,
    _H_ABS,
    _LAST_ERROR_FINITE,
    _LOG_SIZE,
    _MAX_STEP,
    _METHOD,
    _MIN_STEP,
    _PHASE,
    _PHASE_ACCEPTED,
    _PHASE_BEGIN,
    _PHASE_DONE,
    _PHASE_EXTRA,
    _PHASE_F0,
    _PHASE_F1,
    _PHASE_F_NEW,
    _PHASE_STAGE,
    _PHASE_STEP,
    _PHASE_STEP_END,
    _PHASE_TRIAL,
    _REJECTED,
    _RTOL,
    _RTOL_GIVEN,
    _SCALE,
    _STAGE,
    _STOP,
    _T,
    _T0,
    _T1,
    _T_NEW,
    _T_OLD,
    _Y,
    _Y_NEW,
    _Y_OLD,
    _Y_STAGE,
    DENSE_ROWS,
    INVALID_ARGUMENT,
    N_ACCEPTED,
    N_INT_SLOTS,
    N_REJECTED,
    NEXT_EVAL,
    NFEV,
    NON_FINITE,
    RUN_ACCEPTED,
    STAGE_ROWS,
    STATUS,
    STEP_NOT_A_NUMBER,
    STEP_TOO_SMALL,
    STIFF,
    SUCCESS,
    T_REQUEST,
    TIME_REACHED,
    _arguments_valid,
    _at,
    _dense_at,
    _evaluation_end,
    _log_at,
)

#: Returned by :func:`machine` when the interval is done (or failed).
FINISHED = -1


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


@jit(inline=True)
def _serve(method, K, K_flat, f, st, t_eval, y_eval, n):
    """The last step's interpolant, and the evaluation times ``t_eval[NEXT_EVAL:_STOP]``
    read from it; False (nothing served) when its coefficients are not finite."""
    _build_interpolant(method, K, K_flat, f, f[_H], n)
    coefficients = DENSE_ROWS if method.dop853 else method.dense.shape[1]
    if not _all_finite(f, _dense_at(n), n * coefficients):
        return False
    t_old = f[_T_OLD]
    _evaluate_interpolant(method, f, t_old, f[_T] - t_old, t_eval, st[NEXT_EVAL], st[_STOP],
                          y_eval, _log_at(n) + st[_LOG_SIZE], n)
    st[NEXT_EVAL] = st[_STOP]
    return True


@jit(inline=True)
def machine_on_arrays(t_eval, y_eval, f, K, K_flat, st):
    """Advance the loaded interval: the next request (a row ``r >= 0``) or :data:`FINISHED`.

    ``f, K, K_flat, st`` are a :class:`Workspace`'s four arrays. A request asks the
    caller for ``K[r] = rhs(f[T_REQUEST], stage_input(work))``. At :data:`FINISHED`,
    ``st[STATUS]`` holds the status, ``st[NEXT_EVAL]`` the first evaluation time not
    served and :func:`state` the state at ``f[TIME_REACHED]``.

    Most calls only form the next stage's argument; they are served here, in a small
    function, and the rest (:func:`_machine_general`, a large one whose every call costs
    setting up its many variables) only once or twice per step. Plain Python runs this;
    compiled callers call :func:`machine`, the same code on arrays given by address.

    Examples
    --------
    ``y' = -y`` over ``[0, 1]``, the right-hand side evaluated by hand (no evaluation
    times: ``t_eval`` and ``y_eval`` are empty):

    >>> import numpy as np
    >>> from controlkit.engines.fast.rk import METHOD_INDEX, make_workspace
    >>> from controlkit.engines.fast.rk.workspace import load, stage_input, state
    >>> work = make_workspace(1)
    >>> load(METHOD_INDEX["RK23"], 0.0, 1.0, np.ones(1), 1e-6, np.full(1, 1e-9), np.inf,
    ...      0.0, 0, True, work)
    >>> no_times, no_states = np.zeros(0), np.zeros((0, 1))
    >>> row = machine_on_arrays(no_times, no_states, *work)
    >>> while row != FINISHED:
    ...     work.stages[row] = -stage_input(work)
    ...     row = machine_on_arrays(no_times, no_states, *work)
    >>> int(work.ints[STATUS]) == SUCCESS, bool(abs(state(work)[0] - np.exp(-1.0)) < 1e-6)
    (True, True)
    """
    if st[_PHASE] == _PHASE_STAGE:
        method = TABLEAUX[st[_METHOD]]
        s = st[_STAGE] + 1
        if s < method.n_stages:
            n = K.shape[1]
            h = f[_H]
            st[_STAGE] = s
            _stage_argument(K, K_flat, s, method.A[s], f, _at(_Y, n), h, n)
            return _request(f, st, f[_T] + method.C[s] * h, s, _PHASE_STAGE)
    return _machine_general(t_eval, y_eval, f, K, K_flat, st)


@jit
def _machine_general(t_eval, y_eval, f, K, K_flat, st):
    """Every phase of the step machine (see :func:`machine_on_arrays`), one after the other
    until the next request: validation and ``f0``; Hairer's starting step; a step's bounds,
    trial, stages, error norm and acceptance; the interpolant and the evaluation times
    it serves; the end of the interval or a failure.
    """
    phase = st[_PHASE]
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
        eval_end = _evaluation_end(t0, t1, t_eval, st[NEXT_EVAL], st[_CLOSED_RIGHT] == 1)
        if eval_end < 0:
            return _finish(st, INVALID_ARGUMENT)
        st[_EVAL_END] = eval_end
        f[_T] = t0
        f[_RTOL] = _py_max(f[_RTOL_GIVEN], RTOL_FLOOR)
        if not _all_finite(f, y, n):
            return _finish(st, NON_FINITE)
        for i in range(n):
            f[y_stage + i] = f[y + i]
        return _request(f, st, t0, 0, _PHASE_F0)

    method = TABLEAUX[st[_METHOD]]
    S = method.n_stages
    while True:
        if phase == _PHASE_STAGE:
            # The last stage is in K (machine_on_arrays asked for the others): the new
            # state and its slope.
            t = f[_T]
            h = f[_H]
            _combine(K, K_flat, S, method.B, f, y_new, n)
            for i in range(n):
                f[y_new + i] = f[y + i] + h * f[y_new + i]
                f[y_stage + i] = f[y_new + i]
            return _request(f, st, t + h, S, _PHASE_F_NEW)

        elif phase == _PHASE_F_NEW:
            # f_new = rhs(t + h, y_new) is in K[S]: accept or reject.
            h_abs = f[_H_ABS]
            error = _error_norm(method, K, K_flat, f, f[_H], f[_RTOL], n)
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
            if h_abs != h_abs:  # (scipy's trials go on at NaN forever)
                return _finish(st, STEP_NOT_A_NUMBER)
            if h_abs < f[_MIN_STEP]:
                if st[_LAST_ERROR_FINITE] == 1:
                    return _finish(st, STEP_TOO_SMALL)
                return _finish(st, NON_FINITE)
            t_new = t + h_abs
            if t_new > f[_T1]:
                t_new = f[_T1]
            h = t_new - t
            f[_H] = h
            f[_H_ABS] = abs(h)
            f[_T_NEW] = t_new
            st[_STAGE] = 1
            _stage_argument(K, K_flat, 1, method.A[1], f, y, h, n)
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
                return _finish(st, NON_FINITE)
            f[_T_OLD] = t_old
            f[_T] = t
            if st[N_ACCEPTED] < st[_LOG_SIZE]:
                f[_log_at(n) + st[N_ACCEPTED]] = t
            st[N_ACCEPTED] += 1
            st[RUN_ACCEPTED] += 1
            f[TIME_REACHED] = t
            if method.stiffness_bound > 0.0 and _too_stiff(method, K, f, st, n, t):
                return _finish(st, STIFF)
            # The evaluation times this step serves: t_e <= t.
            first = st[NEXT_EVAL]
            stop = first
            eval_end = st[_EVAL_END]
            while stop < eval_end and t_eval[stop] <= t:
                stop += 1
            st[_STOP] = stop
            phase = _PHASE_STEP_END
            if stop > first:
                if method.dop853:  # its interpolant needs its extra stages first
                    st[_STAGE] = S
                    phase = _PHASE_EXTRA
                elif not _serve(method, K, K_flat, f, st, t_eval, y_eval, n):
                    return _finish(st, NON_FINITE)

        elif phase == _PHASE_STEP_END:
            if f[_T] >= f[_T1]:
                return _finish(st, SUCCESS)
            for i in range(n):
                K[0, i] = K[S, i]
            phase = _PHASE_STEP

        elif phase == _PHASE_STEP:
            # A new step from (t, y) with f in K[0]: bound the proposed size.
            t = f[_T]
            min_step = 10 * abs(math.nextafter(t, math.inf) - t)
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
                _stage_argument(K, K_flat, s, method.A[s], f, y_old, h, n)
                return _request(f, st, t_old + method.C[s] * h, s, _PHASE_EXTRA)
            if not _serve(method, K, K_flat, f, st, t_eval, y_eval, n):
                return _finish(st, NON_FINITE)
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
                f[ratio + i] = _divided(f[y + i], f[scale + i])
            d0 = _rms(f, ratio, n)
            for i in range(n):
                f[ratio + i] = _divided(K[0, i], f[scale + i])
            d1 = _rms(f, ratio, n)
            if d0 < 1e-5 or d1 < 1e-5:
                h0 = 1e-6
            else:
                h0 = 0.01 * d0 / d1
            h0 = _py_min(h0, interval)
            for i in range(n):
                f[y_stage + i] = f[y + i] + h0 * K[0, i]
            f[_H0] = h0
            f[_D1] = d1
            return _request(f, st, t0 + h0, 1, _PHASE_F1)

        elif phase == _PHASE_F1:
            # Second half: f1 = rhs(t0 + h0, y0 + h0 f0) is in K[1].
            h0 = f[_H0]
            d1 = f[_D1]
            scale = _at(_SCALE, n)
            ratio = _at(_ERR, n)
            for i in range(n):
                f[ratio + i] = _divided(K[1, i] - K[0, i], f[scale + i])
            d2 = _rms(f, ratio, n) / h0
            if d1 <= 1e-15 and d2 <= 1e-15:
                h1 = _py_max(1e-6, h0 * 1e-3)
            else:
                h1 = (0.01 / _py_max(d1, d2)) ** (1 / (method.estimator_order + 1))
            interval = abs(f[_T1] - f[_T0])
            f[_H_ABS] = _py_min(_py_min(_py_min(100 * h0, h1), interval), f[_MAX_STEP])
            phase = _PHASE_STEP

        else:
            return FINISHED


def _by_address_in_python(*args):
    raise TypeError("machine takes addresses: compiled code only (Python calls machine_on_arrays)")


@jit(inline=True, python=_by_address_in_python)
def machine(t_eval_at, m, y_eval_at, floats_at, floats_size, stages_at, n, ints_at):
    """:func:`machine_on_arrays` on arrays given by address (compiled callers).

    Given addresses, the machine views the memory with arrays that own nothing
    (:func:`controlkit._jit.floats_at`), whose reference counting compiles to nothing
    (see :mod:`.workspace`); the caller keeps the arrays alive, as :func:`solve_interval`
    does. Compiled once and kept in the store
    (:func:`controlkit.engines.fast.store.step_machine`), it is called, not pasted, by
    every diagram's module.
    """
    t_eval = _jit.floats_at(t_eval_at, m)
    y_eval = _jit.matrix_at(y_eval_at, m, n)
    f = _jit.floats_at(floats_at, floats_size)
    K = _jit.matrix_at(stages_at, STAGE_ROWS, n)
    K_flat = _jit.floats_at(stages_at, STAGE_ROWS * n)
    st = _jit.ints_at(ints_at, N_INT_SLOTS)
    return machine_on_arrays(t_eval, y_eval, f, K, K_flat, st)
