"""The on-line FRIT tuner of the MEC gain (spacecraft paper, eq. 17-30, Fig. 4).

Fictitious reference iterative tuning (FRIT) estimates the MEC gain ``K`` from the
loop's own signals by recursive least squares, row by row; the tuner is a block of
its own that drives the compensator's gain input, so Fig. 3 becomes Fig. 4 by
swapping one block (:func:`controlkit.blocks.mec.constant_gain` for
:func:`frit_tuner`). Errata E1-E3 of the project spec apply (see each docstring).
"""

from __future__ import annotations

import control as ct
import numpy as np

from .. import _checks
from ..kernels import mec as kernels
from ..kernels.mec import TUNER, TUNER_INPUTS, TUNER_STATE
from .contract import KernelBlock, drawn_as
from .mec import K_SIGNALS
from .spacecraft import F_PAPER, TS_PAPER

#: Table 3: forgetting factor, P(0) = gamma I, low-pass coefficient, threshold.
LAMBDA_PAPER = 0.995
GAMMA_PAPER = 100.0
KAPPA_PAPER = 0.45
PSI_PAPER = 0.00012

#: Names of the tuner's 24 states, in order (declared by :data:`TUNER_STATE`):
#: ``Mxi1``, ``Mxi2`` (``M_j (hn - h)``, the regressors of rows 1 and 2), ``Mmu``
#: (``M_j mu_j``), ``Mh`` (``M_j h_j``), ``Khat`` (RLS estimate), ``P1``, ``P2``
#: (covariances), ``K`` (implemented, low-passed gain), matrices row-major.
TUNER_STATES = TUNER_STATE.labels()


def frit_regressors(x, h, F):
    """Regressors of the row-wise FRIT least squares at the current step.

    ``xi_j = M_j (hn - h)`` (eq. 24 with erratum E2) and
    ``eta = M mu - F (h - M h)`` (eq. 20; erratum E1: eq. 25 prints ``+``).

    Parameters
    ----------
    x : array_like
        Tuner state (:data:`TUNER_STATES` layout).
    h : array_like
        Current actual output.
    F : array_like
        ``(F1, F2)``.

    Returns
    -------
    xi : ndarray (2, 2)
        Row ``j`` is the regressor of row ``j`` of ``K``.
    eta : ndarray (2,)

    Examples
    --------
    >>> x = np.zeros(24); x[TUNER_STATE.slice("Mh")] = [0.1, 0.2]
    >>> frit_regressors(x, [0.1, 0.2], [1.0, 1.0])[1].tolist()
    [0.0, 0.0]
    """
    x = _checks.vector("x", x, TUNER_STATE.size)
    h, F = _checks.vector("h", h, 2), _checks.vector("F", F, 2)
    state = TUNER_STATE.unpack(x)
    xi = np.array([state["Mxi1"], state["Mxi2"]])
    eta = np.array([kernels.frit_eta(x, F[j], h[j], j) for j in range(2)])
    return xi, eta


