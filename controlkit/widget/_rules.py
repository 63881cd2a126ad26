"""The rules a value read from a saved diagram must follow: names, identifiers, finite
numbers, bounded lists, records with known fields (used by :mod:`._schema`, the palette's
keyword arguments and the sources).

Each :class:`Rule` checks one value and returns it as the model keeps it, or raises a
ValueError naming the value's JSON path and what is allowed there.
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
        shown = repr(value) if not isinstance(value, int) or abs(value) < 10 ** 80 else (
            f"an integer of {int(math.log10(abs(value))) + 1} digits")  # (str() has a limit)
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
        try:
            number = float(value)
        except OverflowError:  # (an integer beyond floats)
            self.refuse(value, path)
        if self.integer and not (isinstance(value, int) or number.is_integer()):
            self.refuse(value, path)
        if not math.isfinite(number) or (self.positive and value <= 0) or (
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
