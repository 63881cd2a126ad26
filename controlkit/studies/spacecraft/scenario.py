"""The spacecraft paper's scenario (Tables 2-3) and its cases.

Each case is one entry of :data:`CASES`: how the true plant differs from the
controller's model and which compensator closes the loop. :func:`build_loop`
turns a case into a diagram; :func:`run` simulates it and returns
``control.TimeResponseData``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import _checks
from ...blocks import frit, mec
from ...blocks import spacecraft as sc
from ...blocks.sampling import time_grid
from ...simulation import initial_state, simulate
from . import diagrams

#: Horizon of the paper's figures (not printed in the paper: two periods of H0), s.
HORIZON = 20_000.0


@dataclass(frozen=True)
class SpacecraftCase:
    """One curve of the paper's Fig. 5-10.

    Attributes
    ----------
    name : str
        Identifier used on the command line and in file names.
    label : str
        Legend text.
    color : str
        Line colour (the paper: blue ideal, green without MEC, red proposed).
    model_error : bool
        True plant with ``J_t = J_m + Delta J`` and the true ``H0(t)`` (Table 2);
        otherwise the plant equals the controller's model.
    compensator : str
        ``"none"`` (Fig. 2 loop), ``"fixed"`` (Fig. 3, constant ``K``) or
        ``"frit"`` (Fig. 4, on-line FRIT tuning of ``K``).
    tuner_options : dict, optional
        Keywords of :func:`~controlkit.blocks.frit.frit_tuner` that define the case.

    Examples
    --------
    >>> CASES["proposed"].color, CASES["proposed"].compensator
    ('tab:red', 'frit')
    """

    name: str
    label: str
    color: str
    model_error: bool
    compensator: str
    tuner_options: dict | None = None


CASES: dict[str, SpacecraftCase] = {
    "ideal": SpacecraftCase("ideal", "Ideal (no model error)", "tab:blue", False, "none"),
    "without_mec": SpacecraftCase("without_mec", "w/o MEC", "tab:green", True, "none"),
    "proposed": SpacecraftCase("proposed", "Proposed (MEC + FRIT)", "tab:red", True, "frit"),
    "mec_fixed": SpacecraftCase("mec_fixed", "MEC, fixed K", "tab:purple", True, "fixed"),
    # Table 3's P(0) and psi read in the units of h = [q1, q2] instead of degrees (decision D1)
    "proposed_literal": SpacecraftCase(
        "proposed_literal", "Proposed, Table 3 in units of q", "tab:orange", True, "frit",
        {"units": "q"}),
    # beyond the paper: the safeguarded tuner (normalised RLS, bounded covariance, dead
    # zone, stable-gain projection; docs/theory/frit.md)
    "safeguarded": SpacecraftCase(
        "safeguarded", "MEC + safeguarded FRIT", "tab:blue", True, "frit",
        {"safeguard": True}),
}
#: Cases run by ``controlkit reproduce spacecraft`` when none is named.
DEFAULT_CASES = ("ideal", "without_mec", "proposed")
#: Constant gain of the ``mec_fixed`` case.
K_FIXED = 0.1


def initial_attitude() -> np.ndarray:
    """Initial attitude of Table 2: 30 degrees about ``[1, 2, 3]`` (normalised).

    Examples
    --------
    >>> initial_attitude().round(4).tolist()
    [0.9659, 0.0692, 0.1383, 0.2075]
    """
    return sc.quaternion_from_axis_angle([1.0, 2.0, 3.0], 30.0)


def requirement_time(F=sc.F_PAPER, Ts=sc.TS_PAPER) -> float:
    r"""When the ideal loop's pointing error first falls under the requirement, in s.

    With the exact model the loop is linear, ``h[k] = (1 - F Ts)^k h[0]`` (eq. 10-12),
    and for small angles the pointing error ``e`` is proportional to ``|h|``, so it
    falls from ``e0`` (Table 2's attitude) under ``e_req = 0.05`` deg after

    .. math:: t^* = T_s \, \frac{\ln(e_0 / e_{req})}{-\ln(1 - F T_s)}
              \approx \frac{\ln(e_0 / e_{req})}{F}.

    No loop with the paper's ``F`` gets there sooner: the compensators recover the
    ideal response, they do not speed it up.

    Examples
    --------
    >>> round(requirement_time())
    6527
    """
    e0 = float(sc.pointing_error_deg(initial_attitude()[:, np.newaxis])[0])
    return Ts * np.log(e0 / sc.POINTING_REQUIREMENT_DEG) / -np.log1p(-F * Ts)


def claim_horizon(F=sc.F_PAPER, Ts=sc.TS_PAPER) -> float:
    """The shortest horizon that can show the paper's claim: ``2 t*``, to the next 1000 s.

    The requirement is judged over the last half of a run (``metrics``), so the run must
    last twice :func:`requirement_time`.

    Examples
    --------
    >>> claim_horizon()
    14000.0
    """
    return float(1000.0 * np.ceil(2 * requirement_time(F, Ts) / 1000.0))


def horizon_note(horizon) -> str | None:
    """What a run of ``horizon`` seconds cannot show of the paper's claim, or None.

    Examples
    --------
    >>> horizon_note(20000.0) is None
    True
    >>> horizon_note(2000.0).startswith("at 2000 s the paper's claim cannot show")
    True
    """
    shortest = claim_horizon()
    if horizon >= shortest:
        return None
    return (f"at {horizon:g} s the paper's claim cannot show: the requirement "
            f"({sc.POINTING_REQUIREMENT_DEG:g} deg) is judged over the last half of a run, "
            f"and even the ideal loop needs {requirement_time():.0f} s to get under it "
            f"(h decays as (1 - F Ts)^k, F = {sc.F_PAPER:g} 1/s); --horizon {shortest:g} is "
            f"the shortest run that shows it (the published {HORIZON:g} s take seconds)")


def true_plant(model_error: bool, *, inertia_error_scale=1.0, momentum_scale=1.0,
               name="plant"):
    """The plant the controller faces.

    Without model error it is the nominal model (``J_b = J_bn``, ``H0 = 0``);
    with it, ``J_b = J_bn + Delta J`` (so that ``J_t = J_m + Delta J``, eq. 31 and
    erratum E4) and ``H0(t)`` of Table 2.

    Parameters
    ----------
    model_error : bool
        Whether the plant differs from the controller's model.
    inertia_error_scale : float or array_like of 3
        Factors on the diagonal entries of ``Delta J`` (Table 2's values at 1), each
        >= 0; used with ``model_error``. The robustness sweeps draw them.
    momentum_scale : float
        Factor on the amplitude of ``H0(t)`` (Table 2's at 1), >= 0; used with
        ``model_error``.
    name : str
        System name.

    Examples
    --------
    >>> float(true_plant(True).J_t[0, 0])
    4020.678
    >>> round(float(true_plant(True, inertia_error_scale=[0, 1, 1]).J_t[0, 0]), 6)  # none on x
    4000.675
    """
    scale = np.broadcast_to(np.asarray(inertia_error_scale, dtype=float), (3,)) \
        if np.ndim(inertia_error_scale) == 0 else np.asarray(inertia_error_scale, dtype=float)
    if scale.shape != (3,) or not np.all(np.isfinite(scale)) or np.any(scale < 0):
        raise ValueError("inertia_error_scale must be one factor or three, each finite and "
                         f">= 0, got {inertia_error_scale!r}")
    momentum_scale = _checks.positive_scalar("momentum_scale", momentum_scale, allow_zero=True)
    if model_error:
        H0 = sc.paper_momentum
        H0 = sc.MomentumProfile(constant=tuple(momentum_scale * np.asarray(H0.constant)),
                                sine=tuple(momentum_scale * np.asarray(H0.sine)),
                                cosine=tuple(momentum_scale * np.asarray(H0.cosine)),
                                omega=H0.omega)
        return sc.spacecraft_plant(J_b=sc.J_BN + sc.DELTA_J * scale, H0=H0, name=name)
    return sc.spacecraft_plant(name=name)


#: Keywords of :func:`~controlkit.blocks.frit.frit_tuner` that ``tuner_options`` may set
#: (``F``, ``Ts`` and ``h0`` come from the loop).
TUNER_OPTIONS = tuple(name for name in __import__("inspect").signature(
    frit.frit_tuner).parameters if name not in ("F", "Ts", "h0", "name"))
#: Keywords of :func:`true_plant` that ``plant_options`` may set.
PLANT_OPTIONS = ("inertia_error_scale", "momentum_scale")


def _options(name, options) -> dict:
    if options is not None and not isinstance(options, dict):
        raise ValueError(f"{name} must be a dict of keyword -> value, got {options!r}")
    return dict(options or {})


def _plant_options(options) -> dict:
    options = _options("plant_options", options)
    unknown = sorted(set(options) - set(PLANT_OPTIONS))
    if unknown:
        raise ValueError(f"plant_options has unknown keys {unknown}; allowed: "
                         f"{list(PLANT_OPTIONS)}")
    return options


def _case(case) -> SpacecraftCase:
    if isinstance(case, SpacecraftCase):
        return case
    if case not in CASES:
        raise ValueError(f"case must be one of {sorted(CASES)}, got {case!r}")
    return CASES[case]


def build_loop(case="ideal", *, Ts=sc.TS_PAPER, F=sc.F_PAPER, K=K_FIXED, h0=None,
               tuner_options=None, plant_options=None):
    """The closed loop of one case, sampled at ``Ts``.

    Parameters
    ----------
    case : str or SpacecraftCase
        A key of :data:`CASES`.
    Ts : float
        Sampling period (s).
    F : float or array_like
        Outer-loop gain ``diag(F1, F2)``.
    K : float or array_like
        Gain of the ``"fixed"`` compensator (default ``0.1 I``).
    h0 : array_like, optional
        Initial output: where the ideal model starts (``hn(0) = h(0)``) and the
        FRIT tuner's filters rest; default that of Table 2.
    tuner_options : dict, optional
        Keywords for :func:`~controlkit.blocks.frit.frit_tuner` (``lambda_``,
        ``gamma``, ``kappa``, ``psi``, ``K0``) in the ``"frit"`` case.

    plant_options : dict, optional
        Keywords of :func:`true_plant` (``inertia_error_scale``, ``momentum_scale``):
        how far the true plant is from the model (Table 2's at their defaults).

    Returns
    -------
    control.InterconnectedSystem
        With outputs ``h[0], h[1], u[0], u[1], q[0]..q[3]`` among others.

    Examples
    --------
    >>> build_loop("without_mec").name
    'without_mec'
    """
    case = _case(case)
    plant = true_plant(case.model_error, **_plant_options(plant_options))
    if case.compensator == "none":
        return diagrams.output_zeroing_loop(
            plant, sc.io_linearizer(), sc.outer_controller(F), Ts=Ts, name=case.name
        )
    h0 = initial_attitude()[1:3] if h0 is None else h0
    if case.compensator == "fixed":
        gain = mec.constant_gain(K)
    else:
        options = {**(case.tuner_options or {}), **_options("tuner_options", tuner_options)}
        unknown = sorted(set(options) - set(TUNER_OPTIONS))
        if unknown:
            raise ValueError(f"tuner_options has unknown keys {unknown}; allowed: "
                             f"{list(TUNER_OPTIONS)}")
        gain = frit.frit_tuner(F, Ts, h0=h0, **options)
    return diagrams.mec_loop(plant, sc.io_linearizer(), sc.outer_controller(F, output="mu_n"),
                             K=gain, nominal=mec.nominal_model(Ts, h0=h0), Ts=Ts,
                             name=case.name)


def options_read(case) -> set[str]:
    """The keywords of :func:`run` that ``case`` reads; it runs the same without the others
    (``K`` is the fixed compensator's gain, ``tuner_options`` the FRIT tuner's, and a plant
    without model error has no ``plant_options`` to apply).

    Examples
    --------
    >>> sorted(options_read("ideal"))
    ['F', 'Ts', 'q_initial']
    >>> "K" in options_read("mec_fixed"), "tuner_options" in options_read("proposed")
    (True, True)
    """
    c = _case(case)
    read = {"F", "Ts", "q_initial"}
    if c.model_error:
        read.add("plant_options")
    if c.compensator == "fixed":
        read.add("K")
    if c.compensator == "frit":
        read.add("tuner_options")
    return read


def run(case="ideal", *, horizon=HORIZON, Ts=sc.TS_PAPER, F=sc.F_PAPER, K=K_FIXED,
        q_initial=None, tuner_options=None, plant_options=None, progress=None, engine="fast",
        record_every=1, on_chunk=None, compile=None):
    """Simulate one case from the initial attitude of Table 2.

    Parameters
    ----------
    case : str or SpacecraftCase
        A key of :data:`CASES`.
    horizon : float
        Simulated time (s), a multiple of ``Ts``. Default 20 000 s.
    Ts : float
        Sampling period (s).
    F : float or array_like
        Outer-loop gain.
    K : float or array_like
        Gain of the ``mec_fixed`` case.
    q_initial : array_like, optional
        Initial unit quaternion; default :func:`initial_attitude`.
    tuner_options : dict, optional
        Keywords for the FRIT tuner (``proposed`` case).
    plant_options : dict, optional
        Keywords of :func:`true_plant` (model error of the true plant).
    progress : callable, optional
        Called with the fraction done.
    engine : {"fast", "python-control"}
        Simulator (see :func:`controlkit.simulation.simulate`); both give the
        same numbers.
    record_every, on_chunk
        Decimated recording and full-resolution streaming of long runs, as in
        :func:`controlkit.simulation.simulate`.
    compile : bool or None
        On the fast engine, as for :func:`controlkit.input_output_response` (default:
        compiled when the run is long enough to pay for it).

    Returns
    -------
    control.TimeResponseData
        Outputs labelled as in :func:`build_loop`.

    Examples
    --------
    >>> resp = run("ideal", horizon=1.0)
    >>> resp.outputs.shape
    (10, 11)
    """
    if q_initial is None:
        q0 = initial_attitude()
    else:
        q0 = _checks.unit_quaternion("q_initial", q_initial)
    h0 = q0[1:3]
    loop = build_loop(case, Ts=Ts, F=F, K=K, h0=h0, tuner_options=tuner_options,
                      plant_options=plant_options)
    X0 = initial_state(loop, plant=q0)  # the ideal model and the tuner start from h0 already
    # a streamed run on the fast engine makes its time samples chunk by chunk
    T = time_grid(horizon, Ts, lazy=engine == "fast" and (record_every != 1 or
                                                          on_chunk is not None))
    return simulate(loop, T, X0=X0, U=0.0, progress=progress, chunks=20 if len(T) > 20_000 else 1,
                    engine=engine, record_every=record_every, on_chunk=on_chunk,
                    compile=compile)