def rls_step(Khat, P1, P2, xi, eta, lambda_):
    """One step of recursive least squares with forgetting (eq. 27-28), both rows of K.

    For each row ``j`` with regressor ``xi`` (shared, as with ``F1 = F2``):
    ``Khat_j += (eta_j - Khat_j xi) (P_j xi)^T / (lambda + xi^T P_j xi)`` and
    ``P_j = (P_j - P_j xi xi^T P_j / (lambda + xi^T P_j xi)) / lambda``.
    Runs the tuner's own kernel on a state holding these regressors, so it is
    the very arithmetic of :func:`frit_tuner`.

    Returns
    -------
    Khat, P1, P2 : ndarray

    Examples
    --------
    >>> K, P1, _ = rls_step(np.zeros((2, 2)), 100 * np.eye(2), 100 * np.eye(2),
    ...                     np.array([1.0, 0]), np.array([2.0, 0.0]), 1.0)
    >>> K[0].round(6).tolist(), P1.round(6).tolist()
    ([1.980198, 0.0], [[0.990099, 0.0], [0.0, 100.0]])
    """
    # with M h = h = 0, eta = M mu; hn - h = 1 > psi = 0 updates both rows
    x = TUNER_STATE.pack(Mxi1=xi, Mxi2=xi, Mmu=eta, Mh=np.zeros(2), Khat=Khat, P1=P1, P2=P2,
                         K=np.zeros(4))
    p = TUNER.pack(F=[1.0, 1.0], a=[0.0, 0.0], lambda_=lambda_, kappa=1.0, psi=[0.0, 0.0],
                   feedthrough=0.0, joint=0.0, **_safeguard_params(None, 1.0))
    u = TUNER_INPUTS.pack(mu=[0.0, 0.0], h=[0.0, 0.0], hn=[1.0, 1.0])
    xn = TUNER_STATE.unpack(kernels.tuner_update(0.0, x, u, p, np.empty(TUNER_STATE.size)))
    return xn["Khat"].reshape(2, 2), xn["P1"].reshape(2, 2), xn["P2"].reshape(2, 2)


#: ``output_scale`` that reads ``h`` in degrees: for small angles the rotation about body
#: x is ``2 q1`` rad, i.e. ``(360 / pi) q1`` degrees.
DEGREES_PER_QUATERNION_UNIT = 360.0 / np.pi
#: Units in which controlkit reads Table 3's ``P(0)`` and ``psi``: ``h`` in degrees (decision
#: D1 in ``docs/theory/errata.md``; the paper does not state them).
TABLE3_OUTPUT_SCALE = DEGREES_PER_QUATERNION_UNIT
#: The two readings of Table 3's units (``units=`` of :func:`frit_tuner`): the scale
#: that turns ``h = [q1, q2]`` into the units in which ``gamma`` and ``psi`` are read.
UNIT_SCALES = {"q": 1.0, "deg": DEGREES_PER_QUATERNION_UNIT}
#: The details of the tuner the paper leaves open, each with its readings (the first
#: is controlkit's default); see the "Sensitivity" section of ``docs/theory/frit.md``.
READINGS = {
    "filter": ("zoh", "feedthrough"),
    "start": ("rest", "zero"),
    "freeze": ("row", "joint"),
    "units": ("deg", "q"),
}


#: Settings of the safeguarded tuner (``safeguard=True``); see ``docs/theory/frit.md``.
#: ``p_min``, ``p_max``: bounds on the eigenvalues of each covariance ``P_j`` (the
#: regressors are normalised, so these are in (1/s)^2 whatever the units of ``h``);
#: ``deadzone``: no update while the normalised prediction error is at most this (1/s);
#: it replaces the paper's threshold ``psi``, whose units the paper leaves open;
#: ``rho``: the gain is kept in ``|| I - Ts K ||_2 <= rho`` (a stable error loop).
SAFEGUARD_DEFAULTS = {"p_min": 1e-4, "p_max": 1.0, "deadzone": 0.01, "rho": 0.98}


