"""One interval of integration, as one ``solve_ivp`` call: the loop around the machine.

:func:`solve_interval` is what compiled callers (the generated simulation loops) call:
six lines that load the interval, then evaluate the right-hand side whenever the step
machine asks and call it again. numba pastes it into its caller (``inline="always"``),
so a right-hand side that is a global of the caller stays a compile-time constant
there and the caller can be cached on disk. The machine itself is passed in: either
:func:`~controlkit.engines.fast.rk.machine.machine` (its code is then compiled into
the caller) or the first-class function :func:`machine_function` returns (called
through a pointer: a new diagram then compiles no more than its own loop).
"""

from __future__ import annotations

import numpy as np

from ...._jit import HAVE_NUMBA, jit
from .machine import machine
from .workspace import (
    _Y,
    _Y_STAGE,
    INVALID_ARGUMENT,
    NEXT_EVAL,
    STAGE_ROWS,
    STATUS,
    T_REQUEST,
    _at,
    load,
    stage_input,
    state,
)

if HAVE_NUMBA:
    import numba

    from ...._jit import void_pointer


def solve_interval(machine_function, rhs, args, method_index, t0, t1, y0, rtol, atol,
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
        :data:`SUCCESS`, :data:`STEP_TOO_SMALL`, :data:`NON_FINITE`, :data:`STIFF` (a
        run that looks stiff and would need more than :data:`STIFF_STEP_BUDGET` steps,
        projected over :func:`set_horizon`'s span or else the interval) or
        :data:`INVALID_ARGUMENT` (meanings in :data:`STATUS_MESSAGES`).
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
    >>> if rk.HAVE_NUMBA:
    ...     import numba
    ...     decay = numba.njit(decay)
    >>> args = (np.array([0.5]),)
    >>> t_eval = np.linspace(0.0, 2.0, 5)
    >>> y_eval = np.zeros((5, 1))
    >>> y = np.ones(1)
    >>> work = rk.make_workspace(1, 0, t_eval.size)
    >>> machine, rhs = rk.machine_function(), rk.first_class(decay, args)
    >>> served = 0
    >>> for t0, t1 in [(0.0, 1.0), (1.0, 2.0)]:
    ...     status, served = rk.solve_interval(
    ...         machine, rhs, args, rk.METHOD_INDEX["RK45"], t0, t1, y, 1e-8,
    ...         np.full(1, 1e-10), np.inf, 0.0, t_eval, served, t1 == 2.0, y_eval, y, work,
    ...         True)
    >>> int(status) == rk.SUCCESS, int(served)
    (True, 5)
    >>> bool(np.allclose(y_eval[:, 0], np.exp(-0.5 * t_eval), rtol=1e-7))
    True
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
    floats_view = numba.carray(void_pointer(floats_at), (floats.shape[0],), np.float64)
    y_stage = floats_view[_at(_Y_STAGE, n) : _at(_Y_STAGE, n) + n]
    stages = numba.carray(void_pointer(stages_at), (STAGE_ROWS, n), np.float64)
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
    # solve_interval without numba: the machine runs on the arrays themselves.
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


if HAVE_NUMBA:
    solve_interval = jit(solve_interval, inline=True)
else:
    _solve_interval_python.__doc__ = solve_interval.__doc__
    solve_interval = _solve_interval_python


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

    Examples
    --------
    Two right-hand sides with the same type of ``args`` have the same numba type, so a
    compiled caller that takes them as arguments is compiled once for both:

    >>> import numpy as np
    >>> from controlkit.engines.fast import rk
    >>> def decay(t, y, args, out):
    ...     out[0] = -args[0][0] * y[0]
    >>> def growth(t, y, args, out):
    ...     out[0] = args[0][0] * y[0]
    >>> if rk.HAVE_NUMBA:
    ...     import numba
    ...     decay, growth = numba.njit(decay), numba.njit(growth)
    >>> args = (np.array([0.5]),)
    >>> a, b = rk.first_class(decay, args), rk.first_class(growth, args)
    >>> not rk.HAVE_NUMBA or numba.typeof(a) == numba.typeof(b)
    True
    """
    if not HAVE_NUMBA:
        return rhs
    from numba.core import types

    vector = types.float64[::1]
    argument_types = (types.float64, vector, numba.typeof(args), vector)
    rhs.compile(argument_types)
    return _typed_once()(rhs.overloads[argument_types])


_MACHINE_FUNCTION = []
_TYPED_ONCE = []


def _typed_once():
    """numba's ``CompileResultWAP`` with its type made once, not at every call it is passed
    to (numba makes a new ``FunctionType`` each time: 15 us of every run)."""
    if not _TYPED_ONCE:
        from numba.core.types.function_type import CompileResultWAP
        from numba.extending import typeof_impl

        class TypedOnce(CompileResultWAP):
            def __init__(self, cres):
                super().__init__(cres)
                self.numba_type = numba.types.FunctionType(self.signature())

        @typeof_impl.register(TypedOnce)
        def _typeof(value, context):
            return value.numba_type

        _TYPED_ONCE.append(TypedOnce)
    return _TYPED_ONCE[0]


def machine_function():
    """:func:`machine` as a numba first-class function (plain :func:`machine` without numba).

    A compiled caller that receives this object as an argument calls the machine
    through a pointer: the machine's code (compiled once, cached on disk) is then not
    compiled again into each caller, which keeps a new diagram's compile time to its
    own right-hand side and loop. Built once per process.

    Examples
    --------
    >>> from controlkit.engines.fast import rk
    >>> rk.machine_function() is rk.machine_function()
    True
    """
    if not HAVE_NUMBA:
        return machine
    if not _MACHINE_FUNCTION:
        address = numba.types.uintp
        size = numba.types.intp
        argument_types = (address, size, address, address, size, address, size, address)
        machine.compile(argument_types)
        _MACHINE_FUNCTION.append(_typed_once()(machine.overloads[argument_types]))
    return _MACHINE_FUNCTION[0]

