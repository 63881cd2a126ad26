"""Sensitivity of the paper's central claim to the tuner details it leaves open.

The spacecraft paper's on-line FRIT tuner (eq. 15-30, Table 3) leaves four
details unstated: how ``M`` is discretised (``filter``), where its filters
start (``start``), how the threshold freezes the rows of ``K`` (``freeze``) and
the units of Table 3's ``P(0)`` and ``psi`` (``units``); see
:data:`controlkit.blocks.frit.READINGS`. This study runs the ``proposed`` case
of :mod:`controlkit.studies.spacecraft.scenario` under all 16 combinations, for the
paper's tuner and for the safeguarded one, and reports per reading whether the
0.05 deg requirement holds. A reading whose loop diverges is a result, not a
crash: its row says ``diverged`` and when.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from ...blocks import frit
from ...blocks.spacecraft import POINTING_REQUIREMENT_DEG, TS_PAPER, pointing_error_deg
from ..spacecraft import scenario as spacecraft

#: Horizon of the study (the paper's figures), s.
HORIZON = spacecraft.HORIZON
#: The tuners compared: the paper's (eq. 15-30) and the safeguarded one (beyond the paper).
TUNERS = {"paper": {}, "safeguarded": {"safeguard": True}}
#: Cases of the ``frit`` study on the command line: one per tuner.
CASES = tuple(TUNERS)
DEFAULT_CASES = CASES
#: Wheel speeds are compared after the initial transient: from this time on, s.
TRANSIENT_S = 1000.0
#: Every reading, as dicts of ``frit_tuner`` keywords, in a fixed order.
READINGS = tuple(dict(zip(frit.READINGS, values, strict=True))
                 for values in itertools.product(*frit.READINGS.values()))
#: Samples of ``K`` kept per reading for the figures (the run itself has every step).
K_TRACE_POINTS = 2000


@dataclass
class ReadingResult:
    """One tuner under one reading: the row of ``sensitivity.csv`` and a trace of ``K``.

    Attributes
    ----------
    tuner : str
        A key of :data:`TUNERS`.
    reading : dict
        ``filter``, ``start``, ``freeze``, ``units``.
    metrics : dict
        The CSV columns after the reading's (see :data:`controlkit.studies.frit.outputs.COLUMNS`).
    time, K : numpy.ndarray
        Decimated time and gain trace (``K`` row-major, shape ``(4, n)``); for a run that
        diverged, the trace up to the last chunk of the run that stayed finite.
    error : str
        Why the run stopped, when it diverged; else ``""``.

    Examples
    --------
    >>> r = run_reading("paper", READINGS[0], horizon=10.0)
    >>> r.tuner, r.metrics["diverged"]
    ('paper', False)
    """

    tuner: str
    reading: dict
    metrics: dict
    time: np.ndarray = field(repr=False)
    K: np.ndarray = field(repr=False)
    error: str = ""


def _tuner_options(tuner: str, reading: dict) -> dict:
    if tuner not in TUNERS:
        raise ValueError(f"tuner must be one of {list(TUNERS)}, got {tuner!r}")
    options = {**reading, **TUNERS[tuner]}
    if "safeguard" in options and not _has_safeguard():
        raise ValueError("the safeguarded tuner is not available in this version of "
                         "controlkit (frit_tuner has no 'safeguard' option)")
    return options


def _has_safeguard() -> bool:
    import inspect

    return "safeguard" in inspect.signature(frit.frit_tuner).parameters


def run_reading(tuner="paper", reading=None, *, horizon=HORIZON, engine="fast",
                progress=None) -> ReadingResult:
    """Simulate the ``proposed`` loop with one tuner under one reading.

    Parameters
    ----------
    tuner : {"paper", "safeguarded"}
        Which tuner (:data:`TUNERS`).
    reading : dict, optional
        ``frit_tuner`` keywords among ``filter``, ``start``, ``freeze``, ``units``;
        default controlkit's reading (:data:`READINGS` ``[0]``).
    horizon : float
        Simulated time, s (default 20 000 s).
    engine : {"fast", "python-control"}
        Simulator.
    progress : callable, optional
        Called with the fraction done.

    Returns
    -------
    ReadingResult

    Examples
    --------
    >>> r = run_reading("paper", {"units": "q"}, horizon=100.0)
    >>> r.reading["units"], round(r.metrics["horizon_s"])
    ('q', 100)
    """
    reading = {**READINGS[0], **(reading or {})}
    unknown = set(reading) - set(frit.READINGS)
    if unknown:
        raise ValueError(f"reading has unknown keys {sorted(unknown)}; "
                         f"allowed: {list(frit.READINGS)}")
    options = _tuner_options(tuner, reading)
    labels = list(spacecraft.build_loop("proposed", tuner_options=options).output_labels)
    steps = int(round(horizon / TS_PAPER)) + 1
    every = max(1, steps // K_TRACE_POINTS)
    watch = _Watch(labels, horizon, every)
    try:
        # a reading that diverges is a result of this study (recorded below); the engine's
        # diagnosis of where it diverged evaluates the loop at the non-finite state, and
        # numpy's "invalid value" warnings from that evaluation say nothing more
        with np.errstate(invalid="ignore", over="ignore"):
            resp = spacecraft.run("proposed", horizon=horizon, tuner_options=options,
                                  progress=progress, engine=engine, on_chunk=watch,
                                  record_every=every)
    except FloatingPointError as error:
        metrics = {"horizon_s": float(horizon), "max_pointing_error_last_half_deg": math.nan,
                   "final_pointing_error_deg": math.nan, "max_abs_K": math.nan,
                   "peak_abs_u_after_1000s_rad_s": math.nan, "diverged": True,
                   "requirement_met_last_half": False,
                   "diverged_at_s": getattr(error, "time", math.nan)}
        time, K = watch.trace()
        return ReadingResult(tuner, reading, metrics, time, K, str(error))
    K = resp.outputs[[labels.index(f"K[{i}]") for i in range(4)]]
    return ReadingResult(tuner, reading, watch.metrics(), resp.time, K)


class _Watch:
    """The study's metrics, accumulated chunk by chunk over every step of a streamed run."""

    def __init__(self, labels, horizon, every=1):
        self.q = [labels.index(f"q[{i}]") for i in range(4)]
        self.K = [labels.index(f"K[{i}]") for i in range(4)]
        self.u = [labels.index(f"u[{i}]") for i in range(2)]
        self.half, self.horizon = horizon / 2, horizon
        self.worst = self.max_K = self.peak_u = 0.0
        self.final, self.finite, self.t_end = math.nan, True, 0.0
        # every ``every``-th sample of K, counted over the whole run: the trace of a run
        # that diverges, whose decimated response is lost with the exception
        self.every, self.seen, self.t_kept, self.K_kept = every, 0, [], []

    def __call__(self, t, y, x):
        error = pointing_error_deg(y[self.q])
        K, u = y[self.K], y[self.u]
        self.finite &= bool(np.all(np.isfinite(error)) and np.all(np.isfinite(K)))
        late = t >= self.half
        if late.any():
            self.worst = max(self.worst, float(error[late].max()))
        self.max_K = max(self.max_K, float(np.abs(K).max()))
        after = t >= min(TRANSIENT_S, self.horizon)
        if after.any():
            self.peak_u = max(self.peak_u, float(np.abs(u[:, after]).max()))
        self.final, self.t_end = float(error[-1]), float(t[-1])
        first = -self.seen % self.every
        self.t_kept.append(t[first::self.every].copy())
        self.K_kept.append(K[:, first::self.every].copy())
        self.seen += t.size

    def trace(self):
        """The kept samples of ``K`` so far: ``time (n,)``, ``K (4, n)``."""
        if not self.t_kept:
            return np.zeros(0), np.zeros((4, 0))
        return np.concatenate(self.t_kept), np.hstack(self.K_kept)

    def metrics(self) -> dict:
        return {
            "horizon_s": self.t_end,
            "max_pointing_error_last_half_deg": self.worst,
            "final_pointing_error_deg": self.final,
            "max_abs_K": self.max_K,
            "peak_abs_u_after_1000s_rad_s": self.peak_u,
            "diverged": not self.finite,
            "requirement_met_last_half": bool(self.finite
                                              and self.worst <= POINTING_REQUIREMENT_DEG),
            "diverged_at_s": math.nan,
        }


