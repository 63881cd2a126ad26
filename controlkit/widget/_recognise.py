"""Which constructor call rebuilds a block of an opened diagram: proposed, then proved.

For each block the editor proposes recipes (:data:`~._palette.PALETTE` entries with
keyword arguments read from the block: the matrices of a state-space block, the signs
of a summing junction, ``F`` of the outer controller...), builds each, and accepts one
only when the rebuilt block is the same as the original (:func:`same_block`: same
class, signals, timebase, matrices or compiled kernels and their packed parameters).
A block no proposal rebuilds exactly - a user's own ``nlsys``, a tuned factory
argument the block does not keep - is not guessed: the written code takes it as a
parameter (see :mod:`._code`).
"""

from __future__ import annotations

import functools
import warnings

import control as ct
import numpy as np

from ..blocks.contract import KernelBlock
from ..blocks.sampling import SampledSystem
from . import _palette
from ._calls import plain

#: Controlkit palette entries tried on a KernelBlock, with the keyword arguments read back.
_FACTORY_KWARGS = {
    "outer_controller": lambda b: [{"F": float(np.ravel(b.F)[0]),
                                    "output": b.output_labels[0].split("[")[0]}]
    if getattr(b, "F", None) is not None and b.noutputs else [],
    "constant_gain": lambda b: [{"K": float(np.ravel(b.K)[0])}]
    if getattr(b, "K", None) is not None else [],
    "nominal_model": lambda b: [{"Ts": float(b.dt)} | (
        {"h0": plain(b.x0)} if np.any(getattr(b, "x0", 0)) else {})]
    if b.dt and b.dt is not True else [],
    "torque_saturation": lambda b: [{"T1_max": float(b.limits[0]), "T2_max": float(
        b.limits[1])}] if getattr(b, "limits", None) is not None else [],
    "adaptive_smc": lambda b: [{"Ts": float(b.dt)}] if b.dt and b.dt is not True else [],
    "true_plant": lambda b: [{"model_error": True}, {"model_error": False}],
    "spacecraft_plant": lambda b: [{}],
    "io_linearizer": lambda b: [{}],
    "attitude_output": lambda b: [{}],
    "mec_compensator": lambda b: [{}],
    "cmg_plant": lambda b: [{}],
    "reference_generator": lambda b: [{}],
}


def recognise(block):
    """A recipe that rebuilds ``block`` exactly, or None.

    Returns
    -------
    dict or None
        ``{"kind": palette key, "kwargs": {...}}`` (with ``"sampled": {"Ts": ...}`` for a
        block sampled by :func:`~controlkit.blocks.sampling.sample_nlsys`).

    Examples
    --------
    >>> from controlkit.blocks import spacecraft as sc
    >>> recognise(sc.outer_controller(0.002, output="mu_n"))["kwargs"]
    {'F': 0.002, 'output': 'mu_n'}
    >>> recognise(ct.nlsys(lambda t, x, u, p: -x, None, states=1, inputs=1, outputs=1)) is None
    True
    """
    for recipe in _proposals(block):
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rebuilt = _palette.build(recipe["kind"], block.name, recipe["kwargs"],
                                         recipe.get("sampled"))
        except (ValueError, TypeError, KeyError, IndexError, np.linalg.LinAlgError):
            continue
        if same_block(block, rebuilt):
            return recipe
    return None


def _proposals(block):
    if isinstance(block, ct.InterconnectedSystem):
        return
    if isinstance(block, ct.StateSpace):
        yield from _lti(block)
        return
    if isinstance(block, SampledSystem):
        sampled = {"Ts": float(block.dt)}
        if block.method != "rk4" or block.substeps != 1:
            sampled |= {"method": block.method, "substeps": int(block.substeps)}
        for recipe in _proposals(block.continuous):
            if recipe["kind"] in _palette.PALETTE and _palette.PALETTE[
                    recipe["kind"]].follows_period and block.continuous.name == block.name:
                yield {**recipe, "sampled": sampled}
        return
    if isinstance(block, KernelBlock):
        for key in _candidates(block):
            for kwargs in _FACTORY_KWARGS[key](block):
                yield {"kind": key, "kwargs": kwargs}


