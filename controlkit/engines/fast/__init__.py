"""The fast backend: a diagram written out as one module, run as Python or compiled.

The kernels called are the blocks' own, so the result equals
``control.input_output_response`` on the same system. Its pipeline, module by module, is
described in ``docs/architecture.md`` (*The engine*).
"""

from __future__ import annotations

from .continuous import StiffProblem, run_continuous
from .diagnose import explain
from .discrete import STREAM_CHUNK_STEPS, simulate
from .response import response
from .run import RULE, compiled_job, prepare
from .store import CACHE_DIR
from .tiers import TIERS, BlockTier

__all__ = ["CACHE_DIR", "RULE", "STREAM_CHUNK_STEPS", "TIERS", "BlockTier", "StiffProblem",
           "compiled_job", "explain", "prepare", "response", "run_continuous", "simulate"]
