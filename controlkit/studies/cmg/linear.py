"""Where a linearization of the CMG loop means something, and where it does not.

The adaptive sliding-mode controller (thesis eq. 20-45) rests, once the references are
constant (``t > 8`` s), on both sliding surfaces ``s = 0`` with the gimbals at their
targets and every speed zero: an equilibrium (:data:`REST`). There:

- with the thesis's switching term ``eta sgn(s)`` the loop has **no** linearization: ``sgn``
  jumps by ``2 eta`` across ``s = 0``, exactly where the loop rests, so a difference
  quotient of step ``h`` returns ``eta / h`` and grows without bound as ``h`` shrinks
  (:func:`closed_loop_radius` with ``boundary_layer=0`` and ``eps=h`` shows it). What the
  small motions do is the sliding motion of reduced order (``z' = -C z`` on the surface)
  and, sampled at ``Ts``, a chattering band around it: not a spectrum;
- with a boundary layer ``sat(s / phi)`` the switching term is linear for ``|s| < phi``,
  with slope ``eta / phi``, and the loop linearizes: :func:`closed_loop_radius` and
  :func:`loop_gain_at_torques`. Inside the layer each surface obeys, sampled,
  ``s[k+1] ~ (1 - Ts (C + eta / phi)) s[k]``: the sampled loop loses stability when
  ``phi < eta Ts / (2 - C Ts)`` (:func:`critical_boundary_layer`: 5.0e-4 rad/s of ``s``
  for the thesis's gains at 1 ms), and below it the layer chatters as ``sgn`` does.

Seven eigenvalues of the linearized loop lie at exactly 1 whatever ``phi``: the four
adaptive estimates (their laws multiply ``s`` by a speed, both zero at rest), the rotor's
angle ``q1`` (twice), which the loop does not control, and a family of rest states: a rotor
spinning at a steady ``w1`` whose friction torque ``T1`` the controller supplies through a
steady error in ``q4`` (its law has no integral action). Stability is judged on the
others.
"""

from __future__ import annotations

import numpy as np

from ...analysis import loop_transfers, reduced
from . import scenario

#: The loop at rest after the references settle: ``q2 = pi/3``, ``q4 = 1`` rad, the rotor
#: angle 0, every speed and every adaptive estimate 0 (``[q1, q2, q4, w1, w2, w4, a1..a4]``).
REST = np.array([0.0, np.pi / 3, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
#: A time after the references settled (they are constant for ``t > 8`` s).
SETTLED = 12.0
#: The plant inputs the loop is cut at: the motor torques behind the saturation.
TORQUES = ["T1", "T2"]
#: How close to 1 an eigenvalue of the structural modes at rest lies (rounding only).
MARGINAL = 1e-9


def loop_gain_at_torques(boundary_layer, *, at=TORQUES, eps=None, **gains):
    """:class:`~controlkit.analysis.loops.LoopTransfers` of the thesis's loop at :data:`REST`,
    cut at the motor torques (``at``), with the switching term ``sat(s / boundary_layer)``.

    Examples
    --------
    >>> L, S, T = loop_gain_at_torques(0.05, at="T2")
    >>> L.input_labels
    ['T2']
    """
    loop = scenario.build_loop(boundary_layer=boundary_layer, **gains)
    return loop_transfers(loop, at, REST, [], t=SETTLED, eps=eps)


def closed_loop_radius(boundary_layer, *, eps=None, **gains) -> float:
    """The largest ``|eigenvalue|`` of the closed loop at :data:`REST` (the poles of its
    sensitivity at the torques) other than the seven at exactly 1 (module description);
    < 1 is stable. ``eps``: the difference step, to show that with ``boundary_layer=0``
    the result is about ``eta / eps``, no derivative.

    Examples
    --------
    >>> closed_loop_radius(0.05) < 1.0
    True
    """
    S = reduced(loop_gain_at_torques(boundary_layer, eps=eps, **gains).S)
    radii = np.abs(np.linalg.eigvals(S.A))
    return float(radii[np.abs(radii - 1.0) > MARGINAL].max())


def critical_boundary_layer(*, low=1e-5, high=1e-1, rtol=1e-6, **gains) -> float:
    """The thinnest boundary layer with a stable linearized loop, by bisection (below it
    the sampled loop inside the layer is unstable: chattering).

    Examples
    --------
    >>> round(critical_boundary_layer(rtol=1e-3) * 1e4, 2)  # eta Ts / (2 - C Ts) = 5.01e-4
    5.02
    """
    if closed_loop_radius(high, **gains) >= 1.0:
        raise ValueError(f"the loop is unstable even with a boundary layer of {high:g}")
    while np.log(high / low) > rtol:
        middle = np.sqrt(low * high)
        if closed_loop_radius(middle, **gains) >= 1.0:
            low = middle
        else:
            high = middle
    return float(high)
