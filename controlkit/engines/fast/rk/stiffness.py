"""Hairer's stiffness test: whether an explicit method's steps are held down by stability.

DOPRI5 and DOP853 (Hairer & Wanner, *Solving Ordinary Differential Equations II*, 2nd ed.,
Sec. IV.2) estimate ``|h lambda|`` on each accepted step and call the problem stiff after
:data:`~.workspace.STIFF_STEPS_IN_ROW` steps above the method's stability bound; the
machine then stops a run whose projected steps exceed :data:`~.workspace.STIFF_STEP_BUDGET`
(:data:`~.workspace.STIFF`).
"""

from __future__ import annotations

import math

from ...._jit import jit
from .workspace import (
    _NONSTIFF_IN_ROW,
    _RUN_END,
    _RUN_START,
    _STIFF_IN_ROW,
    _T0,
    _T1,
    NONSTIFF_STEPS_IN_ROW,
    PROJECTED_STEPS,
    RUN_ACCEPTED,
    STIFF_STEP_BUDGET,
    STIFF_STEPS_BEFORE_PROJECTING,
    STIFF_STEPS_IN_ROW,
    STIFFNESS,
)


@jit(inline=True)
def _stiffness(method, K, n):
    """Hairer's estimate of ``|h lambda|`` for the accepted step (a method with the test).

    The new state and the last stage's argument both sit at ``t + h``; their
    derivatives ``k_S`` and ``k_{S-1}`` differ by about the Jacobian times their
    difference ``h sum_j w_j k_j`` (``w``: the tableau's ``stiffness_weights``), so

    .. math::

        |h \\lambda| \\approx \\frac{\\lVert k_S - k_{S-1} \\rVert}
        {\\lVert \\sum_j w_j k_j \\rVert}

    estimates the step size times the largest eigenvalue of the Jacobian along the
    step. An explicit step whose value sits at the edge of the method's stability
    region (above ``stiffness_bound``) is held down by stability: the problem is stiff.
    """
    S = method.n_stages
    w = method.stiffness_weights
    num = 0.0
    den = 0.0
    for i in range(n):
        d = K[S, i] - K[S - 1, i]
        num += d * d
        c = 0.0
        for j in range(S):
            c += w[j] * K[j, i]
        den += c * c
    if den == 0.0:
        return 0.0
    return math.sqrt(num / den)



@jit(inline=True)
def _too_stiff(method, K, f, st, n, t):
    """Hairer's stiffness test on the step just accepted, and whether the run must stop.

    A step counts as stiff when :func:`_stiffness` exceeds the method's
    bound; :data:`STIFF_STEPS_IN_ROW` of them (with fewer than
    :data:`NONSTIFF_STEPS_IN_ROW` other steps in between) make the run look stiff. It
    then stops if the steps it would need, ``N (t_end - t_start) / (t - t_start)`` from
    the ``N`` accepted since the run's start (:func:`~.workspace.set_horizon`, else the
    interval's), exceed :data:`STIFF_STEP_BUDGET`.
    """
    h_lambda = _stiffness(method, K, n)
    f[STIFFNESS] = h_lambda
    if h_lambda <= method.stiffness_bound:
        st[_NONSTIFF_IN_ROW] += 1
        if st[_NONSTIFF_IN_ROW] >= NONSTIFF_STEPS_IN_ROW:
            st[_STIFF_IN_ROW] = 0
        return False
    st[_NONSTIFF_IN_ROW] = 0
    st[_STIFF_IN_ROW] += 1
    if st[_STIFF_IN_ROW] < STIFF_STEPS_IN_ROW or st[RUN_ACCEPTED] < STIFF_STEPS_BEFORE_PROJECTING:
        return False
    start = f[_RUN_START]
    end = f[_RUN_END]
    if not (math.isfinite(start) and math.isfinite(end)):
        start = f[_T0]
        end = f[_T1]
    done = abs(t - start)
    if done == 0.0:
        return False
    projected = st[RUN_ACCEPTED] * (abs(end - start) / done)
    if projected <= STIFF_STEP_BUDGET:
        return False
    f[PROJECTED_STEPS] = projected
    return True
