"""What the MEC does to the spacecraft's loop, as numbers: its linearization at the target.

At the target attitude ``q = [1, 0, 0, 0]`` with the wheels at rest and no momentum
(``H0 = 0``: the paper's momentum is a disturbance, not part of the loop), every loop of
the paper is at equilibrium. :func:`controlkit.analysis.linearize` gives its discrete
model at ``Ts``, :func:`~controlkit.analysis.loops.loop_transfers` its loop gain and
sensitivities at the plant input ``u``, and the eigenvalues decide how large an inertia
error it tolerates:

- :func:`tolerated` brackets the scale ``s`` of the inertia error ``J_t = J_m + s Delta J``
  (Table 2's ``Delta J`` at ``s = 1``; one axis at a time, or all three along ``Delta J``)
  for the largest spectral radius of the closed loop crossing 1, in both directions from
  ``s = 1``, down to the physical limit (the body's inertia ``J_b`` positive definite);
- :func:`confirm` simulates the nonlinear loop just inside and just outside a bound;
- :func:`sensitivity_band` finds where the MEC's input sensitivity lies below the loop's
  without it.

Stability is judged on the modes the reference reaches and ``h`` shows
(:func:`~controlkit.analysis.loops.reduced`): the rotation about the antenna axis and the
quaternion's norm, two eigenvalues at exactly 1, are neither (the loop does not control
them and they do not move the antenna).
"""

from __future__ import annotations

from dataclasses import dataclass

import control as ct
import numpy as np

from ...analysis import linearize
from ...analysis.diagram import compose
from ...analysis.jacobians import block_jacobians
from ...analysis.linearize import jacobians_at
from ...analysis.loops import LoopTransfers, loop_transfers, reduced
from ...analysis.plots import frequency_response, gain
from ...blocks import mec
from ...blocks import spacecraft as sc
from ...blocks.sampling import sample_nlsys
from ...simulation import initial_state, simulate
from . import diagrams, scenario

#: The target attitude, the operating point of every linearization here.
TARGET = np.array([1.0, 0.0, 0.0, 0.0])
#: The directions of the inertia error: which diagonal entries of ``Delta J`` the scale
#: multiplies (the others stay at Table 2's).
DIRECTIONS = {"delta_J": (True, True, True), "x": (True, False, False),
              "y": (False, True, False), "z": (False, False, True)}
#: Heaviest error searched: ``s`` up to this (``J_t`` about 50 times ``J_m``).
SCALE_CAP = 1e4
#: Relative distance (on ``J_t / J_m`` of the reference axis) of the simulations that
#: confirm a bound, inside and outside it.
CONFIRM_MARGIN = 0.02


@dataclass(frozen=True)
class Setting:
    """The loop's design: outer gain ``F`` (1/s), period ``Ts`` (s), the fixed MEC gain.

    Examples
    --------
    >>> bool(Setting().omega[-1] == np.pi / 0.1)
    True
    """

    F: float = sc.F_PAPER
    Ts: float = sc.TS_PAPER
    K_fixed: float = scenario.K_FIXED

    @property
    def omega(self) -> np.ndarray:
        """Frequencies of the figures and of the band, rad/s: from far below ``F`` to the
        Nyquist frequency ``pi / Ts``."""
        return self.frequencies(600)

    def frequencies(self, points) -> np.ndarray:
        """``points`` frequencies log-spaced from 1e-6 rad/s to exactly ``pi / Ts``."""
        omega = np.logspace(-6, np.log10(np.pi / self.Ts), points)
        omega[-1] = np.pi / self.Ts  # exactly: the end of a sampled loop's Nyquist plot
        return omega


#: The paper's: F = 0.0009 1/s, Ts = 0.1 s, K = 0.1 I.
PAPER = Setting()


def _reference_axis(direction) -> int:
    """The axis whose ``J_t / J_m`` stands for the direction (x along ``Delta J``)."""
    return int(np.flatnonzero(_mask(direction))[0])


def _mask(direction) -> np.ndarray:
    if direction not in DIRECTIONS:
        raise ValueError(f"direction must be one of {list(DIRECTIONS)}, got {direction!r}")
    return np.array(DIRECTIONS[direction])


def inertia_scales(scale, direction="delta_J") -> np.ndarray:
    """The factors on ``Delta J``'s diagonal: ``scale`` on the direction's axes, 1 elsewhere.

    Examples
    --------
    >>> inertia_scales(3.0, "y").tolist()
    [1.0, 3.0, 1.0]
    """
    return np.where(_mask(direction), float(scale), 1.0)


