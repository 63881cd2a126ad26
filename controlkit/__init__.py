"""controlkit: block diagrams for robust nonlinear attitude control, on python-control.

The names most notebooks need are available from the package itself (imported when
first used, so ``import controlkit`` stays light): python-control's
:func:`input_output_response` and :func:`interconnect` as drop-ins (compiled where they
can be; continuous, discrete and mixed diagrams), :func:`simulate`,
:func:`initial_state`, :func:`time_grid`, :func:`sample_nlsys`, :func:`explain`,
:func:`draw_block_diagram`, :func:`plot`.

Subpackages: ``blocks`` (one ``NonlinearIOSystem`` per element of the papers, and the
block contract), ``kernels`` (their equations), ``engines`` (simulation backends:
python-control's, and the compiled one), ``studies`` (the papers' diagrams, cases,
outputs and robustness sweeps), ``drawing`` (block diagrams), ``outputs`` (figure style
and files). The page *Architecture* of the documentation says where to add a block, a
backend or a study.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: Top-level name to the module that defines it.
_LAZY = {
    "input_output_response": "controlkit.simulation",
    "interconnect": "controlkit.sampled_data",
    "simulate": "controlkit.simulation",
    "initial_state": "controlkit.simulation",
    "time_grid": "controlkit.blocks.sampling",
    "sample_nlsys": "controlkit.blocks.sampling",
    "explain": "controlkit.engines.fast",
    "draw_block_diagram": "controlkit.drawing",
    "plot": "controlkit.plotting",
    "linearize": "controlkit.analysis",
    "find_eqpt": "controlkit.analysis",
    "loop_transfers": "controlkit.analysis",
    "compare_frequency_responses": "controlkit.analysis",
}

__all__ = sorted(_LAZY)


def __getattr__(name):
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value  # later lookups skip this function
        return value
    raise AttributeError(f"module 'controlkit' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))