def run(case="paper", *, horizon=HORIZON, engine="fast", progress=None):
    """Run one tuner under all 16 readings (:data:`READINGS`).

    Parameters
    ----------
    case : {"paper", "safeguarded"}
        Which tuner.
    horizon : float
        Simulated time of each run, s.
    engine : {"fast", "python-control"}
        Simulator.
    progress : callable, optional
        Called with the fraction of readings done.

    Returns
    -------
    list of ReadingResult
        One per reading, in :data:`READINGS` order.

    Examples
    --------
    >>> results = run("paper", horizon=1.0)
    >>> len(results), results[0].reading
    (16, {'filter': 'zoh', 'start': 'rest', 'freeze': 'row', 'units': 'deg'})
    """
    results = []
    for i, reading in enumerate(READINGS):
        results.append(run_reading(case, reading, horizon=horizon, engine=engine))
        if progress is not None:
            progress((i + 1) / len(READINGS))
    return results


def run_inertia_step(tuner="safeguarded", reading=None, *, horizon=HORIZON, step_at=None,
                     factor=2.0, engine="fast"):
    """The proposed loop whose inertia error jumps to ``factor`` times Table 2's mid-run.

    Until ``step_at`` (default half the horizon) the true plant is Table 2's; from then on
    each diagonal entry of ``Delta J`` is ``factor`` times larger. The loop continues from
    the state it reached (the tuner keeps what it learnt), so the run shows whether the
    tuner re-tunes. Returns the response and the recovery time: how long after the step the
    pointing error last exceeded the 0.05 deg requirement (0 if it never did; ``inf`` if it
    still exceeds it at the end).

    Examples
    --------
    >>> resp, recovery = run_inertia_step("paper", horizon=20.0)  # still turning at 20 s
    >>> float(resp.time[-1]), recovery
    (20.0, inf)
    """
    from ...blocks.sampling import time_grid
    from ...engines.contract import response
    from ...simulation import initial_state, simulate

    reading = {**READINGS[0], **(reading or {})}
    options = _tuner_options(tuner, reading)
    step_at = horizon / 2 if step_at is None else step_at
    if not 0 < step_at < horizon:
        raise ValueError(f"step_at must lie inside (0, horizon = {horizon:g}) s, got {step_at!r}")
    first = spacecraft.run("proposed", horizon=step_at, tuner_options=options, engine=engine)
    loop = spacecraft.build_loop("proposed", tuner_options=options,
                                 h0=spacecraft.initial_attitude()[1:3],
                                 plant_options={"inertia_error_scale": factor})
    if initial_state(loop).size != first.states.shape[0]:  # the same blocks, the same state
        raise RuntimeError("the stepped loop's state does not match the first part's")
    T = step_at + time_grid(horizon - step_at, TS_PAPER)
    second = simulate(loop, T, X0=first.states[:, -1], U=0.0, engine=engine)

    # the second part starts where the first ended: its first sample is the first's last
    resp = response(
        loop, *(np.concatenate([a, b[..., 1:]], axis=-1) for a, b in (
            (first.time, second.time), (first.outputs, second.outputs),
            (first.states, second.states), (first.inputs, second.inputs))),
        sysname="inertia_step", title=f"Inertia error x{factor:g} at t = {step_at:g} s")
    labels = list(resp.output_labels)
    error = pointing_error_deg(resp.outputs[[labels.index(f"q[{i}]") for i in range(4)]])
    after = resp.time >= step_at
    over = np.nonzero(after & (error > POINTING_REQUIREMENT_DEG))[0]
    if over.size == 0:
        recovery = 0.0
    elif over[-1] == resp.time.size - 1:
        recovery = math.inf
    else:
        recovery = float(resp.time[over[-1] + 1] - step_at)
    return resp, recovery
