"""Explicit Runge-Kutta integration that takes the steps scipy's ``solve_ivp`` takes.

The three explicit methods of :func:`scipy.integrate.solve_ivp` -- ``"RK23"``
(Bogacki-Shampine 3(2) [4]_), ``"RK45"`` (Dormand-Prince 5(4) [2]_ with Shampine's
dense output [3]_, python-control's default) and ``"DOP853"`` (Hairer's 8(5,3) [1]_)
-- as loops numba compiles, so that a compiled right-hand side is integrated without a
Python call per stage. "The same steps" is meant literally: the initial step, the
error norm, the acceptance test, the step-size factors, the clipping at the end of the
interval and the dense output are scipy 1.17's [5]_, operation for operation, and so
is the arithmetic (every combination of stages is the BLAS call numpy makes in scipy;
:mod:`.arithmetic` says why plain loops would not do): the results are scipy's to the
last bit.

Modules: :mod:`.tableaux` (scipy's own coefficients: a method is its tableau),
:mod:`.workspace` (the integrator's arrays, their slots, the status codes), :mod:`.machine`
(the step machine), :mod:`.interval` (the loop around it), :mod:`.arithmetic` (stage
combinations, error norm, interpolants) and :mod:`.stiffness`.

Design
------
**Reverse communication.** The integrator never calls the right-hand side: the step
machine (:func:`machine`) asks its caller to evaluate it and is called again with the
result (as RKSUITE and ODEPACK do). What a caller compiles is the six-line loop
:func:`solve_interval`, which numba pastes into it, so the right-hand side stays a
compile-time constant of the caller, which is then cached on disk.

**Compiled once.** The machine does not depend on the right-hand side, the type of its
``args`` or the method (a run-time index into :data:`TABLEAUX`): it is compiled once
and kept in the store, named by controlkit's own source (editing these files compiles
it again); a diagram's module calls it, so a new diagram compiles no slower than a
diagram with no integrator. Its state is one workspace of four flat arrays
(:mod:`~controlkit.engines.fast.rk.workspace` says why).

**Evaluation times.** One :func:`solve_interval` call is one ``solve_ivp(fun, (t0,
t1), y0, t_eval=...)`` call: a fresh initial step, a stop exactly at ``t1``. It serves
the times ``t0 <= t_e < t1``, plus ``t_e == t1`` when ``closed_right`` (pass False but
for the last interval of a sampled-data loop: a time at a sample instant is then served
by the next interval at its start, after the discrete update, and equals the state
exactly). A time equal to a step's end is read from that step's interpolant at
``x = 1``, as scipy does (it may differ from the step's state in the last bits); a time
equal to ``t0`` is ``y0`` exactly; ``t0 == t1`` takes no step and serves nothing
(scipy treats that span as backward and returns no points).

**Status codes** (never a silent NaN): :data:`STATUS_MESSAGES`, and the constants'
comments in :mod:`~controlkit.engines.fast.rk.workspace`.

Comparing with python-control
-----------------------------
Bit-for-bit agreement needs the right-hand side to compute the same bits too: at loose
tolerances the step-size control amplifies a last-bit difference in it (numpy's ``tanh``
against the C library's compiled: 2.4e-10 after 20 s of Van der Pol at ``rtol = 1e-3``,
measured in benchmarks/README.md, *Last bits and adaptive steps*). Equality at
python-control's default ``rtol = 1e-3`` asks for a compiled right-hand side that
reproduces numpy's bits, not merely its formulas.

Without numba (or with ``CONTROLKIT_DISABLE_NUMBA=1``) the same functions run as plain
Python and take the same steps.

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

from .interval import solve_interval
from .machine import machine
from .tableaux import METHOD_INDEX, METHODS, RTOL_FLOOR, TABLEAUX
from .workspace import (
    INVALID_ARGUMENT,
    N_ACCEPTED,
    N_REJECTED,
    NEXT_EVAL,
    NFEV,
    NON_FINITE,
    PAUSED,
    PROJECTED_STEPS,
    STATUS_MESSAGES,
    STEP_NOT_A_NUMBER,
    STEP_TOO_SMALL,
    STIFF,
    STIFF_STEP_BUDGET,
    STIFF_STEPS_BEFORE_PROJECTING,
    STIFFNESS,
    SUCCESS,
    TIME_REACHED,
    make_workspace,
    set_horizon,
    step_times,
)

# what the engine, the tests and the benchmarks take from here
__all__ = [
    "INVALID_ARGUMENT", "METHODS", "METHOD_INDEX", "NEXT_EVAL", "NFEV", "NON_FINITE", "N_ACCEPTED",
    "N_REJECTED", "PAUSED", "PROJECTED_STEPS", "RTOL_FLOOR", "STATUS_MESSAGES",
    "STEP_NOT_A_NUMBER", "STEP_TOO_SMALL", "STIFF", "STIFFNESS", "STIFF_STEP_BUDGET",
    "STIFF_STEPS_BEFORE_PROJECTING", "SUCCESS", "TABLEAUX", "TIME_REACHED", "machine",
    "make_workspace", "set_horizon", "solve_interval", "step_times",
]
