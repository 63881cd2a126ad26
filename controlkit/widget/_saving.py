"""The editor's diagram read from an interconnect, saved as JSON-ready data and read back
through the schema.

Blocks are saved by recipe (a palette entry with its checked keyword arguments, or the
notebook's variable that held them); a block the editor cannot rebuild is saved by name
and found again, when the file is read, among the blocks given (``systems=``). Reading
goes through :func:`._schema.read` first: a file is data, and nothing in it is run.
"""

from __future__ import annotations

import copy
import json

import control as ct
import numpy as np

from . import _palette, _schema
from ._calls import check_identifier
from ._parts import Block, Wire
from ._recognise import recognise


def to_dict(model):
    """The diagram as JSON-ready data (blocks by recipe; others by name)."""
    blocks = []
    for name, b in model.blocks.items():
        s = b.system
        blocks.append({"name": name, "recipe": b.recipe, "label": b.label,
                       "position": list(b.position) if b.position else None,
                       "look": b.look,
                       "inputs": list(s.input_labels), "outputs": list(s.output_labels),
                       "dt": _dt_json(s.dt)})
    return {
        "format": _schema.FORMAT, "name": model.name, "blocks": blocks,
        "wires": [[*w.src, *w.dst, w.gain] for w in model.wires],
        "inputs": [[n, [list(t) for t in targets]] for n, targets in model.inputs],
        "outputs": [[n, [list(s) for s in sources]] for n, sources in model.outputs],
        "summed": sorted(list(d) for d in model.summed),
        "hints": model.hints,
        "setup": {"horizon": model.horizon, "sources": model.sources,
                  "initial": model.initial},
    }


def from_interconnect(cls, sys, *, source_name=None):
    """A ``cls`` (a :class:`~controlkit.widget.DiagramModel`) of the interconnect ``sys``.

    See :meth:`~controlkit.widget.DiagramModel.from_interconnect`.
    """
    if not isinstance(sys, ct.InterconnectedSystem):
        raise ValueError(f"sys must be a control.InterconnectedSystem (built with "
                         f"control.interconnect), got {type(sys).__name__}")
    if source_name is not None:
        check_identifier(source_name, "source_name")
    hints = copy.deepcopy(dict(getattr(sys, "drawing_hints", None) or {}))
    labels = dict(hints.pop("labels", {}))
    for s in sys.syslist:  # a block's own junction (r - h in front of F), as drawn
        if getattr(s, "junction", None):
            hints.setdefault("sums", {}).setdefault(s.name, dict(s.junction))
    model = cls(name=sys.name, hints=hints, source_name=source_name)
    out_owner, in_owner = [], []
    for s in sys.syslist:
        if s.name in model.blocks:
            raise ValueError(f"two blocks are named {s.name!r}; the editor needs unique "
                             f"block names")
        label = labels.get(s.name, getattr(s, "display_name", None))
        model.blocks[s.name] = Block(s, recognise(s), label)
        out_owner += [(s.name, label) for label in s.output_labels]
        in_owner += [(s.name, label) for label in s.input_labels]
    drivers = {}
    for i, dst in enumerate(in_owner):
        for j in np.nonzero(sys.connect_map[i])[0]:
            model.wires.append(Wire(out_owner[j], dst, float(sys.connect_map[i, j])))
            drivers[dst] = drivers.get(dst, 0) + 1
    for e, name in enumerate(sys.input_labels):
        targets = [(*in_owner[i], float(sys.input_map[i, e]))
                   for i in np.nonzero(sys.input_map[:, e])[0]]
        for block, signal, _ in targets:
            drivers[(block, signal)] = drivers.get((block, signal), 0) + 1
        model.inputs.append((name, targets))
    n_out = len(out_owner)
    for r, name in enumerate(sys.output_labels):
        sources = []
        for j in np.nonzero(sys.output_map[r])[0]:
            side, (block, signal) = ("out", out_owner[j]) if j < n_out else (
                "in", in_owner[j - n_out])
            sources.append((side, block, signal, float(sys.output_map[r, j])))
        model.outputs.append((name, sources))
    model.summed = {dst for dst, n in drivers.items() if n > 1}  # sums written in code
    return model


