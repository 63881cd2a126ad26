"""One interval of integration, as one ``solve_ivp`` call: the loop around the machine,
which numba pastes into its callers (:mod:`controlkit.engines.fast.rk`, *Design*).

A call may stop after a budget of evaluations and be resumed: a long run returns to
Python between pieces (progress, Ctrl-C).
"""

from __future__ import annotations

from .... import _jit
from ...._jit import jit
from .machine import machine_on_arrays
from .workspace import (
    _Y,
    _Y_STAGE,
    INVALID_ARGUMENT,
    NEXT_EVAL,
    PAUSED,
    STAGE_ROWS,
    STATUS,
    T_REQUEST,
    _at,
    load,
    stage_input,
    state,
)


def _solve_interval_compiled(machine_function, rhs, args, method_index, t0, t1, y0, rtol,
                             atol, max_step, first_step, t_eval, i_eval, closed_right, y_eval,
                             y_end, work, budget, resume):
    """Integrate ``y' = rhs(t, y)`` over ``[t0, t1]`` as one ``solve_ivp`` call would.

    The steps are scipy's (see :mod:`.machine`); after each accepted step ending at
    ``t``, the evaluation times not yet served with ``t_e <= t`` are read from that
    step's interpolant, a time equal to ``t0`` comes out exactly ``y0``.

    Parameters
    ----------
    machine_function : callable
        The step machine compiled once and kept
        (:func:`controlkit.engines.fast.store.step_machine`), which compiled callers call
        by address; ignored by Python calls (they run :func:`machine_on_arrays`).
    rhs : callable
        ``rhs(t, y, args, out)`` writes ``y'`` into ``out`` (a 1-D float64 array): a
        function of the compiled caller, or any Python function in a Python call.
    args : tuple
        Passed to ``rhs`` untouched (parameters, input tables, scratch arrays).
    method_index : int
        ``METHOD_INDEX[name]``: 0 RK23, 1 RK45, 2 DOP853 (the tableaux :data:`TABLEAUX`).
    t0, t1 : float
        The interval, forward (``t1 < t0`` is an invalid argument: the engine never
        integrates backwards); ``t1 == t0`` takes no step and, as in scipy, serves no
        evaluation time.
    y0 : numpy.ndarray, shape (n,)
        State at ``t0`` (read only).
    rtol : float
        Relative tolerance, raised to :data:`RTOL_FLOOR` if smaller (silently here).
    atol : numpy.ndarray, shape (n,)
        Absolute tolerance per state (``np.full(n, atol)`` for a scalar).
    max_step : float
        Largest step (``numpy.inf``: unbounded); > 0.
    first_step : float
        First step; 0 lets the integrator choose; else in ``(0, t1 - t0]``.
    t_eval : numpy.ndarray, shape (m,)
        Evaluation times, increasing (the interval is integrated forward: ``t1 >= t0``).
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
    budget : int
        At most this many evaluations of ``rhs`` in this call (0: no limit); past it the
        call returns :data:`PAUSED`, the interval held in ``work`` to go on with.
    resume : bool
        Go on with the interval ``work`` holds (paused), instead of loading a new one
        (the interval's arguments are then not read again).

    Returns
    -------
    status : int
        :data:`SUCCESS`, :data:`STEP_TOO_SMALL`, :data:`NON_FINITE`, :data:`STIFF` (a
        run that looks stiff and would need more than :data:`STIFF_STEP_BUDGET` steps,
        projected over :func:`set_horizon`'s span or else the interval) or
        :data:`INVALID_ARGUMENT` (meanings in :data:`STATUS_MESSAGES`), or
        :data:`PAUSED` (the budget is spent: call again with ``resume=True``).
    next_eval : int
        Index of the first evaluation time not served.

    Examples
    --------
    ``y' = -y / 2`` over two sample intervals, as a sampled-data loop calls it: the
    state is updated in place (``y_end`` is ``y0``), the first interval leaves ``t = 1``
    to the second (``closed_right=False``), which serves it at its start:

    >>> import numpy as np
    >>> from controlkit.engines.fast import rk
    >>> def decay(t, y, args, out):
    ...     out[0] = -args[0][0] * y[0]
    >>> args = (np.array([0.5]),)
    >>> t_eval = np.linspace(0.0, 2.0, 5)
    >>> y_eval = np.zeros((5, 1))
    >>> y = np.ones(1)
    >>> work = rk.make_workspace(1, 0, t_eval.size)
    >>> served = 0
    >>> for t0, t1 in [(0.0, 1.0), (1.0, 2.0)]:
    ...     status, served = rk.solve_interval(
    ...         None, decay, args, rk.METHOD_INDEX["RK45"], t0, t1, y, 1e-8,
    ...         np.full(1, 1e-10), np.inf, 0.0, t_eval, served, t1 == 2.0, y_eval, y, work,
    ...         0, False)
    >>> int(status) == rk.SUCCESS, int(served)
    (True, 5)
    >>> bool(np.allclose(y_eval[:, 0], np.exp(-0.5 * t_eval), rtol=1e-7))
    True
    """
    if not resume:
        load(method_index, t0, t1, y0, rtol, atol, max_step, first_step, i_eval,
             closed_right, work)
    floats = work.floats
    ints = work.ints
    n = work.stages.shape[1]
    if not (t_eval.flags.c_contiguous and y_eval.flags.c_contiguous):
        ints[STATUS] = INVALID_ARGUMENT
        return ints[STATUS], i_eval
    floats_at = floats.ctypes.data
    stages_at = work.stages.ctypes.data
    # Views that own nothing (see machine): handing them to rhs costs no atomic updates.
    floats_view = _jit.floats_at(floats_at, floats.shape[0])
    y_stage = floats_view[_at(_Y_STAGE, n) : _at(_Y_STAGE, n) + n]
    stages = _jit.matrix_at(stages_at, STAGE_ROWS, n)
    m = t_eval.shape[0]
    t_eval_at, y_eval_at, size, ints_at = (t_eval.ctypes.data, y_eval.ctypes.data,
                                           floats.shape[0], ints.ctypes.data)
    # the arguments spelled out, not *args: this loop is pasted into callers that are
    # themselves pasted into others, where numba cannot call a function value with *args
    row = machine_function(t_eval_at, m, y_eval_at, floats_at, size, stages_at, n, ints_at)
    spent = 0
    while row >= 0:
        rhs(floats[T_REQUEST], y_stage, args, stages[row])
        spent += 1
        if budget > 0 and spent >= budget:
            return PAUSED, ints[NEXT_EVAL]  # the request is answered: resume calls the machine
        row = machine_function(t_eval_at, m, y_eval_at, floats_at, size, stages_at, n, ints_at)
    if ints[STATUS] != INVALID_ARGUMENT:
        start = _at(_Y, n)
        for i in range(n):
            y_end[i] = floats[start + i]
    return ints[STATUS], ints[NEXT_EVAL]


