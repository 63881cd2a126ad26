"""The saved diagram's format, read by a schema: every field checked, nothing evaluated.

A saved diagram is data whoever wrote it (a course shares diagram files): this module is
the one place that reads it. Every key and value is checked against what the format
allows - names, identifiers, finite numbers, short strings, lists of numbers, bounded
sizes - and a file that breaks a rule raises a ValueError naming the field by its JSON
path (``blocks[2].recipe.kwargs``) and what is allowed there. Recipes name entries of the
editor's fixed palette (:mod:`._palette`), whose keyword arguments are checked by the
entry's own rules; nothing of the file is ever passed to ``eval``, ``exec`` or the
import system.

Format ``controlkit.widget/2`` (``/1``, written before the schema, is read and migrated:
it was plain JSON data too)::

    {"format": "controlkit.widget/2", "name": str,
     "blocks": [{"name", "recipe", "label", "position", "look", "inputs", "outputs", "dt"}],
     "wires": [[block, signal, block, signal, gain]],
     "inputs": [[name, [[block, signal, gain]]]],
     "outputs": [[name, [["out" | "in", block, signal, gain]]]],
     "summed": [[block, signal]], "hints": {...},
     "setup": {"horizon": seconds, "sources": {input: source}, "initial": {block: [x0]}}}
"""

from __future__ import annotations

from ._palette import PALETTE
from ._rules import (
    FORMAT,
    LIMITS,
    NAME,
    OLD_FORMATS,
    Flag,
    Identifier,
    Items,
    Mapping,
    Number,
    Optional,
    Record,
    Row,
    Rule,
    Text,
    Timebase,
)
from ._sources import SOURCE

__all__ = ["FORMAT", "LIMITS", "OLD_FORMATS", "read"]

# ---------------------------------------------------------------------- the file

_SIGN = Number(-1.0, 1.0)
_GAIN = Number()
_POSITION = Optional(Row(Number(-1e6, 1e6), Number(-1e6, 1e6)))
_LOOK = Optional(Record({}, {
    "w": Number(0.0, 5000.0), "h": Number(0.0, 5000.0), "flip": Flag(),
    "order": Mapping(Text(choices=("in", "out")), Mapping(NAME, Number(-1e6, 1e6)), 2)}))
_HINTS = Record({}, {
    "labels": Mapping(NAME, Text()),
    "groups": Mapping(Text(), Items(NAME, LIMITS["blocks"]), 50),
    "beside": Mapping(NAME, NAME),
    "rows": Mapping(NAME, Number(-100, 100, integer=True)),
    "notes": Mapping(NAME, Text()),
    "sums": Mapping(NAME, Mapping(NAME, _SIGN, 50)),
    "title": Optional(Text()),
    "outputs": Items(NAME, LIMITS["signals"]),  # the declared outputs drawn as arrows
}, what="an object of drawing hints")


def _recipe_rule():
    return _Recipe(PALETTE)


class _Recipe(Rule):
    """A block's recipe: a palette entry and its keyword arguments, or a notebook variable."""

    allowed = "null, a palette recipe or a notebook variable"

    def __init__(self, palette):
        self.palette = palette

    def check(self, value, path):
        if value is None:
            return None
        if not isinstance(value, dict) or "kind" not in value:
            raise ValueError(f"{path}: must be null or an object with a 'kind' "
                             f"(a palette entry, or 'variable')")
        kind = value["kind"]
        if kind == "variable":
            return Record({"kind": Text(), "variable": Identifier()},
                          {"system_name": NAME}).check(value, path)
        if not isinstance(kind, str) or kind not in self.palette:
            raise ValueError(f"{path}.kind: must be 'variable' or a palette entry, one of "
                             f"{sorted(self.palette)}; got {str(kind)[:80]!r}")
        entry = self.palette[kind]
        checked = Record({"kind": Text(), "kwargs": Record({})},
                         {"sampled": Optional(Record({"Ts": Number(positive=True, high=1e6)}, {
                             "method": Text(choices=("rk4", "solve_ivp")),
                             "substeps": Number(1, 10_000, integer=True)}))}
                         ).check({**value, "kwargs": {}}, path)
        checked["kwargs"] = entry.check_kwargs(value.get("kwargs"), f"{path}.kwargs")
        return checked


def _block_rule():
    return Record({"name": NAME, "recipe": _recipe_rule(), "inputs": Items(NAME, LIMITS[
        "signals"]), "outputs": Items(NAME, LIMITS["signals"]), "dt": Timebase()},
        {"label": Optional(Text()), "position": _POSITION, "look": _LOOK},
        what="a block")


def _setup_rule():
    return Record({}, {"horizon": Number(positive=True, high=1e9),
                       "sources": Mapping(NAME, SOURCE),
                       "initial": Mapping(NAME, Items(Number(), LIMITS["signals"]))},
                  what="the run's setup")


