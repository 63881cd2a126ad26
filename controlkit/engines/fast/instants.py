"""The discrete instants of a continuous or sampled-data run, and which of them serve the
evaluation times: shared by the single-run, many-run and stiff-method paths."""

from __future__ import annotations

import math

import numpy as np

#: An evaluation time within this fraction of the base period of an instant is on it.
INSTANT_TOLERANCE = 1e-9


def _instants(sys, T0, Tf):
    """The discrete instants ``T0 + k h`` up to ``Tf`` (``[T0]`` without discrete blocks)."""
    h = float(getattr(sys, "base_period", 0.0) or 0.0)
    if not h:
        return np.array([T0]), 0.0
    count = math.floor((Tf - T0) / h * (1 + 1e-12)) + 1
    return T0 + np.arange(count) * h, h


def _eval_instants(t_eval, instants, h):
    """For each evaluation time, the index of the instant it is on, else -1."""
    if not h:
        return np.where(t_eval == instants[0], 0, -1).astype(np.int64)
    k = np.rint((t_eval - instants[0]) / h).astype(np.int64)
    on = (k >= 0) & (k < instants.size) & (
        np.abs(t_eval - instants[0] - k * h) <= INSTANT_TOLERANCE * h)
    return np.where(on, k, -1).astype(np.int64)
