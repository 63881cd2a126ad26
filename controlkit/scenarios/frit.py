"""Sensitivity of the paper's central claim to the tuner details it leaves open.

The spacecraft paper's on-line FRIT tuner (eq. 15-30, Table 3) leaves four
details unstated: how ``M`` is discretised (``filter``), where its filters
start (``start``), how the threshold freezes the rows of ``K`` (``freeze``) and
the units of Table 3's ``P(0)`` and ``psi`` (``units``); see
:data:`controlkit.blocks.mec.READINGS`. This study runs the ``proposed`` case
of :mod:`controlkit.scenarios.spacecraft` under all 16 combinations, for the
paper's tuner and for the safeguarded one, and reports per reading whether the
0.05 deg requirement holds. A reading whose loop diverges is a result, not a
crash: its row says ``diverged`` and when.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np

from ..blocks import mec
from ..blocks.spacecraft import POINTING_REQUIREMENT_DEG, pointing_error_deg
from . import spacecraft

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
READINGS = tuple(dict(zip(mec.READINGS, values, strict=True))
                 for values in itertools.product(*mec.READINGS.values()))
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
        The CSV columns after the reading's (see :data:`controlkit.outputs.frit.COLUMNS`).
    time, K : numpy.ndarray
        Decimated time and gain trace (``K`` row-major, shape ``(4, n)``); empty if the
        run diverged.
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

    return "safeguard" in inspect.signature(mec.frit_tuner).parameters


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
    unknown = set(reading) - set(mec.READINGS)
    if unknown:
        raise ValueError(f"reading has unknown keys {sorted(unknown)}; "
                         f"allowed: {list(mec.READINGS)}")
    options = _tuner_options(tuner, reading)
    try:
        resp = spacecraft.run("proposed", horizon=horizon, tuner_options=options,
                              progress=progress, engine=engine)
    except FloatingPointError as error:
        metrics = {"horizon_s": float(horizon), "max_pointing_error_last_half_deg": math.nan,
                   "final_pointing_error_deg": math.nan, "max_abs_K": math.nan,
                   "peak_abs_u_after_1000s_rad_s": math.nan, "diverged": True,
                   "requirement_met_last_half": False,
                   "diverged_at_s": getattr(error, "time", math.nan)}
        return ReadingResult(tuner, reading, metrics, np.zeros(0), np.zeros((4, 0)),
                             str(error))
    return ReadingResult(tuner, reading, *_summarise(resp))


def _summarise(resp):
    """The CSV metrics of one run and its decimated ``K`` trace (the run is then dropped)."""
    labels = list(resp.output_labels)

    def rows(name, n):
        return resp.outputs[[labels.index(f"{name}[{i}]") for i in range(n)]]

    t, q, K, u = resp.time, rows("q", 4), rows("K", 4), rows("u", 2)
    error = pointing_error_deg(q)
    finite = bool(np.all(np.isfinite(error)) and np.all(np.isfinite(K)))
    worst = float(error[t >= t[-1] / 2].max())
    after = t >= min(TRANSIENT_S, t[-1])
    metrics = {
        "horizon_s": float(t[-1]),
        "max_pointing_error_last_half_deg": worst,
        "final_pointing_error_deg": float(error[-1]),
        "max_abs_K": float(np.abs(K).max()),
        "peak_abs_u_after_1000s_rad_s": float(np.abs(u[:, after]).max()),
        "diverged": not finite,
        "requirement_met_last_half": bool(finite and worst <= POINTING_REQUIREMENT_DEG),
        "diverged_at_s": math.nan,
    }
    every = max(1, t.size // K_TRACE_POINTS)
    return metrics, t[::every], K[:, ::every]


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