def _safeguard_params(safeguard, Ts) -> dict:
    """The safeguard's entries of the :data:`TUNER` layout (flag 0 for the paper's tuner)."""
    if safeguard is None or safeguard is False:
        return {"safeguard": 0.0, "Ts": Ts, **SAFEGUARD_DEFAULTS}
    if safeguard is True:
        settings = dict(SAFEGUARD_DEFAULTS)
    elif isinstance(safeguard, dict):
        unknown = sorted(set(safeguard) - set(SAFEGUARD_DEFAULTS))
        if unknown:
            raise ValueError(f"safeguard has unknown keys {unknown}; allowed: "
                             f"{list(SAFEGUARD_DEFAULTS)}")
        settings = {**SAFEGUARD_DEFAULTS, **safeguard}
    else:
        raise ValueError(f"safeguard must be None, False, True or a dict of "
                         f"{list(SAFEGUARD_DEFAULTS)}, got {safeguard!r}")
    settings["p_max"] = _checks.positive_scalar("safeguard p_max", settings["p_max"])
    settings["p_min"] = _checks.in_interval("safeguard p_min", settings["p_min"], 0.0,
                                            settings["p_max"])
    settings["deadzone"] = _checks.positive_scalar("safeguard deadzone", settings["deadzone"],
                                                   allow_zero=True)
    settings["rho"] = _checks.in_interval("safeguard rho", settings["rho"], 0.0, 1.0)
    if settings["rho"] == 1.0:
        raise ValueError("safeguard rho must be < 1 (rho = 1 admits gains on the stability "
                         "boundary)")
    return {"safeguard": 1.0, "Ts": Ts, **settings}


def _reading(name, value):
    if value not in READINGS[name]:
        raise ValueError(f"{name} must be one of {READINGS[name]}, got {value!r}")
    return value


