"""The ``params`` check shared by every backend: a key no block reads is refused.

python-control silently ignores a ``params`` key that no block reads (a typo, or a
parameter of a controlkit block, which takes its parameters when it is built). Both
backends refuse it instead, naming the keys the blocks do read, found in the functions'
source (:func:`.source.used_params`); where a block's reads cannot be known (a function
without source, ``params`` used otherwise than by key), every key is accepted, as
python-control would.
"""

from __future__ import annotations

import control as ct

from ..blocks.contract import KernelBlock
from ..blocks.sampling import SampledSystem
from .source import used_params


def params_read(block):
    """The parameter names ``block`` reads, or None where that cannot be known.

    Examples
    --------
    >>> import control as ct
    >>> gain = ct.nlsys(None, lambda t, x, u, params: params.get("k", 1.0) * u, inputs=1,
    ...                 outputs=1)
    >>> params_read(gain)
    {'k'}
    """
    if isinstance(block, KernelBlock | ct.StateSpace):
        return set()  # controlkit blocks take theirs when built; LTI blocks have none
    if isinstance(block, ct.InterconnectedSystem):
        return _union(block.params, (params_read(sub) for sub in block.syslist))
    if isinstance(block, SampledSystem):
        return _union(block.params, [params_read(block.continuous)])
    return _union(block.params, (used_params(fn) for fn in (block.updfcn, block.outfcn)
                                 if fn is not None))


def _union(keys, more):
    """The set of ``keys`` and of every set in ``more``; None (not known) as soon as one of
    them is None."""
    keys = set(keys)
    for part in more:
        if part is None:
            return None
        keys |= part
    return keys


def check_params(sys, params):
    """Refuse ``params`` keys that no block of ``sys`` reads (python-control ignores them).

    Raises
    ------
    ValueError
        Naming the unknown keys and the ones the blocks read.

    Examples
    --------
    >>> import control as ct
    >>> gain = ct.nlsys(None, lambda t, x, u, params: params["k"] * u, inputs=1, outputs=1,
    ...                 params={"k": 2.0}, name="gain")
    >>> check_params(gain, {"k": 3.0})
    >>> try:
    ...     check_params(gain, {"K": 3.0})
    ... except ValueError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    params ['K'] are read by no block of 'gain' (they read ['k']); controlkit's own
    blocks take their parameters when they are built, e.g. outer_controller(F=...)
    """
    if not params:
        return
    if not isinstance(params, dict):
        raise ValueError(f"params must be a dict of parameter values, got {type(params).__name__}")
    keys = params_read(sys)
    if keys is None:  # reads not known: python-control's own behaviour
        return
    unknown = sorted(set(params) - keys)
    if unknown:
        raise ValueError(
            f"params {unknown} are read by no block of {sys.name!r} (they read "
            f"{sorted(keys)}); controlkit's own blocks take their parameters when they are "
            f"built, e.g. outer_controller(F=...)")