def read(data):
    """The saved diagram ``data`` (parsed JSON), checked field by field.

    Returns
    -------
    dict
        The same structure with every value checked (numbers as floats).

    Raises
    ------
    ValueError
        Naming the first field that breaks the format, by its JSON path, and what is
        allowed there.

    Examples
    --------
    >>> read({"format": "controlkit.widget/2", "name": "x", "blocks": [{"name": "a",
    ...       "recipe": {"kind": "gain", "kwargs": {"k": "1; import os"}},
    ...       "inputs": ["u"], "outputs": ["y"], "dt": None}]})
    Traceback (most recent call last):
    ValueError: blocks[0].recipe.kwargs.k: must be a finite number, got '1; import os'
    """
    if not isinstance(data, dict):
        raise ValueError(f"a saved diagram must be a JSON object, got {type(data).__name__}")
    version = data.get("format")
    if version in OLD_FORMATS:
        data = _migrate(data)
    elif version != FORMAT:
        raise ValueError(f"format: not a saved diagram: the format must be {FORMAT!r} (or "
                         f"the older {', '.join(map(repr, OLD_FORMATS))}), got "
                         f"{str(version)[:80]!r}")
    rule = Record({"format": Text(), "name": NAME, "blocks": Items(_block_rule(), LIMITS[
        "blocks"])}, {
        "wires": Items(Row(NAME, NAME, NAME, NAME, _GAIN), LIMITS["wires"]),
        "inputs": Items(Row(NAME, Items(Row(NAME, NAME, _GAIN), LIMITS["signals"])),
                        LIMITS["signals"]),
        "outputs": Items(Row(NAME, Items(Row(Text(choices=("out", "in")), NAME, NAME, _GAIN),
                                         LIMITS["signals"])), LIMITS["signals"]),
        "summed": Items(Row(NAME, NAME), LIMITS["wires"]),
        "hints": _HINTS, "setup": _setup_rule(),
        "source_name": Optional(Identifier())}, what="a saved diagram")
    checked = rule.check(data, "")
    _check_references(checked)
    return checked


def _migrate(data):
    """Format 1 (plain JSON data as well) in format 2's shape."""
    data = dict(data)
    data["format"] = FORMAT
    blocks = []
    for i, saved in enumerate(data.get("blocks") or []):
        if not isinstance(saved, dict):
            raise ValueError(f"blocks[{i}]: must be a block, got {type(saved).__name__}")
        saved = dict(saved)
        recipe = saved.get("recipe")
        if isinstance(recipe, dict) and recipe.get("kind") not in (None, "variable"):
            # format 1 sampled a plant or an LTI palette block when the diagram was discrete
            recipe = dict(recipe)
            kind = recipe.get("kind")
            entry = PALETTE.get(kind) if isinstance(kind, str) else None
            dt = saved.get("dt")
            if entry is not None and entry.follows_period and isinstance(dt, (int, float)) \
                    and not isinstance(dt, bool) and dt > 0 and "sampled" not in recipe:
                recipe["sampled"] = {"Ts": dt}
            saved["recipe"] = recipe
        blocks.append(saved)
    data["blocks"] = blocks
    return data


def _check_references(data):
    """Wires, inputs, outputs and hints name blocks and signals the file declares."""
    signals = {}
    for i, b in enumerate(data["blocks"]):
        if b["name"] in signals:
            raise ValueError(f"blocks[{i}].name: two blocks are named {b['name']!r}")
        signals[b["name"]] = (set(b["inputs"]), set(b["outputs"]))

    def needs(block, signal, side, path):
        if block not in signals:
            raise ValueError(f"{path}: names no block of the file: {block!r}")
        if signal not in signals[block][0 if side == "in" else 1]:
            raise ValueError(f"{path}: block {block!r} has no {side}put signal {signal!r}")

    for i, (a, s, b, d, _) in enumerate(data.get("wires", [])):
        needs(a, s, "out", f"wires[{i}]")
        needs(b, d, "in", f"wires[{i}]")
    for i, (_, targets) in enumerate(data.get("inputs", [])):
        for j, (b, s, _) in enumerate(targets):
            needs(b, s, "in", f"inputs[{i}][1][{j}]")
    for i, (_, sources) in enumerate(data.get("outputs", [])):
        for j, (side, b, s, _) in enumerate(sources):
            needs(b, s, side, f"outputs[{i}][1][{j}]")
    for i, (b, s) in enumerate(data.get("summed", [])):
        needs(b, s, "in", f"summed[{i}]")
    setup = data.get("setup", {})
    inputs = {name for name, _ in data.get("inputs", [])}
    for name in setup.get("sources", {}):
        if name not in inputs:
            raise ValueError(f"setup.sources[{name!r}]: names no external input of the file")
    for name in setup.get("initial", {}):
        if name not in signals:
            raise ValueError(f"setup.initial[{name!r}]: names no block of the file")
