"""The reference backend: :func:`control.input_output_response`, in chunks.

Chunks only add progress reports: each restarts from the state the previous one
reached, so a discrete system run in chunks gives the numbers of one run, bit for bit.
"""

from __future__ import annotations

import control as ct
import numpy as np

from .contract import chunk_bounds, recorded_indices, response


def simulate(sys, T, X0, U, *, params=None, progress=None, chunks=1, record_every=1,
             on_chunk=None) -> ct.TimeResponseData:
    """Run ``sys`` with :func:`control.input_output_response`, chunk by chunk.

    Arguments as :func:`controlkit.simulation.simulate`, already checked
    (:func:`controlkit.engines.contract.check_arguments`). The whole run is held in
    memory; ``on_chunk`` is called once with all of it, and ``record_every`` keeps
    every ``record_every``-th sample (and the last) of the result.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    >>> simulate(sys, np.arange(4.0), np.ones(1), np.zeros((0, 4)), chunks=2).outputs.tolist()
    [[1.0, 0.5, 0.25, 0.125]]
    """
    kept = None if record_every == 1 else recorded_indices(len(T), record_every)
    bounds = chunk_bounds(len(T) - 1, chunks)  # chunks share their end samples
    x = np.asarray(X0, dtype=float)
    pieces = []
    for k, (i0, i1) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        resp = ct.input_output_response(sys, T[i0 : i1 + 1], U[:, i0 : i1 + 1], x,
                                        params=params, squeeze=False)
        first = 0 if k == 0 else 1  # the previous chunk already holds this sample
        states = resp.x if resp.x is not None else np.zeros((0, resp.time.size))
        arrays = (resp.time, resp.outputs, states, resp.inputs)
        pieces.append([a[..., first:] for a in arrays])
        x = states[:, -1]
        if progress is not None:
            progress(i1 / (len(T) - 1))
    time, outputs, states, inputs = (np.concatenate(a, axis=-1)
                                     for a in zip(*pieces, strict=True))
    if on_chunk is not None:  # this path holds the whole run anyway
        on_chunk(time, outputs, states)
    if kept is not None:
        time, outputs, states, inputs = (time[kept], outputs[:, kept], states[:, kept],
                                         inputs[:, kept])
    return response(sys, time, outputs, states, inputs)
