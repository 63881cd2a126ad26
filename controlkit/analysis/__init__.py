"""Linear analysis of any diagram, sampled-data included.

:func:`linearize` and :func:`find_eqpt` take python-control's arguments and return its
results, also for a continuous plant under a discrete controller
(:func:`controlkit.interconnect`); :func:`loop_transfers` cuts a loop open at a signal
(loop gain, sensitivity, complementary sensitivity); :func:`reduced` drops the states the
wiring decouples; :func:`compare_frequency_responses` draws several loops on one figure.
"""

from .linearize import find_eqpt, linearize
from .loops import LoopTransfers, loop_transfers, reduced
from .plots import compare_frequency_responses, frequency_response

__all__ = ["LoopTransfers", "compare_frequency_responses", "find_eqpt",
           "frequency_response", "linearize", "loop_transfers", "reduced"]
