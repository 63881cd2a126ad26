"""The thesis's CMG experiment (section 6) and a friction case beyond its assumption."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ... import _checks
from ...blocks import cmg
from ...blocks.sampling import time_grid
from ...simulation import initial_state, simulate
from .diagrams import cmg_loop

#: Horizon of the thesis's Fig. 3-6 (s).
HORIZON = 12.0
#: Initial state ``[q1, q2, q4, w1, w2, w4]`` (section 6).
X0_THESIS = np.array([0.0, np.pi / 18, 0.0, 0.0, 0.0, 0.0])
#: Change of gimbal 4's inertia in the true plant (eq. 47), kg m^2.
DELTA_IG4X = 0.005

#: Friction of the ``thesis`` case: the apparatus's reported viscous values (mid-range),
#: rotor Coulomb 0.03 N m, gimbal-2 Coulomb 0.01 N m (low end of 0.01-0.05) and an assumed
#: 0.01 N m on the frame (no value is reported). The remainders then satisfy the thesis's
#: ``|D1| <= c2 / (IG2x + IR1x) = 0.42 < eta1 = 1`` and ``|D2| <= (c1 + c4) / D <= 0.31 < eta2``.
FRICTION_THESIS = cmg.Friction(b1=1.8e-4, b2=5.4e-3, b4=0.0, c1=0.03, c2=0.01, c4=0.01)
#: Gimbal-2 Coulomb friction 0.05 N m (high end reported): ``|D1|`` up to 2.1 > ``eta1 = 1``.
FRICTION_STRONG = cmg.Friction(b1=1.8e-4, b2=5.4e-3, b4=0.0, c1=0.03, c2=0.05, c4=0.01)


@dataclass(frozen=True)
class CmgCase:
    """One CMG run: the true plant's friction and inertia change.

    Attributes
    ----------
    name, label : str
        Identifier and legend text.
    friction : Friction
        True friction of the plant.
    delta_IG4x : float
        True change of gimbal 4's inertia.

    Examples
    --------
    >>> CASES["strong_friction"].friction.c2
    0.05
    """

    name: str
    label: str
    friction: cmg.Friction
    delta_IG4x: float = DELTA_IG4X


CASES: dict[str, CmgCase] = {
    "thesis": CmgCase("thesis", "Thesis experiment (|D_i| < eta_i)", FRICTION_THESIS),
    "strong_friction": CmgCase("strong_friction", "Gimbal-2 Coulomb friction beyond eta1",
                               FRICTION_STRONG),
}
DEFAULT_CASES = ("thesis",)
#: Keywords :func:`run` passes on to the controller (``**gains``, eq. 47's gains).
RUN_KEYWORDS = tuple(cmg.GAINS_THESIS)


def true_plant(case="thesis", *, friction_scale=1.0, inertia_scale=1.0, name="cmg"):
    """The gyroscope the controller faces in one case, optionally further from the model.

    Parameters
    ----------
    case : str
        A key of :data:`CASES` (its friction and ``delta IG4x``).
    friction_scale : float
        Factor on every friction coefficient of the case (>= 0; 1: as published).
    inertia_scale : float
        Factor on the seven inertias of the true plant (> 0); the controller keeps the
        nominal ones, so this is an inertia model error.
    name : str
        System name.

    Examples
    --------
    >>> true_plant(inertia_scale=1.1).name
    'cmg'
    """
    if case not in CASES:
        raise ValueError(f"case must be one of {sorted(CASES)}, got {case!r}")
    c = CASES[case]
    f = _checks.positive_scalar("friction_scale", friction_scale, allow_zero=True)
    s = _checks.positive_scalar("inertia_scale", inertia_scale)
    friction = dataclasses.replace(c.friction, **{k: f * getattr(c.friction, k) for k in
                                                  ("b1", "b2", "b4", "c1", "c2", "c4")})
    nominal = cmg.Inertias()
    inertias = dataclasses.replace(nominal, **{field.name: s * getattr(nominal, field.name)
                                               for field in dataclasses.fields(nominal)})
    return cmg.cmg_plant(inertias, delta_IG4x=c.delta_IG4x, friction=friction, name=name)


def build_loop(case="thesis", *, Ts=cmg.TS_CMG, boundary_layer=0.0, plant_options=None,
               **gains):
    """The closed loop of one case (true plant with friction and ``delta IG4x``).

    ``plant_options`` are keywords of :func:`true_plant` (``friction_scale``,
    ``inertia_scale``); the controller keeps the nominal model.

    Examples
    --------
    >>> build_loop("thesis").name
    'thesis'
    """
    if case not in CASES:
        raise ValueError(f"case must be one of {sorted(CASES)}, got {case!r}")
    c = CASES[case]
    if plant_options is not None and not isinstance(plant_options, dict):
        raise ValueError(f"plant_options must be a dict of keyword -> value, got "
                         f"{plant_options!r}")
    unknown = sorted(set(plant_options or {}) - {"friction_scale", "inertia_scale"})
    if unknown:
        raise ValueError(f"plant_options has unknown keys {unknown}; allowed: "
                         "['friction_scale', 'inertia_scale']")
    plant = true_plant(case, **(plant_options or {}))
    controller = cmg.adaptive_smc(Ts=Ts, boundary_layer=boundary_layer, **gains)
    return cmg_loop(plant, controller, Ts=Ts, name=c.name)


def run(case="thesis", *, horizon=HORIZON, Ts=cmg.TS_CMG, x0=None, boundary_layer=0.0,
        plant_options=None, progress=None, engine="fast", compile=None, **gains):
    """Simulate one case from the thesis's initial state.

    Parameters
    ----------
    case : str
        A key of :data:`CASES`.
    horizon : float
        Simulated time (s), default 12.
    Ts : float
        Controller and hold period (s), default 1 ms.
    x0 : array_like, optional
        Initial ``[q1, q2, q4, w1, w2, w4]``; ``q2`` must lie in ``(0, pi/2)``.
    boundary_layer : float
        Switching function: 0 for ``sgn``, ``phi > 0`` for ``sat(s/phi)``.
    plant_options : dict, optional
        Keywords of :func:`true_plant` (``friction_scale``, ``inertia_scale``).
    progress : callable, optional
        Called with the fraction done.
    engine : {"fast", "python-control"}
        Simulator (see :func:`controlkit.simulation.simulate`).
    compile : bool or None
        On the fast engine, as for :func:`controlkit.input_output_response`.
    **gains : float
        Controller gains overriding eq. (47).

    Returns
    -------
    control.TimeResponseData

    Examples
    --------
    >>> run(horizon=0.01).outputs.shape
    (16, 11)
    """
    x0 = X0_THESIS if x0 is None else np.asarray(x0, dtype=float)
    if x0.shape != (6,) or not np.all(np.isfinite(x0)):
        raise ValueError(f"x0 must be 6 finite values [q1, q2, q4, w1, w2, w4], got {x0!r}")
    if not 0.0 < x0[1] < np.pi / 2:
        raise ValueError(f"x0: q2 must lie in (0, pi/2) (the controller divides by sin q2), "
                         f"got q2 = {x0[1]:.6g} rad")
    loop = build_loop(case, Ts=Ts, boundary_layer=boundary_layer, plant_options=plant_options,
                      **gains)
    T = time_grid(horizon, Ts)
    return simulate(loop, T, X0=initial_state(loop, cmg=x0), progress=progress,
                    chunks=10 if len(T) > 5000 else 1, engine=engine, compile=compile)
