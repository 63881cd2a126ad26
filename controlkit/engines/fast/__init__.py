"""The fast backend: a diagram written out as one module, run as Python or compiled.

Each block gets kernels and a tier (:mod:`.tiers`, :func:`explain`); the diagram's
evaluation order is written out as the text of one module (:mod:`.codegen`), which runs
as Python or, compiled by numba, from the store (:mod:`.store`), as :mod:`.run` decides;
discrete diagrams run in :mod:`.discrete`, the others in :mod:`.continuous`, both through
the loops of :mod:`.loops` (and the integrator of :mod:`.rk`). Users' own ``(t, x, u,
params)`` functions are called as they are, or compiled from their source
(:mod:`.usercode`); when a kernel signals a failure with NaN, :mod:`.diagnose` lets the
block say why in its own words. The kernels called are the blocks' own, so the result
equals ``control.input_output_response`` on the same system.
"""

from __future__ import annotations

from .continuous import StiffProblem, run_continuous
from .discrete import STREAM_CHUNK_STEPS, simulate
from .response import response
from .run import RULE, compiled_job, explain, prepare
from .store import CACHE_DIR
from .tiers import TIERS, BlockTier

__all__ = ["CACHE_DIR", "RULE", "STREAM_CHUNK_STEPS", "TIERS", "BlockTier", "StiffProblem",
           "compiled_job", "explain", "prepare", "response", "run_continuous", "simulate"]