def parse(text):
    """A saved diagram's JSON text as data, refusing a file too large to be a diagram."""
    if isinstance(text, bytes):
        text = text.decode("utf-8")
    if len(text) > _schema.LIMITS["bytes"]:
        raise ValueError(f"a saved diagram is at most {_schema.LIMITS['bytes']:,} characters "
                         f"of JSON; this one has {len(text):,}")
    try:  # (an integer of thousands of digits: read as a float, which the schema refuses)
        return json.loads(text, parse_int=lambda digits: int(digits) if len(digits) < 400
                          else float(digits))
    except (json.JSONDecodeError, RecursionError) as error:
        raise ValueError(f"not a saved diagram: the file is not JSON ({error})") from None


def from_dict(cls, data, *, systems=None, namespace=None):
    """A ``cls`` (a :class:`~controlkit.widget.DiagramModel`) saved by :func:`to_dict`.

    See :meth:`~controlkit.widget.DiagramModel.from_dict`.
    """
    data = _schema.read(data)
    if isinstance(systems, ct.InterconnectedSystem):
        systems = {s.name: s for s in systems.syslist}
    systems, namespace = dict(systems or {}), dict(namespace or {})
    model = cls(name=data["name"], hints=data.get("hints") or {},
                source_name=data.get("source_name"))
    for i, saved in enumerate(data["blocks"]):
        name, recipe = saved["name"], saved["recipe"]
        if recipe and recipe["kind"] in _palette.PALETTE:
            system = _palette.build(recipe["kind"], name, recipe["kwargs"],
                                    recipe.get("sampled"))
        elif recipe and recipe["kind"] == "variable":
            if recipe["variable"] not in namespace:
                raise ValueError(f"blocks[{i}].recipe.variable: block {name!r} was the "
                                 f"notebook's variable {recipe['variable']!r}, which is not "
                                 f"in namespace")
            system = namespace[recipe["variable"]]
            if not _palette.is_system(system):
                raise ValueError(f"variable {recipe['variable']!r} holds a "
                                 f"{type(system).__name__}, not a python-control system")
            if system.name != name:
                system = system.copy(name=name)
        else:
            if name not in systems:
                raise ValueError(f"blocks[{i}]: block {name!r} was taken from an opened "
                                 f"diagram and cannot be rebuilt from the file; pass that "
                                 f"diagram (or {{name: system}}) as systems=")
            system = systems[name]
        if (list(system.input_labels), list(system.output_labels)) != (
                saved["inputs"], saved["outputs"]):
            raise ValueError(f"block {name!r} has inputs {system.input_labels} and outputs "
                             f"{system.output_labels}, the saved diagram expects "
                             f"{saved['inputs']} and {saved['outputs']}")
        model.blocks[name] = Block(system, recipe, saved.get("label"),
                                   tuple(saved["position"]) if saved.get("position") else None,
                                   saved.get("look"))
    model.wires = [Wire((a, b), (c, d), g) for a, b, c, d, g in data.get("wires", [])]
    model.inputs = [(n, [tuple(t) for t in targets]) for n, targets in data.get("inputs", [])]
    model.outputs = [(n, [tuple(s) for s in sources])
                     for n, sources in data.get("outputs", [])]
    model.summed = {tuple(d) for d in data.get("summed", [])}
    setup = data.get("setup", {})
    model.horizon = setup.get("horizon", model.horizon)
    model.sources = dict(setup.get("sources", {}))
    for name, values in setup.get("initial", {}).items():
        model.set_initial(name, values)  # checks the number of states
    return model


def _dt_json(dt):
    """A block's dt as JSON keeps it: None and True as they are, a period as a float."""
    return dt if dt is None or dt is True else float(dt)