def _solve_interval_python(machine_function, rhs, args, method_index, t0, t1, y0, rtol,
                           atol, max_step, first_step, t_eval, i_eval, closed_right, y_eval,
                           y_end, work, budget, resume):
    # the same loop on the arrays themselves (Python cannot view memory by address)
    if not resume:
        load(method_index, t0, t1, y0, rtol, atol, max_step, first_step, i_eval,
             closed_right, work)
    floats, stages, stages_flat, ints = work
    y_stage = stage_input(work)
    row = machine_on_arrays(t_eval, y_eval, floats, stages, stages_flat, ints)
    spent = 0
    # solve_ivp's first call, fun(t0, y0), is given t0 as a Python float, its later ones
    # numpy's floats: a function's 0.5 / t at t0 = 0 raises ZeroDivisionError there, as in
    # python-control, where numpy's float would give inf
    t = float(floats[T_REQUEST]) if not resume and row >= 0 else floats[T_REQUEST]
    while row >= 0:
        rhs(t, y_stage, args, stages[row])
        spent += 1
        if budget > 0 and spent >= budget:
            return PAUSED, ints[NEXT_EVAL]
        row = machine_on_arrays(t_eval, y_eval, floats, stages, stages_flat, ints)
        t = floats[T_REQUEST]
    if ints[STATUS] != INVALID_ARGUMENT:
        y_end[:] = state(work)
    return ints[STATUS], ints[NEXT_EVAL]


solve_interval = jit(_solve_interval_compiled, inline=True, python=_solve_interval_python)