def physical_limit(direction="delta_J") -> float:
    """The lowest scale with a positive-definite body inertia ``J_bn + s Delta J``.

    Examples
    --------
    >>> round(physical_limit("x"), 3)
    -199.97
    """
    axes = _mask(direction)
    return float(np.max(-np.diag(sc.J_BN)[axes] / np.diag(sc.DELTA_J)[axes]))


def loop_at_target(K=None, scale=1.0, direction="delta_J", *, setting=PAPER):
    """``(loop, xeq)``: the paper's loop around the plant with ``J_t = J_m + s Delta J``.

    Parameters
    ----------
    K : None, float or array_like
        None: the loop without MEC (Fig. 2); else the MEC with this constant gain (Fig. 3).
    scale : float
        ``s``, on the direction's axes of ``Delta J``.
    direction : str
        A key of :data:`DIRECTIONS`.
    setting : Setting
        ``F`` and ``Ts`` of the loop.

    Examples
    --------
    >>> loop, x = loop_at_target(0.1)
    >>> x.tolist()
    [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    """
    J_b = sc.J_BN + sc.DELTA_J * inertia_scales(scale, direction)
    plant, Ts = sc.spacecraft_plant(J_b=J_b), setting.Ts
    if K is None:
        loop = diagrams.output_zeroing_loop(plant, controller=sc.outer_controller(setting.F),
                                            Ts=Ts)
        return loop, initial_state(loop, plant=TARGET)
    loop = diagrams.mec_loop(plant, controller=sc.outer_controller(setting.F, output="mu_n"),
                             K=K, nominal=mec.nominal_model(Ts), Ts=Ts)
    return loop, initial_state(loop, plant=TARGET, nominal=np.zeros(2))


def spectral_radius(K=None, scale=1.0, direction="delta_J", *, setting=PAPER) -> float:
    """The largest ``|eigenvalue|`` of the loop's modes from ``r`` to ``h`` (< 1: stable).

    Examples
    --------
    >>> round(spectral_radius(None), 6)  # 1 - F Ts J_m / J_t
    0.99991
    """
    loop, x = loop_at_target(K, scale, direction, setting=setting)
    lin = reduced(linearize(loop, x, 0.0, copy_names=True), outputs=["h[0]", "h[1]"])
    return float(np.abs(np.linalg.eigvals(lin.A)).max())


class LoopFamily:
    """One loop's linearization at the target for any inertia error, without rebuilding it.

    At the target every block's operating point is the same whatever the inertia (the
    plant's output is its state, the wheels are at rest), so only the plant's Jacobians
    change with ``s``: they are computed for the new plant and put in place of the old,
    and the diagram's linearization is composed again (about ten times quicker than
    building and linearizing the loop anew, to the same numbers).

    Examples
    --------
    >>> family = LoopFamily(0.1)
    >>> abs(family.radius(-50.0) - spectral_radius(0.1, -50.0)) < 1e-12
    True
    """

    def __init__(self, K=None, direction="delta_J", *, setting=PAPER):
        loop, x = loop_at_target(K, 1.0, direction, setting=setting)
        self.direction = direction
        self.flat, self.jac = jacobians_at(loop, x, np.zeros(loop.ninputs), 0.0, None, None)
        self.plant = next(leaf for leaf in self.flat.leaves if leaf.name == "plant")
        self.x = x[self.plant.x]
        self.dt = loop.dt
        # the modes from r to h: which states they are depends on the wiring, not on s
        A, B, C, D = compose(self.flat, self.jac)
        outputs = [loop.output_labels.index(s) for s in ("h[0]", "h[1]")]
        states = list(loop.state_labels)
        lin = ct.StateSpace(A, B, C[outputs], D[outputs], self.dt, states=states,
                            remove_useless_states=False)
        self.modes = [states.index(s) for s in reduced(lin).state_labels]

    def radius(self, scale) -> float:
        """:func:`spectral_radius` at ``scale``."""
        J_b = sc.J_BN + sc.DELTA_J * inertia_scales(scale, self.direction)
        plant = sample_nlsys(sc.spacecraft_plant(J_b=J_b), self.dt)
        A, B, _, _, _ = block_jacobians(plant, 0.0, self.x, np.zeros(2), {})
        leaf, jac = self.plant, self.jac
        jac.A[leaf.x, leaf.x], jac.B[leaf.x, leaf.u] = A, B
        A = compose(self.flat, jac)[0][np.ix_(self.modes, self.modes)]
        return float(np.abs(np.linalg.eigvals(A)).max())


