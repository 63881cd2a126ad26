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

import math
import re

from ._calls import is_identifier

FORMAT = "controlkit.widget/2"
OLD_FORMATS = ("controlkit.widget/1",)

#: Bounds that keep a hostile file from asking for huge work or memory.
LIMITS = {"blocks": 500, "wires": 20_000, "signals": 2_000, "name": 100, "text": 300,
          "numbers": 10_000, "matrix": 200, "bytes": 5_000_000}

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]")


class Rule:
    """A check of one value; :meth:`check` returns the value as the model keeps it."""

    allowed = "a value"

    def check(self, value, path):
        raise NotImplementedError

    def refuse(self, value, path):
        shown = repr(value)
        if len(shown) > 80:
            shown = shown[:77] + "..."
        raise ValueError(f"{path}: must be {self.allowed}, got {shown}")


class Number(Rule):
    """A finite number, optionally within ``[low, high]`` (or ``> 0`` with ``positive``)."""

    def __init__(self, low=None, high=None, *, positive=False, integer=False):
        self.low, self.high, self.positive, self.integer = low, high, positive, integer
        kind = "an integer" if integer else "a finite number"
        if positive:
            kind += " > 0"
        if low is not None and high is not None:
            kind += f" in [{low:g}, {high:g}]"
        elif low is not None:
            kind += f" >= {low:g}"
        elif high is not None:
            kind += f" <= {high:g}"
        self.allowed = kind

    def check(self, value, path):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            self.refuse(value, path)
        if self.integer and not (isinstance(value, int) or float(value).is_integer()):
            self.refuse(value, path)
        if not math.isfinite(value) or (self.positive and value <= 0) or (
                self.low is not None and value < self.low) or (
                self.high is not None and value > self.high):
            self.refuse(value, path)
        return int(value) if self.integer else float(value)


class Flag(Rule):
    allowed = "true or false"

    def check(self, value, path):
        if not isinstance(value, bool):
            self.refuse(value, path)
        return value


class Text(Rule):
    """A string of at most ``size`` characters, no control characters (no newline)."""

    def __init__(self, size=None, *, pattern=None, choices=None, what=None):
        self.size = size or LIMITS["text"]
        self.pattern = re.compile(pattern) if pattern else None
        self.choices = choices
        self.allowed = what or (f"one of {list(choices)}" if choices else
                                f"a string of at most {self.size} characters without "
                                f"control characters (no newline)")

    def check(self, value, path):
        if (not isinstance(value, str) or len(value) > self.size or _CONTROL.search(value)
                or (self.pattern and not self.pattern.fullmatch(value))
                or (self.choices and value not in self.choices)):
            self.refuse(value, path)
        return value


class Identifier(Rule):
    allowed = "a Python identifier (letters, digits and _, not a keyword)"

    def check(self, value, path):
        if not is_identifier(value) or len(value) > LIMITS["name"]:
            self.refuse(value, path)
        return value


#: A block's or a signal's name: what python-control accepts (no dot), printable, short.
NAME = Text(LIMITS["name"], pattern=r"[^.]+",
            what=f"a name of 1 to {LIMITS['name']} characters without '.' or control "
                 f"characters")


class Optional(Rule):
    def __init__(self, rule):
        self.rule = rule
        self.allowed = f"null or {rule.allowed}"

    def check(self, value, path):
        if value is None:
            return None
        try:
            return self.rule.check(value, path)
        except ValueError as error:
            if str(error).startswith(f"{path}: must be "):  # this value, not one inside it
                self.refuse(value, path)
            raise


class Either(Rule):
    def __init__(self, *rules):
        self.rules = rules
        self.allowed = " or ".join(r.allowed for r in rules)

    def check(self, value, path):
        for rule in self.rules:
            try:
                return rule.check(value, path)
            except ValueError:
                continue
        self.refuse(value, path)


class Items(Rule):
    """A list of at most ``size`` values, each checked by ``rule``."""

    def __init__(self, rule, size=None, *, least=0):
        self.rule, self.size, self.least = rule, size or LIMITS["numbers"], least
        self.allowed = (f"a list of {least} to {self.size} items, each {rule.allowed}"
                        if least else f"a list of at most {self.size} items, each "
                                      f"{rule.allowed}")

    def check(self, value, path):
        if not isinstance(value, list) or not self.least <= len(value) <= self.size:
            self.refuse(value, path)
        return [self.rule.check(v, f"{path}[{i}]") for i, v in enumerate(value)]


class Row(Rule):
    """A list of fixed length whose items follow their own rules (``[block, signal, 1.0]``)."""

    def __init__(self, *rules):
        self.rules = rules
        self.allowed = "[" + ", ".join(r.allowed for r in rules) + "]"

    def check(self, value, path):
        if not isinstance(value, list) or len(value) != len(self.rules):
            self.refuse(value, path)
        return [r.check(v, f"{path}[{i}]") for i, (r, v) in enumerate(zip(self.rules, value,
                                                                          strict=True))]


class Mapping(Rule):
    """A dict of at most ``size`` entries, keys by ``keys``, values by ``values``."""

    def __init__(self, keys, values, size=None):
        self.keys, self.values, self.size = keys, values, size or LIMITS["signals"]
        self.allowed = f"an object of at most {self.size} entries"

    def check(self, value, path):
        if not isinstance(value, dict) or len(value) > self.size:
            self.refuse(value, path)
        out = {}
        for k, v in value.items():
            self.keys.check(k, f"{path} key")
            out[k] = self.values.check(v, f"{path}[{k!r}]")
        return out


class Record(Rule):
    """A dict with known keys: ``required`` must be there, ``optional`` may be."""

    def __init__(self, required, optional=None, what="an object"):
        self.required, self.optional = dict(required), dict(optional or {})
        self.allowed = what

    def check(self, value, path):
        where = path or "diagram"  # the file itself
        if not isinstance(value, dict):
            self.refuse(value, where)
        known = {**self.required, **self.optional}
        unknown = [k for k in value if k not in known]
        if unknown:
            raise ValueError(f"{where}: unknown field {str(unknown[0])[:80]!r}; allowed: "
                             f"{sorted(known)}")
        missing = [k for k in self.required if k not in value]
        if missing:
            raise ValueError(f"{where}: missing field {missing[0]!r}")
        return {k: known[k].check(v, f"{path}.{k}" if path else k) for k, v in value.items()}


def matrix(size=None):
    """A list of rows of finite numbers (a matrix), at most ``size`` rows and columns."""
    size = size or LIMITS["matrix"]
    return Items(Items(Number(), size), size)


class Timebase(Rule):
    allowed = "null (any timebase), true (discrete), 0 (continuous) or a period > 0"

    def check(self, value, path):
        if value is None or value is True:
            return value
        return Number(low=0.0).check(value, path)


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
}, what="an object of drawing hints")


def _recipe_rule():
    from ._palette import PALETTE

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
                         {"sampled": Optional(Record({"Ts": Number(positive=True)}, {
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
    from ._sources import SOURCE

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
            from ._palette import PALETTE

            entry = PALETTE.get(recipe.get("kind"))
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
