"""The editor's checks: the wiring mistakes of a diagram, each naming its blocks.

:func:`find_problems` is :meth:`~controlkit.widget.DiagramModel.problems`;
:func:`passes_input` says whether a block feeds its input through at the same instant, which
an algebraic loop needs in every block it passes (found as Tarjan's strongly connected
components of the feedthrough blocks' wiring).
"""

from __future__ import annotations

import warnings

import control as ct
import numpy as np

from ..blocks.sampling import SampledSystem
from ._parts import Problem
from ._ports import port_groups


def find_problems(model):
    """The wiring mistakes of ``model``; see :meth:`~controlkit.widget.DiagramModel.problems`."""
    found = []
    drivers = {}
    for w in model.wires:
        drivers.setdefault(w.dst, []).append(f"{w.src[0]}.{w.src[1]}")
    for name, targets in model.inputs:
        for block, signal, _ in targets:
            drivers.setdefault((block, signal), []).append(f"external input {name}")
    used = {w.src for w in model.wires} | {(b, s) for _, src in model.outputs
                                          for side, b, s, _ in src if side == "out"}
    for name, block in model.blocks.items():
        s = block.system
        loose = [label for label in s.input_labels if (name, label) not in drivers]
        if loose:
            found.append(Problem(
                "unconnected input", "warning", [name],
                f"unconnected input: {_signals(name, loose)} of block {name!r} has no "
                f"driver (python-control reads it as 0)"))
        for label in s.input_labels:
            feeds = drivers.get((name, label), [])
            if len(feeds) > 1 and (name, label) not in model.summed:
                blocks = [name] + [f.split(".")[0] for f in feeds
                                   if not f.startswith("external")]
                found.append(Problem(
                    "two drivers", "error", list(dict.fromkeys(blocks)),
                    f"two drivers on one signal: {name}.{label} is driven by "
                    f"{' and '.join(feeds)}; remove one wire, or add them in a summing "
                    f"junction"))
        unused = [label for label in s.output_labels if (name, label) not in used]
        if unused:
            found.append(Problem(
                "unused output", "note", [name],
                f"unused output: {_signals(name, unused)} of block {name!r} goes nowhere"))
    for label, names in model.input_groups():
        if not any(dict(model.inputs)[n] for n in names):
            found.append(Problem(
                "unused input", "note", [],
                f"unused input: the external input {label} drives nothing; it joins the "
                f"interconnect when it is wired to a block"))
    found += _algebraic_loops(model)
    found += _timebases(model)
    return found


def _algebraic_loops(model):
    """Loops of blocks that all pass their input through: no step order computes them."""
    direct = {n for n, b in model.blocks.items() if passes_input(b.system)}
    succ = {n: set() for n in direct}
    for w in model.wires:
        if w.src[0] in direct and w.dst[0] in direct:
            succ[w.src[0]].add(w.dst[0])
    found = []
    for component in _strong_components(succ):
        if len(component) == 1 and component[0] not in succ[component[0]]:
            continue
        cycle = _cycle(component, succ)
        order = " -> ".join(repr(n) for n in cycle + cycle[:1])
        found.append(Problem(
            "algebraic loop", "error", cycle,
            f"algebraic loop through blocks {order}: each passes its input straight to "
            f"its output, so no order of computing them exists; put a block with a "
            f"state (a delay, a plant, a filter) in the loop"))
    return found


def _timebases(model):
    """The timebases :func:`controlkit.interconnect` refuses, with its reason.

    Continuous and discrete blocks together make a sampled-data diagram, which runs; what
    is refused is what the engine refuses: periods that are not integer multiples of
    the shortest, a discrete block of unspecified period (``dt=True``) beside others.
    """
    from controlkit.sampled_data import interconnect

    if not model.is_mixed() and not any(b.system.dt is True for b in model.blocks.values()):
        return []
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            interconnect(model.systems(), connections=False, inplist=[], outlist=[])
    except ValueError as error:
        message = str(error)
        blocks = [n for n in model.blocks if repr(n) in message] or [
            n for names in model.timebases().values() for n in names]
        return [Problem("mismatched timebases", "error", blocks,
                        f"mismatched timebases: {message}")]
    return []


def passes_input(system):
    """Whether a block's output can move with its input at the same instant (feedthrough).

    A controlkit block declares it (``kernels.feedthrough``); a block sampled by
    :func:`~controlkit.blocks.sampling.sample_nlsys` has that of its continuous block; an LTI
    block has it where ``D`` is not zero; for any other block the output function is
    tried at a few points (a block whose output fails there counts as feedthrough).

    Examples
    --------
    >>> import control as ct
    >>> passes_input(ct.tf([1], [1, 1])), passes_input(ct.tf([1, 0], [1, 1]))
    (False, True)
    """
    kernels = getattr(system, "kernels", None)
    if kernels is not None and hasattr(kernels, "feedthrough"):
        return bool(kernels.feedthrough)
    if isinstance(system, SampledSystem):
        return passes_input(system.continuous)
    if not system.ninputs or not system.noutputs:
        return False
    if isinstance(system, ct.TransferFunction):
        try:
            system = ct.tf2ss(system)
        except Exception:  # noqa: BLE001 - an improper tf passes its input on
            return True
    if isinstance(system, ct.StateSpace):
        return bool(np.any(np.asarray(system.D) != 0))
    rng = np.random.default_rng(0)
    for _ in range(3):
        x = rng.uniform(-0.5, 0.5, system.nstates)
        u = rng.uniform(-0.5, 0.5, system.ninputs)
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                a = np.asarray(system.output(0.0, x, np.zeros(system.ninputs)), dtype=float)
                b = np.asarray(system.output(0.0, x, u), dtype=float)
        except Exception:  # noqa: BLE001 - not defined there: assume the worst
            return True
        if not np.array_equal(a, b, equal_nan=True):
            return True
    return False



def _signals(block, labels):
    return ", ".join(f"{block}.{p}" for p, _ in port_groups(labels))



def _strong_components(succ):
    """Tarjan's strongly connected components of a graph ``{node: successors}``."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(succ[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            out.append(component)

    for v in sorted(succ):
        if v not in index:
            visit(v)
    return out


def _cycle(component, succ):
    """One cycle through the first node of a strongly connected component, in order."""
    members = set(component)
    start = min(component)
    path, seen = [start], {start}

    def walk(v):
        for w in sorted(succ[v] & members):
            if w == start:
                return True
            if w not in seen:
                seen.add(w)
                path.append(w)
                if walk(w):
                    return True
                path.pop()
        return False

    walk(start)
    return path
