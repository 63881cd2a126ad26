"""The fast backend: a diagram written out as one loop, compiled with numba.

Each block gets kernels and a tier (:mod:`.tiers`, :func:`explain`); the
diagram's evaluation order is written out as the source of one loop over time
(:mod:`.codegen`), loaded from the disk cache or compiled (:mod:`.loader`) and run
in chunks or streamed (:mod:`.run`). Users' own ``(t, x, u, params)`` functions are
compiled from their source (:mod:`.usercode`); when a kernel signals a failure with
NaN, :mod:`.diagnose` lets the block say why in its own words. The kernels called
are the blocks' own, so the result equals ``control.input_output_response`` on the
same system.
"""

from __future__ import annotations

from .continuous import StiffProblem, run_continuous
from .loader import CACHE_DIR
from .response import response
from .run import STREAM_CHUNK_STEPS, compile_system, prepare, simulate
from .tiers import TIERS, BlockTier, explain

__all__ = ["CACHE_DIR", "STREAM_CHUNK_STEPS", "TIERS", "BlockTier", "StiffProblem",
           "compile_system", "explain", "prepare", "response", "run_continuous", "simulate"]
