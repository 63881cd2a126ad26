"""Simulation backends behind one signature, found by name in :data:`BACKENDS`.

A backend is a module with a function

``simulate(sys, T, X0, U, *, params, progress, chunks, record_every, on_chunk)``

taking the arguments already checked by :func:`.contract.check_arguments` and
returning :func:`.contract.response`'s :class:`control.TimeResponseData`. A backend
that cannot run a system raises :class:`.contract.UnsupportedSystem` with the reason;
:func:`controlkit.simulation.simulate` then runs the reference instead and warns.

To add a backend: write its module in this package, following :mod:`.reference`
(the simplest), and add one entry to :data:`BACKENDS`.
"""

from __future__ import annotations

import importlib

#: Backend name to its module (imported when first used: numba loads only when asked for).
BACKENDS = {
    "fast": "controlkit.engines.fast",
    "python-control": "controlkit.engines.reference",
}

#: The backends' names.
ENGINES = tuple(BACKENDS)


def backend(name: str):
    """The module of backend ``name`` (one of :data:`ENGINES`).

    Examples
    --------
    >>> backend("python-control").__name__
    'controlkit.engines.reference'
    >>> backend("matlab")
    Traceback (most recent call last):
    ...
    ValueError: engine must be one of ('fast', 'python-control'), got 'matlab'
    """
    if name not in BACKENDS:
        raise ValueError(f"engine must be one of {ENGINES}, got {name!r}")
    return importlib.import_module(BACKENDS[name])