def frit_tuner(
    F=F_PAPER, Ts=TS_PAPER, *, lambda_=LAMBDA_PAPER, gamma=GAMMA_PAPER, kappa=KAPPA_PAPER,
    psi=None, K0=0.0, h0=(0.0, 0.0), filter="zoh", start="rest", freeze="row",
    units="deg", output_scale=None, safeguard=None, name="tuner",
) -> ct.NonlinearIOSystem:
    """On-line FRIT tuner of the MEC gain ``K`` by recursive least squares (eq. 15-30).

    At each step ``i`` (period ``Ts``), for each row ``j`` of ``K``:

    1. regressors ``xi_j(i) = M_j (hn - h)`` and ``eta(i) = M mu - F (h - M h)``,
       where ``M = diag(F_j / (s + F_j))`` is the ideal closed loop, discretised
       exactly under ZOH (``M_j``: ``m[i+1] = a_j m[i] + (1 - a_j) v[i]``,
       ``a_j = exp(-F_j Ts)``, output ``m[i]``);
    2. unless ``|hn_j - h_j| < psi_j`` (updates of row ``j`` are then frozen),
       RLS with forgetting ``lambda_`` (eq. 27-28) updates ``Khat_j`` and ``P_j``,
       and the implemented gain follows the low-pass law
       ``K_j(i) = (1 - kappa) K_j(i-1) + kappa Khat_j(i)`` (eq. 30).

    The least squares minimises ``sum lambda^(N-i) eps^2`` with
    ``eps = K xi - eta`` (eq. 21-26), which for ``lambda_ = 1`` has the same
    minimiser as the FRIT criterion ``J(K) = sum (h - M r~(K))^2`` (eq. 17),
    since ``h - M r~(K) = F^-1 eps`` row by row.

    Where the printed paper differs: eq. (25) prints ``eta = M mu + F(h - M h)``;
    eq. (20), from which it is derived, and the derivation give ``-`` (E1).
    Eq. (20) writes ``K M (hn - h)``, equal to ``M K (hn - h)`` only when ``M``
    and ``K`` commute; this block uses the exact row-wise form (E2).

    The output is the gain of the previous update (the state), so the MEC and
    the tuner form no algebraic loop: ``K`` acts one sample after the data
    that produced it.

    Parameters
    ----------
    F : float or array_like
        Outer-loop gain ``diag(F1, F2)``, each > 0 (it defines ``M``).
    Ts : float
        Period, must equal the loop's (0.1 s in the paper).
    lambda_ : float
        Forgetting factor in ``(0, 1]``; 1 is ordinary least squares. Default 0.995.
    gamma : float
        ``P_j(0) = gamma I`` (eq. 29), > 0. Default 100.
    kappa : float
        Low-pass coefficient in ``(0, 1]`` (eq. 30); 1 applies ``Khat`` directly.
        Default 0.45.
    psi : float or array_like, optional
        Thresholds ``(psi1, psi2)`` >= 0 on ``|hn_j - h_j|``. Default 0.00012 (Table 3).
        The paper's tuner only: the safeguarded tuner replaces the threshold by its
        dead zone, and refuses ``psi``.
    K0 : float or array_like
        Initial gain ``K(0) = Khat(0)``, scalar or 2x2. Default 0.
    h0 : array_like
        Initial output ``h(0)``, where the ``M h`` filters start with ``start="rest"``.
    filter : {"zoh", "feedthrough"}
        How ``M`` is discretised. The paper writes ``M = F/(s + F)`` in continuous
        time and the RLS in discrete time without saying how one becomes the other.
        ``"zoh"`` (default): exact under zero-order hold, strictly proper:
        ``m[k+1] = a m[k] + (1 - a) v[k]``, step ``k`` uses ``m[k]``.
        ``"feedthrough"``: ``m[k] = a m[k-1] + (1 - a) v[k]``, the current sample
        included (the ``"zoh"`` regressors advanced by one sample).
    start : {"rest", "zero"}
        Initial state of the ``M h`` filters, which the paper does not give.
        ``"rest"`` (default): at ``h(0)``, as if the loop had rested there (then
        ``h - M r~ = 0`` holds from the first step). ``"zero"``: every filter at 0.
    freeze : {"row", "joint"}
        How the threshold of Table 3 applies, stated only as "``|hn - h| < psi``".
        ``"row"`` (default): row ``j`` of ``K`` is frozen while
        ``|hn_j - h_j| < psi_j``. ``"joint"``: both rows are frozen while
        ``|hn_j - h_j| < psi_j`` for both ``j`` (``max |hn - h| < psi`` for equal ``psi``).
    units : {"deg", "q"}
        Units in which Table 3's ``gamma`` and ``psi`` are read; the paper states
        none. ``"deg"`` (default, decision D1): ``h`` in degrees of rotation
        (scale :data:`TABLE3_OUTPUT_SCALE` ``= 360/pi``), the reading that
        reproduces Fig. 7-8. ``"q"``: in the units of ``h = [q1, q2]`` itself (the
        literal reading, whose gain drifts in bursts).
    output_scale : float, optional
        Any other scale ``s`` (overrides ``units``): the tuner behaves as if it
        received ``s h`` (and ``mu``, ``hn`` alike). ``K`` does not depend on
        units, but ``P`` and the threshold do: scaling the data by ``s`` is exactly
        ``P(0) = gamma s^2 I`` and a threshold ``psi / s``.
    safeguard : None, bool or dict
        ``None``/``False`` (default): the paper's tuner. ``True``: the safeguarded tuner
        (beyond the paper; ``docs/theory/frit.md``): each row's regression is
        normalised by ``|xi_j|`` (so ``P`` and ``gamma`` no longer depend on the units of
        ``h``; ``P(0) = min(gamma, p_max) I``), a dead zone on the normalised prediction
        error takes the place of ``psi`` (row ``j`` frozen while the error is at most
        ``deadzone``; ``freeze="joint"``: both rows while both are), so ``units`` and
        ``output_scale`` change nothing, the eigenvalues of ``P_j``
        stay in ``[p_min, p_max]`` (no wind-up, no starving: it re-tunes when the plant
        changes), and ``Khat`` is projected onto ``|| I - Ts K ||_2 <= rho`` so the
        sampled error loop stays stable (``K(0)`` is projected too). A dict overrides
        entries of :data:`SAFEGUARD_DEFAULTS`.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Discrete at ``Ts``. Inputs ``mu[0], mu[1], h[0], h[1], hn[0], hn[1]``;
        outputs ``K[0]..K[3]`` (row-major); 24 states (:data:`TUNER_STATES`);
        attribute ``x0`` (the initial state).

    Examples
    --------
    >>> tuner = frit_tuner()
    >>> tuner.nstates, tuner.output(0.0, tuner.x0, np.zeros(6)).tolist()
    (24, [0.0, 0.0, 0.0, 0.0])
    >>> round(tuner.gamma), tuner.psi.round(8).tolist()  # in units of h = [q1, q2]
    (1313123, [1.05e-06, 1.05e-06])
    >>> guarded = frit_tuner(safeguard=True, units="q")  # units change nothing here
    >>> guarded.psi is None, guarded.safeguard["deadzone"], guarded.gamma
    (True, 0.01, 1.0)
    """
    F = _checks.gain_pair("F", F)
    if np.any(F == 0):
        raise ValueError(f"F must be > 0 for the FRIT tuner (it defines M = F/(s+F)), got {F}")
    Ts = _checks.positive_scalar("Ts", Ts)
    lambda_ = _checks.in_interval("lambda_", lambda_, 0.0, 1.0)
    gamma = _checks.positive_scalar("gamma", gamma)
    kappa = _checks.in_interval("kappa", kappa, 0.0, 1.0)
    guard = _safeguard_params(safeguard, Ts)
    if guard["safeguard"] and psi is not None:
        raise ValueError("psi is the paper's threshold; the safeguarded tuner replaces it by "
                         "its dead zone: give safeguard={'deadzone': ...} instead of psi")
    psi = PSI_PAPER if psi is None else psi
    psi_values = _checks.float_array("psi", psi)
    psi_values = np.broadcast_to(psi_values, (2,)) if psi_values.ndim == 0 else psi_values
    if psi_values.shape != (2,) or not np.all(np.isfinite(psi_values)) or np.any(psi_values < 0):
        raise ValueError(f"psi must be >= 0 (one value or two), got {psi!r}")
    K0 = _checks.gain_matrix("K0", K0)
    h0 = _checks.vector("h0", h0, 2)
    readings = {name: _reading(name, value) for name, value in
                (("filter", filter), ("start", start), ("freeze", freeze), ("units", units))}
    scale = UNIT_SCALES[units] if output_scale is None else \
        _checks.positive_scalar("output_scale", output_scale)
    if guard["safeguard"]:
        # normalised regressors: P is in the units of K, not of h, and the dead zone takes
        # the place of psi, so the units of h enter nowhere
        gamma = min(gamma, guard["p_max"])
        K0 = kernels.project_stable_gain(K0.ravel().copy(), 0, Ts, guard["rho"]).reshape(2, 2)
        psi_values = np.zeros(2)
    else:
        gamma = gamma * scale**2  # see output_scale
        psi_values = psi_values / scale
    a = np.exp(-F * Ts)
    params = TUNER.pack(F=F, a=a, lambda_=lambda_, kappa=kappa, psi=psi_values,
                        feedthrough=float(filter == "feedthrough"),
                        joint=float(freeze == "joint"), **guard)
    sys = KernelBlock(kernels.tuner_output, kernels.tuner_update, params=params,
                       feedthrough=False,
                       inputs=TUNER_INPUTS.labels(),
                       outputs=K_SIGNALS, states=TUNER_STATES, dt=Ts, name=name)
    P0 = (gamma * np.eye(2)).ravel()
    Mh0 = h0 if start == "rest" else np.zeros(2)
    sys.x0 = TUNER_STATE.pack(Mxi1=np.zeros(2), Mxi2=np.zeros(2), Mmu=np.zeros(2), Mh=Mh0,
                              Khat=K0, P1=P0, P2=P0, K=K0)
    sys.F, sys.lambda_, sys.gamma, sys.kappa = F, lambda_, gamma, kappa
    sys.psi = None if guard["safeguard"] else psi_values
    sys.readings, sys.output_scale = readings, scale
    sys.safeguard = {k: guard[k] for k in SAFEGUARD_DEFAULTS} if guard["safeguard"] else None
    return drawn_as(sys, "FRIT", default_name="tuner")
