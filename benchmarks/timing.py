"""What the benchmarks share: the median wall time of repeated calls."""

import statistics
import time


def median_seconds(function, repeats=5) -> float:
    """The median wall time, in seconds, of ``repeats`` calls of ``function()``."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)
