"""The editor's diagram saved as JSON-ready data and read back.

Blocks are saved by recipe (a palette call, or the notebook's variable that held them);
a block taken as it is from an opened diagram is saved by name, and found again in that
diagram when the data is read.
"""

from __future__ import annotations

import control as ct

from . import _palette
from ._parts import FORMAT, Block, Wire, timebase


def to_dict(model):
    """The diagram as JSON-ready data (blocks by recipe; opened blocks by name)."""
    blocks = []
    for name, b in model.blocks.items():
        s = b.system
        blocks.append({"name": name, "recipe": b.recipe, "label": b.label,
                       "position": list(b.position) if b.position else None,
                       "look": b.look,
                       "inputs": list(s.input_labels), "outputs": list(s.output_labels),
                       "dt": _dt_json(s.dt)})
    return {
        "format": FORMAT, "name": model.name, "source_name": model.source_name,
        "blocks": blocks,
        "wires": [[*w.src, *w.dst, w.gain] for w in model.wires],
        "inputs": [[n, [list(t) for t in targets]] for n, targets in model.inputs],
        "outputs": [[n, [list(s) for s in sources]] for n, sources in model.outputs],
        "summed": sorted(list(d) for d in model.summed),
        "hints": model.hints,
    }


def from_dict(cls, data, *, systems=None, namespace=None):
    """A ``cls`` (a :class:`~controlkit.widget.DiagramModel`) saved by :func:`to_dict`.

    See :meth:`~controlkit.widget.DiagramModel.from_dict`.
    """
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f"not a saved diagram: the data must have format {FORMAT!r}")
    if isinstance(systems, ct.InterconnectedSystem):
        systems = {s.name: s for s in systems.syslist}
    systems, namespace = dict(systems or {}), dict(namespace or {})
    model = cls(name=data["name"], hints=data.get("hints") or {},
                source_name=data.get("source_name"))
    for saved in data["blocks"]:
        name, recipe = saved["name"], saved["recipe"]
        period = saved["dt"]
        if recipe and recipe["kind"] in _palette.PALETTE:
            system = _palette.build(recipe["kind"], name, recipe["kwargs"],
                                    period if timebase(period) == "discrete" else None)
        elif recipe and recipe["kind"] == "variable":
            if recipe["variable"] not in namespace:
                raise ValueError(f"block {name!r} was the notebook's variable "
                                 f"{recipe['variable']!r}, which is not in namespace")
            system = namespace[recipe["variable"]]
            if not _palette.is_system(system):
                raise ValueError(f"variable {recipe['variable']!r} holds a "
                                 f"{type(system).__name__}, not a python-control system")
            if system.name != name:
                system = system.copy(name=name)
        else:
            if name not in systems:
                raise ValueError(f"block {name!r} was taken from an opened diagram; pass "
                                 f"that diagram (or {{name: system}}) as systems=")
            system = systems[name]
        if (list(system.input_labels), list(system.output_labels)) != (
                saved["inputs"], saved["outputs"]):
            raise ValueError(f"block {name!r} has inputs {system.input_labels} and outputs "
                             f"{system.output_labels}, the saved diagram expects "
                             f"{saved['inputs']} and {saved['outputs']}")
        model.blocks[name] = Block(system, recipe, saved["label"],
                                   tuple(saved["position"]) if saved["position"] else None,
                                   saved.get("look"))
    model.wires = [Wire((a, b), (c, d), g) for a, b, c, d, g in data["wires"]]
    model.inputs = [(n, [tuple(t) for t in targets]) for n, targets in data["inputs"]]
    model.outputs = [(n, [tuple(s) for s in sources]) for n, sources in data["outputs"]]
    model.summed = {tuple(d) for d in data["summed"]}
    return model


def _dt_json(dt):
    """A block's dt as JSON keeps it: None and True as they are, a period as a float."""
    return dt if dt is None or dt is True else float(dt)