def _ratio(scale, direction) -> float:
    """``J_t / J_m`` of the direction's reference axis at ``scale``."""
    a = _reference_axis(direction)
    return 1.0 + scale * sc.DELTA_J[a, a] / sc.J_M[a, a]


def _scale(ratio, direction) -> float:
    a = _reference_axis(direction)
    return (ratio - 1.0) * sc.J_M[a, a] / sc.DELTA_J[a, a]


def tolerated(K=None, direction="delta_J", *, setting=PAPER, points=6, rtol=1e-5) -> dict:
    """The range of inertia-error scales around Table 2's (``s = 1``) the loop tolerates.

    On each side of ``s = 1`` the ratio ``J_t / J_m`` of the reference axis is stepped
    geometrically (``points`` steps, to the physical limit below and to
    :data:`SCALE_CAP` above) until the spectral radius reaches 1, and the crossing is then
    bracketed to ``rtol`` in that ratio (regula falsi on the logarithm of the ratio, with
    the Illinois modification: the bracket always holds a stable and an unstable point).

    Returns
    -------
    dict
        ``low`` and ``high``: the bounds on ``s`` (None where the loop stays stable to the
        end of the search), ``low_ratio`` and ``high_ratio`` (``J_t / J_m`` of the
        reference axis there), ``physical_limit``, ``searched_to`` (the cap) and
        ``stable_at_table2``.

    Examples
    --------
    >>> bounds = tolerated(0.1, "x", points=6, rtol=1e-3)
    >>> round(bounds["low"]), bounds["high"]
    (-199, None)
    """
    radius = LoopFamily(K, direction, setting=setting).radius
    limit = physical_limit(direction)
    out = {"physical_limit": limit, "searched_to": SCALE_CAP,
           "stable_at_table2": bool(radius(1.0) < 1.0)}
    ends = {"low": _ratio(limit, direction) * (1 + 1e-9), "high": _ratio(SCALE_CAP, direction)}
    for side, end in ends.items():
        out[side] = out[f"{side}_ratio"] = None
        if not out["stable_at_table2"]:
            continue
        inside = _ratio(1.0, direction)
        for ratio in np.geomspace(inside, end, points + 1)[1:]:
            if radius(_scale(ratio, direction)) >= 1.0:
                break
            inside = ratio
        else:
            continue
        inside, outside = _crossing(lambda r: radius(_scale(r, direction)) - 1.0, inside,
                                    ratio, rtol)
        out[f"{side}_ratio"] = float(np.sqrt(inside * outside))
        out[side] = float(_scale(out[f"{side}_ratio"], direction))
    return out


def _crossing(f, inside, outside, rtol):
    """Shrink ``(inside, outside)``, with ``f(inside) < 0 <= f(outside)``, to ``rtol`` in
    ``log(ratio)``: regula falsi with the Illinois modification (a side kept twice has its
    value halved), so each step keeps a stable and an unstable end."""
    a, b = np.log(inside), np.log(outside)
    fa, fb = f(inside), f(outside)
    kept = 0
    while abs(b - a) > rtol:
        c = b - fb * (b - a) / (fb - fa) if fb != fa else (a + b) / 2
        c = min(max(c, min(a, b) + 0.05 * abs(b - a)), max(a, b) - 0.05 * abs(b - a))
        fc = f(np.exp(c))
        if fc < 0:
            a, fa = c, fc
            kept = kept + 1 if kept > 0 else 1
            if kept > 1:
                fb /= 2
        else:
            b, fb = c, fc
            kept = kept - 1 if kept < 0 else -1
            if kept < -1:
                fa /= 2
    return float(np.exp(a)), float(np.exp(b))