def _lti(block):
    D = np.asarray(block.D, dtype=float)
    if (not block.nstates and block.dt is None and D.shape[0] == 1 and D.shape[1] >= 1
            and set(np.unique(D).tolist()) <= {-1.0, 1.0}):
        yield {"kind": "junction", "kwargs": {
            "inputs": [("-" if d < 0 else "") + label
                       for d, label in zip(D[0], block.input_labels, strict=True)],
            "output": block.output_labels[0]}}
    kwargs = {m: plain(np.asarray(getattr(block, m), dtype=float)) for m in "ABCD"}
    if block.dt != 0:
        kwargs["dt"] = block.dt if block.dt is None or block.dt is True else float(block.dt)
    for key, prefix, labels in (("inputs", "u", block.input_labels),
                                ("outputs", "y", block.output_labels),
                                ("states", "x", block.state_labels)):
        if list(labels) != [f"{prefix}[{i}]" for i in range(len(labels))]:
            kwargs[key] = list(labels)
    yield {"kind": "state_space", "kwargs": kwargs}


@functools.cache
def _kernel_functions(key):
    """The output and update kernels of palette entry ``key``'s default block."""
    entry = _palette.PALETTE[key]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            block = _palette.build(key, entry.name, entry.defaults)
    except (ValueError, TypeError, KeyError, IndexError):
        return None
    kernels = getattr(block, "kernels", None)
    return None if kernels is None else (kernels.output, kernels.update)


def _candidates(block):
    functions = (block.kernels.output, block.kernels.update)
    return [key for key in _FACTORY_KWARGS if _kernel_functions(key) == functions]


def same_block(a, b):
    """Whether ``b`` is ``a`` rebuilt: same class, signals, timebase and numbers.

    State-space blocks compare their matrices; controlkit blocks their compiled kernels
    (the functions themselves), packed parameters, ``params``, initial state and drawing
    attributes; sampled blocks also their sampling settings and continuous block.
    Any other block is never the same as a rebuilt one (its functions cannot be read).
    """
    if type(a) is not type(b) or a.name != b.name:
        return False
    if (list(a.input_labels), list(a.output_labels), list(a.state_labels)) != (
            list(b.input_labels), list(b.output_labels), list(b.state_labels)):
        return False
    if not _same_timebase(a.dt, b.dt):
        return False
    if isinstance(a, ct.StateSpace):
        return all(np.array_equal(getattr(a, m), getattr(b, m)) for m in "ABCD")
    if isinstance(a, SampledSystem):
        return ((a.method, a.substeps, a.rtol, a.atol) == (b.method, b.substeps, b.rtol, b.atol)
                and same_block(a.continuous, b.continuous) and _same_kernels(a, b)
                and _same_attributes(a, b))
    if isinstance(a, KernelBlock):
        return _same_kernels(a, b) and _same_attributes(a, b)
    return False


def _same_kernels(a, b):
    ka, kb = getattr(a, "kernels", None), getattr(b, "kernels", None)
    if ka is None or kb is None:
        return ka is kb
    return (ka.output is kb.output and ka.update is kb.update
            and _same_value(ka.params, kb.params) and ka.feedthrough == kb.feedthrough
            and _same_value(ka.rk4, kb.rk4) and _same_value(ka.repack, kb.repack))


def _same_attributes(a, b):
    return all(_same_value(getattr(a, n, None), getattr(b, n, None)) for n in (
        "params", "x0", "display_name", "junction", "uncompiled_reason"))


def _same_timebase(a, b):
    if a is None or a is True or b is None or b is True:
        return a is b
    return float(a) == float(b)


def _same_value(a, b):
    if isinstance(a, dict) or isinstance(b, dict):
        return (isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys()
                and all(_same_value(a[k], b[k]) for k in a))
    if isinstance(a, (np.ndarray, list, tuple)) or isinstance(b, (np.ndarray, list, tuple)):
        try:
            return np.array_equal(np.asarray(a, dtype=object), np.asarray(b, dtype=object))
        except (ValueError, TypeError):
            return False
    if callable(a) or callable(b):
        return a is b
    try:
        return bool(a == b)
    except (ValueError, TypeError):
        return False
