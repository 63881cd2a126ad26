"""Explicit Runge-Kutta integration that takes the steps scipy's ``solve_ivp`` takes.

The three explicit methods of :func:`scipy.integrate.solve_ivp` -- ``"RK23"``
(Bogacki-Shampine 3(2) [4]_), ``"RK45"`` (Dormand-Prince 5(4) [2]_ with Shampine's
dense output [3]_, python-control's default) and ``"DOP853"`` (Hairer's 8(5,3) [1]_)
-- as loops numba compiles, so that a compiled right-hand side is integrated without a
Python call per stage. "The same steps" is meant literally: the initial step, the
error norm, the acceptance test, the step-size factors, the clipping at the end of the
interval and the dense output are scipy 1.17's [5]_, operation for operation, and with
``exact=True`` so is the arithmetic: the results are scipy's to the last bit.

Modules: :mod:`~controlkit.engines.fast.rk.tableaux` (the methods as
:class:`~controlkit.engines.fast.rk.tableaux.Tableau` records of scipy's own
coefficients: a method is its tableau, as in scipy), :mod:`~controlkit.engines.fast.rk.workspace` (the arrays the integrator
works in, their slots, the status codes), :mod:`~controlkit.engines.fast.rk.machine`
(the step machine), :mod:`~controlkit.engines.fast.rk.interval` (the loop around it),
:mod:`~controlkit.engines.fast.rk.arithmetic` (the stage combinations, error norm and
interpolants) and :mod:`~controlkit.engines.fast.rk.stiffness`.

Design
------
**Reverse communication.** The integrator never calls the right-hand side: the step
machine (:func:`machine`) returns "evaluate at ``work.floats[T_REQUEST]`` and
:func:`stage_input` into row ``r`` of ``work.stages``" and is called again with the
result (as RKSUITE and ODEPACK do). What a caller compiles is the six-line loop
:func:`solve_interval`, which numba pastes into it, so the right-hand side stays a
compile-time constant of the caller, which is then cached on disk.

**Compiled once.** The machine does not depend on the right-hand side, the type of its
``args`` or the method (a run-time index into :data:`TABLEAUX`): it is compiled once
and kept in the store; a diagram's module calls it, so a new diagram compiles no slower
than a diagram with no integrator. Its state is one :class:`Workspace` of four flat arrays,
which the machine views by address (numba would otherwise update the reference count
of each array it receives, atomically, at every call).

**Exact arithmetic.** scipy forms each combination of stages with ``numpy.dot``, i.e.
OpenBLAS gemv/gemm/ddot (fused multiply-adds, blocked summation; one state takes
vector-vector paths). The error estimate cancels, so another summation order changes
the step sizes by ~1e-13 relative, which the step-size controller amplifies: on van
der Pol at scipy's default tolerances, plain loops (``exact=False``) differ from scipy
by 3e-9 (RK45) and 1.5e-7 (DOP853) after 20 s. ``exact=True`` makes the BLAS calls
numpy makes (numba's ``numpy.dot`` calls the OpenBLAS bundled with scipy, which picks
the same kernels as numpy's on one machine). ``exact=False`` is faster for small
systems and equal to rounding.

**Evaluation times.** One :func:`solve_interval` call is one ``solve_ivp(fun, (t0,
t1), y0, t_eval=...)`` call: a fresh initial step, a stop exactly at ``t1``. It serves
the times ``t0 <= t_e < t1``, plus ``t_e == t1`` when ``closed_right`` (pass False but
for the last interval of a sampled-data loop: a time at a sample instant is then served
by the next interval at its start, after the discrete update, and equals the state
exactly). A time equal to a step's end is read from that step's interpolant at
``x = 1``, as scipy does (it may differ from the step's state in the last bits); a time
equal to ``t0`` is ``y0`` exactly; ``t0 == t1`` takes no step and serves nothing
(scipy treats that span as backward and returns no points).

**Status codes** (never a silent NaN): :data:`SUCCESS` 0; :data:`STEP_TOO_SMALL` -1
(scipy's failure: same message, time reached and evaluation count);
:data:`NON_FINITE` -2 (where scipy rejects NaN trials until the step is too small we
take the same steps but say why; where scipy hangs, its first step being NaN, we return
after one evaluation; where the stages stay finite but their sums overflow and scipy
returns inf/NaN as a success, we stop at the last finite state);
:data:`INVALID_ARGUMENT` -3. :func:`solve_ivp`, the Python-level wrapper, raises
scipy's ValueErrors with scipy's messages.

Comparing with python-control
-----------------------------
Bit-for-bit agreement needs the right-hand side to compute the same bits too. At loose
tolerances a last-bit difference in it is amplified as one in the summation order is:
numpy's own ``exp``, ``tanh``, ``log1p`` differ from the C library (what numba calls)
by 1 ulp for 5%, 25% and 6% of arguments on an AVX-512 machine, and numba computes
``x**3`` by multiplications where Python calls ``pow``. Van der Pol with ``2 tanh(y0)``
integrated with ``math.tanh`` compiled against scipy with ``numpy.tanh`` differs by
2.4e-10 (RK45) and 1.6e-5 (DOP853) after 20 s at ``rtol = 1e-3``, 5.8e-8 and 2.7e-2
after 200 s, and by at most 4e-13 at ``rtol = 1e-8`` (``benchmarks/rk_ulp_effect.py``).
Equality with python-control at its default ``rtol = 1e-3`` therefore asks for a
compiled right-hand side that reproduces numpy's bits, not merely its formulas.

Without numba (or with ``CONTROLKIT_DISABLE_NUMBA=1``) the same functions run as plain
Python and take the same steps.

The machine is compiled once and kept in the store, named by controlkit's own source
(:mod:`controlkit.engines.fast.store`): editing any of these files compiles it again,
with nothing to delete by hand.

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

import warnings

import numpy as np

from ...._jit import python_function
from .interval import solve_interval
from .machine import FINISHED, machine, machine_on_arrays
from .tableaux import (
    DENSE_DOP853,
    DENSE_POWERS,
    DOP853,
    EPS,
    ERROR_DOP853,
    ERROR_EMBEDDED,
    MAX_FACTOR,
    METHOD_INDEX,
    METHODS,
    MIN_FACTOR,
    RK23,
    RK45,
    RTOL_FLOOR,
    SAFETY,
    TABLEAUX,
    Tableau,
)
from .workspace import (
    DENSE_ROWS,
    INVALID_ARGUMENT,
    N_ACCEPTED,
    N_DENSE,
    N_FLOAT_SLOTS,
    N_INT_SLOTS,
    N_REJECTED,
    NEXT_EVAL,
    NEXT_STEP,
    NFEV,
    NON_FINITE,
    PAUSED,
    PROJECTED_STEPS,
    RUN_ACCEPTED,
    STAGE_ROWS,
    STATUS,
    STATUS_MESSAGES,
    STEP_TOO_SMALL,
    STIFF,
    STIFF_STEP_BUDGET,
    STIFF_STEPS_BEFORE_PROJECTING,
    STIFFNESS,
    SUCCESS,
    T_REQUEST,
    TIME_FAILED,
    TIME_REACHED,
    Workspace,
    load,
    make_workspace,
    set_horizon,
    stage_input,
    state,
    step_times,
)

__all__ = [
    "DENSE_DOP853", "DENSE_POWERS", "DENSE_ROWS", "DOP853", "EPS", "ERROR_DOP853",
    "ERROR_EMBEDDED", "FINISHED", "INVALID_ARGUMENT", "MAX_FACTOR", "METHODS",
    "METHOD_INDEX", "MIN_FACTOR", "NEXT_EVAL", "NEXT_STEP", "NFEV", "NON_FINITE",
    "N_ACCEPTED", "N_DENSE", "N_FLOAT_SLOTS", "N_INT_SLOTS", "N_REJECTED", "PAUSED",
    "PROJECTED_STEPS", "RK23", "RK45", "RTOL_FLOOR", "RUN_ACCEPTED", "SAFETY", "STAGE_ROWS",
    "STATUS", "STATUS_MESSAGES", "STEP_TOO_SMALL", "STIFF", "STIFFNESS",
    "STIFF_STEP_BUDGET", "STIFF_STEPS_BEFORE_PROJECTING", "SUCCESS", "TABLEAUX",
    "TIME_FAILED", "TIME_REACHED", "T_REQUEST", "Tableau", "Workspace", "load", "machine",
    "machine_on_arrays", "make_workspace", "set_horizon", "solve_interval", "solve_ivp",
    "stage_input", "state", "step_times",
]


def _validate_like_scipy(t_span, y0, rtol, atol, max_step, first_step, t_eval):
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
        -3 invalid argument; -4 stiff, :data:`STIFF`), ``message``, ``success``,
        ``nfev``, ``n_accepted``, ``n_rejected``, ``t_reached``, ``step_times``,
        ``stiffness`` (the estimate of ``|h lambda|`` on the last accepted step) and
        ``projected_steps`` (the steps a run stopped as stiff would have needed, else 0).

    Raises
    ------
    ValueError
        ``method`` unknown, or scipy's checks (:func:`_validate_like_scipy`), with
        scipy's messages.

    Examples
    --------
    The same evaluations and, to the last bit, the same values as scipy:

    >>> import numpy as np
    >>> from scipy.integrate import solve_ivp as scipy_solve_ivp
    >>> from controlkit.engines.fast import rk
    >>> def decay(t, y, args, out):
    ...     out[0] = -args[0][0] * y[0]
    >>> t_eval = [0.0, 0.5, 1.0, 2.0]
    >>> ours = rk.solve_ivp(decay, (0.0, 2.0), [1.0], t_eval=t_eval, args=(np.array([0.5]),))
    >>> theirs = scipy_solve_ivp(lambda t, y: -0.5 * y, (0.0, 2.0), [1.0], t_eval=t_eval)
    >>> ours["status"], ours["nfev"] == theirs.nfev, bool(np.array_equal(ours["y"], theirs.y))
    (0, True, True)
    """
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {sorted(METHODS)}, got {method!r}.")
    t0, t1, y0, rtol, atol, max_step, first_step, t_eval = _validate_like_scipy(
        t_span, y0, rtol, atol, max_step, first_step, t_eval
    )
    n = y0.shape[0]
    rhs = python_function(rhs)  # a Python run of the machine calls Python functions
    if t_eval is None:
        t_eval = np.zeros(0)
    y_eval = np.full((t_eval.shape[0], n), np.nan)
    y_end = np.empty(n)
    work = make_workspace(n, int(log_steps), t_eval.shape[0])
    status, served = solve_interval(None, rhs, args, METHOD_INDEX[method], t0,
                                    t1, y0, rtol, atol, max_step, first_step, t_eval, 0,
                                    True, y_eval, y_end, work, bool(exact), 0, False)
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
        "stiffness": float(work.floats[STIFFNESS]),
        "projected_steps": float(work.floats[PROJECTED_STEPS]),
    }