def confirm(K, ratio, direction="delta_J", *, setting=PAPER, engine="fast", tilt_deg=0.05,
            decades=3.0) -> dict:
    """Simulate the nonlinear loop at ``J_t / J_m = ratio`` from a small tilt, no momentum.

    The horizon is long enough for the linearization's slowest mode to change the tilt
    ``10^decades`` times (at most 300 s). The loop is called stable when the largest
    ``|h|`` over the last tenth of the run is below the initial one, unstable when it grows
    past it or the run diverges.

    Returns
    -------
    dict
        ``scale``, ``ratio``, ``stable`` (from the simulation), ``predicted_stable``
        (from the eigenvalues), ``growth`` (last-tenth ``|h|`` over the initial; None when
        the run diverged), ``diverged`` and ``horizon_s``.

    Examples
    --------
    >>> run = confirm(0.1, 0.004, "x")  # lighter than the bound 0.005045: diverges
    >>> run["stable"], run["predicted_stable"]
    (False, False)
    """
    scale = _scale(ratio, direction)
    rho = spectral_radius(K, scale, direction, setting=setting)
    steps = int(np.clip(decades * np.log(10) / max(abs(np.log(rho)), 1e-12), 200, 3_000))
    loop, _ = loop_at_target(K, scale, direction, setting=setting)
    q0 = sc.quaternion_from_axis_angle([1.0, 1.0, 0.0], tilt_deg)
    X0 = initial_state(loop, plant=q0) if K is None else initial_state(
        loop, plant=q0, nominal=q0[1:3])
    T = np.arange(steps + 1) * setting.Ts
    start = float(np.hypot(*q0[1:3]))
    try:
        with np.errstate(all="ignore"):
            resp = simulate(loop, T, X0=X0, U=0.0, engine=engine)
        h = np.hypot(*(resp.outputs[list(resp.output_labels).index(s)] for s in ("h[0]",
                                                                                  "h[1]")))
        growth = float(np.max(h[-max(1, steps // 10):]) / start)
    except (ArithmeticError, ValueError):  # diverged: the blocks refuse what they get
        growth = np.inf
    diverged = not np.isfinite(growth)
    return {"scale": float(scale), "ratio": float(ratio), "stable": bool(growth < 1.0),
            "predicted_stable": bool(rho < 1.0), "growth": None if diverged else growth,
            "diverged": diverged, "horizon_s": float(T[-1])}


def confirmations(K, bounds, direction="delta_J", *, setting=PAPER, engine="fast") -> dict:
    """:func:`confirm` just inside and just outside each bound of :func:`tolerated`
    (:data:`CONFIRM_MARGIN` apart in ``J_t / J_m``); outside points beyond the physical
    limit are not simulated.

    Examples
    --------
    >>> checks = confirmations(0.1, {"low_ratio": 0.0050448, "high_ratio": None}, "x")
    >>> checks["low"]["inside"]["stable"], checks["low"]["outside"]["stable"]
    (True, False)
    """
    out = {}
    floor = _ratio(physical_limit(direction), direction)
    for side, toward in (("low", 1.0), ("high", -1.0)):
        ratio = bounds.get(f"{side}_ratio")
        if ratio is None:
            continue
        inside = ratio * (1 + toward * CONFIRM_MARGIN)
        outside = ratio * (1 - toward * CONFIRM_MARGIN)
        out[side] = {"inside": confirm(K, inside, direction, setting=setting, engine=engine)}
        if outside > floor:
            out[side]["outside"] = confirm(K, outside, direction, setting=setting,
                                           engine=engine)
    return out


def loops(K_frit=None, *, setting=PAPER) -> dict:
    """The compared loops: label -> gain (None: without MEC).

    Examples
    --------
    >>> list(loops())
    ['without MEC', 'MEC, K = 0.1 I']
    """
    out = {"without MEC": None, f"MEC, K = {setting.K_fixed:g} I": setting.K_fixed}
    if K_frit is not None:
        out["MEC, K from FRIT"] = np.asarray(K_frit, dtype=float).reshape(2, 2)
    return out


def transfers(K=None, scale=1.0, at="u", *, setting=PAPER):
    """:class:`~controlkit.analysis.loops.LoopTransfers` at the plant input ``at`` of the
    loop with gain ``K`` at the target, :func:`~controlkit.analysis.reduced` (the modes the
    wiring decouples dropped).

    Examples
    --------
    >>> transfers(0.1, at="u[0]").L.state_labels
    ['plant_q[1]', 'nominal_hn[0]']
    """
    loop, x = loop_at_target(K, scale, setting=setting)
    return LoopTransfers(*(reduced(G) for G in loop_transfers(loop, at, x)))


def sensitivity_band(K, K_reference=None, *, scale=1.0, setting=PAPER) -> list:
    """The frequency intervals (rad/s) where the loop with gain ``K`` has a smaller input
    sensitivity ``sigma_max(S)`` than the loop with ``K_reference`` (None: without MEC),
    each edge refined by bisection; ``sigma_max`` is the largest singular value at the
    plant input ``u`` (both wheels).

    Examples
    --------
    >>> [round(w, 2) for w in sensitivity_band(0.1)[0]]  # cos(w Ts) = 1 - K Ts / 2
    [0.0, 1.0]
    """
    S = transfers(K, scale, setting=setting).S
    S_ref = transfers(K_reference, scale, setting=setting).S
    omega = setting.omega

    def below(w):
        return bool(gain(S, w) < gain(S_ref, w))

    flags = gain(S, omega) < gain(S_ref, omega)
    intervals, start = [], 0.0 if flags[0] else None
    for i in range(1, len(omega)):
        if flags[i] != flags[i - 1]:
            lo, hi = omega[i - 1], omega[i]
            for _ in range(30):
                mid = np.sqrt(lo * hi)
                lo, hi = (mid, hi) if below(mid) == flags[i - 1] else (lo, mid)
            edge = float(np.sqrt(lo * hi))
            if flags[i]:
                start = edge
            else:
                intervals.append((start, edge))
    if flags[-1]:
        intervals.append((start, float(omega[-1])))
    return intervals


def margins(L, omega=None) -> dict:
    """The gain and phase margins of a discrete SISO loop gain: python-control's
    :func:`~control.stability_margins` on its frequency response below the Nyquist
    frequency (a :func:`control.frd` on ``omega``), and the Nyquist frequency itself.

    The Nyquist plot of a sampled loop ends on the real axis at ``w = pi / Ts``
    (``z = -1``). The loops here cross the negative real axis exactly there, where the
    sign of the imaginary part python-control tests for a crossing is rounding noise:
    when ``L(-1) < 0``, ``-1 / L(-1)`` is a gain margin too, and the one nearer 1 is
    reported.

    Examples
    --------
    >>> m = margins(transfers(0.1, at="u[0]").L)  # 4 / (g (2 Ts (F + K) - Ts^2 K F))
    >>> round(m["gain_margin"], 1), round(m["phase_crossover_rad_s"], 2)
    (199.2, 31.42)
    """
    nyquist = np.pi / L.dt
    # python-control interpolates between the points: 30 a decade find the crossings
    omega = Setting(Ts=L.dt).frequencies(230) if omega is None else np.asarray(omega, float)
    gm, pm, _, wpc, wgc, _ = ct.stability_margins(ct.frd(L, omega[omega < nyquist]))
    end = complex(frequency_response(L, [nyquist])[0, 0, 0]).real
    if end < 0 and (not np.isfinite(gm) or abs(np.log(-1 / end)) < abs(np.log(gm))):
        gm, wpc = -1.0 / end, nyquist
    return {"gain_margin": _finite_or_none(gm), "phase_margin_deg": _finite_or_none(pm),
            "phase_crossover_rad_s": _finite_or_none(wpc),
            "gain_crossover_rad_s": _finite_or_none(wgc)}


def _finite_or_none(value):
    value = float(value)
    return value if np.isfinite(value) else None


def report(K_frit=None, *, setting=PAPER, engine="fast", directions=tuple(DIRECTIONS),
           confirm_bounds=True) -> dict:
    """Every number of this module for the loops of :func:`loops`, JSON-ready.

    Examples
    --------
    >>> r = report(directions=("x",), confirm_bounds=False)
    >>> r["loops"]["MEC, K = 0.1 I"]["tolerated"]["x"]["low"] < -198
    True
    """
    out = {"operating_point": "target attitude q = [1, 0, 0, 0], wheels at rest, no "
                              "momentum (H0 = 0); r = 0",
           "Ts_s": setting.Ts, "F_per_s": np.asarray(setting.F, dtype=float).tolist(),
           "scale": "J_t = J_m + s Delta J on the direction's axes (Table 2: s = 1); ratio "
                    "= J_t / J_m of the reference axis (x along Delta J)",
           "loops": {}, "sensitivity_band_rad_s": {}}
    for label, K in loops(K_frit, setting=setting).items():
        entry = {"K": None if K is None else np.asarray(K, float).reshape(-1).tolist()
                 if np.ndim(K) else [K, 0.0, 0.0, K], "tolerated": {}, "confirmed": {}}
        for direction in directions:
            bounds = tolerated(K, direction, setting=setting)
            entry["tolerated"][direction] = bounds
            if confirm_bounds:
                entry["confirmed"][direction] = confirmations(K, bounds, direction,
                                                              setting=setting, engine=engine)
        # each wheel's loop cut alone, the other closed
        entry["margins_at_u"] = {s: margins(transfers(K, at=s, setting=setting).L)
                                 for s in ("u[0]", "u[1]")}
        out["loops"][label] = entry
        if K is not None:
            out["sensitivity_band_rad_s"][label] = [
                list(b) for b in sensitivity_band(K, setting=setting)]
    return out
