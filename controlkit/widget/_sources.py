"""The signals that drive a diagram's external inputs: constant, step, ramp, sine, pulse.

Each source is plain data (``{"kind": "step", "value": 1.0, "time": 1.0}``), checked by
:data:`SOURCE`, turned into the row of python-control's input array ``U`` by
:func:`values` and written into the exported code as the same numpy expression of the
time points ``T`` by :func:`expression` (the two agree bit for bit; the tests check it):

========  ======================================================  ======================
kind      u(t)                                                    fields (defaults)
========  ======================================================  ======================
constant  ``value``                                               value (0)
step      ``initial`` before ``time``, ``value`` from it on        value (1), time (0),
                                                                  initial (0)
ramp      ``initial + slope * max(t - time, 0)``                   slope (1), time (0),
                                                                  initial (0)
sine      ``offset + amplitude * sin(2 pi frequency t + phase)``   amplitude (1),
                                                                  frequency (1 Hz),
                                                                  phase (0 rad), offset
pulse     ``value`` for ``time <= t < time + width`` (repeated    value (1), time (0),
          every ``period`` when it is > 0), else ``initial``       width (1), period (0),
                                                                  initial (0)
========  ======================================================  ======================
"""

from __future__ import annotations

import ast

import numpy as np

from ._rules import Number, Record, Text

#: Every kind's fields and their defaults.
KINDS = {
    "constant": {"value": 0.0},
    "step": {"value": 1.0, "time": 0.0, "initial": 0.0},
    "ramp": {"slope": 1.0, "time": 0.0, "initial": 0.0},
    "sine": {"amplitude": 1.0, "frequency": 1.0, "phase": 0.0, "offset": 0.0},
    "pulse": {"value": 1.0, "time": 0.0, "width": 1.0, "period": 0.0, "initial": 0.0},
}

_BOUND = 1e12
_RULES = {"time": Number(0.0, _BOUND), "width": Number(0.0, _BOUND, positive=True),
          "period": Number(0.0, _BOUND), "frequency": Number(0.0, 1e9)}


class _Source(Record):
    """A source: ``kind`` and that kind's fields (each a finite number, some bounded)."""

    allowed = f"a source: an object with a 'kind' (one of {list(KINDS)}) and its fields"

    def __init__(self):
        super().__init__({}, {}, what=self.allowed)

    def check(self, value, path):
        if not isinstance(value, dict) or not isinstance(value.get("kind"), str) \
                or value["kind"] not in KINDS:
            kind = value.get("kind") if isinstance(value, dict) else value
            raise ValueError(f"{path}.kind: must be one of {list(KINDS)}, got "
                             f"{str(kind)[:80]!r}")
        fields = KINDS[value["kind"]]
        rule = Record({"kind": Text()}, {k: _RULES.get(k, Number(-_BOUND, _BOUND))
                                         for k in fields}, what=self.allowed)
        checked = rule.check(value, path)
        if value["kind"] == "pulse" and 0 < checked.get("period", 0.0) < checked.get(
                "width", 1.0):
            raise ValueError(f"{path}.period: must be 0 (one pulse) or at least the width "
                             f"{checked.get('width', 1.0):g}, got {checked['period']:g}")
        return {"kind": value["kind"], **{k: checked.get(k, d) for k, d in fields.items()}}


#: The rule of one source (used by the saved file's schema).
SOURCE = _Source()


def source(kind="constant", **fields):
    """A checked source of ``kind`` with ``fields`` (the others at their defaults).

    Examples
    --------
    >>> source("step", value=2.0, time=1.0)
    {'kind': 'step', 'value': 2.0, 'time': 1.0, 'initial': 0.0}
    >>> source("step", when=1.0)
    Traceback (most recent call last):
    ValueError: source: unknown field 'when'; allowed: ['initial', 'kind', 'time', 'value']
    """
    return SOURCE.check({"kind": kind, **fields}, "source")


def values(src, T):
    """The source at the time points ``T`` (python-control's ``U`` row for one input).

    Examples
    --------
    >>> values(source("step", value=2.0, time=1.0), np.array([0.0, 0.5, 1.0, 2.0])).tolist()
    [0.0, 0.0, 2.0, 2.0]
    """
    T = np.asarray(T, dtype=float)
    kind = src["kind"]
    if kind == "constant":
        return np.full_like(T, src["value"])
    if kind == "step":
        return np.where(T >= src["time"], src["value"], src["initial"])
    if kind == "ramp":
        return src["initial"] + src["slope"] * np.maximum(T - src["time"], 0.0)
    if kind == "sine":
        return src["offset"] + src["amplitude"] * np.sin(
            2 * np.pi * src["frequency"] * T + src["phase"])
    if src["period"] > 0:  # a pulse train
        on = (T >= src["time"]) & ((T - src["time"]) % src["period"] < src["width"])
    else:
        on = (T >= src["time"]) & (T < src["time"] + src["width"])
    return np.where(on, src["value"], src["initial"])


#: The same formulas as written in the exported code (names are the source's fields); a
#: term that adds zero is left out (adding 0.0 changes no number).
_TEMPLATES = {
    "constant": "np.full_like(T, value)",
    "step": "np.where(T >= time, value, initial)",
    "ramp": "initial + slope * np.maximum(T - time, 0.0)",
    "ramp from 0": "slope * np.maximum(T - time, 0.0)",
    "sine": "offset + amplitude * np.sin(2 * np.pi * frequency * T + phase)",
    "sine without offset": "amplitude * np.sin(2 * np.pi * frequency * T + phase)",
    "sine without phase": "offset + amplitude * np.sin(2 * np.pi * frequency * T)",
    "plain sine": "amplitude * np.sin(2 * np.pi * frequency * T)",
    "pulse": "np.where((T >= time) & (T < time + width), value, initial)",
    "pulse train": "np.where((T >= time) & ((T - time) % period < width), value, initial)",
}


class _Fill(ast.NodeTransformer):
    """Replaces the names of a template's fields by the source's numbers."""

    def __init__(self, numbers):
        self.numbers = numbers

    def visit_Name(self, node):
        if node.id in self.numbers:
            return ast.copy_location(ast.Constant(float(self.numbers[node.id])), node)
        return node


def expression(src):
    """The numpy expression of the source over ``T``, as an :mod:`ast` expression.

    Examples
    --------
    >>> ast.unparse(expression(source("step", value=2.0, time=1.0)))
    'np.where(T >= 1.0, 2.0, 0.0)'
    """
    src = SOURCE.check(src, "source")
    kind = src["kind"]
    if kind == "pulse" and src["period"] > 0:
        kind = "pulse train"
    elif kind == "ramp" and src["initial"] == 0:
        kind = "ramp from 0"
    elif kind == "sine":
        kind = {(True, True): "plain sine", (True, False): "sine without offset",
                (False, True): "sine without phase"}.get(
            (src["offset"] == 0, src["phase"] == 0), "sine")
    tree = ast.parse(_TEMPLATES[kind], mode="eval").body
    numbers = {k: v for k, v in src.items() if k != "kind"}
    return ast.fix_missing_locations(_Fill(numbers).visit(tree))


def describe(src):
    """A short sentence for a source (the page's list and the code's comments).

    Examples
    --------
    >>> describe(source("step", value=1.0, time=1.0))
    'step from 0 to 1 at t = 1 s'
    """
    kind = src["kind"]
    if kind == "constant":
        return f"constant {src['value']:g}"
    if kind == "step":
        return f"step from {src['initial']:g} to {src['value']:g} at t = {src['time']:g} s"
    if kind == "ramp":
        return (f"ramp of slope {src['slope']:g} from {src['initial']:g} at "
                f"t = {src['time']:g} s")
    if kind == "sine":
        return (f"sine of amplitude {src['amplitude']:g} at {src['frequency']:g} Hz, phase "
                f"{src['phase']:g} rad, offset {src['offset']:g}")
    train = f", every {src['period']:g} s" if src["period"] > 0 else ""
    return (f"pulse of {src['value']:g} from t = {src['time']:g} s for {src['width']:g} s"
            f"{train} (else {src['initial']:g})")


def short(src):
    """A few characters for a source, written beside its input in the diagram.

    Examples
    --------
    >>> short(source("step", value=1.0, time=1.0)), short(source("constant", value=2.5))
    ('step 1 at 1 s', '2.5')
    """
    kind = src["kind"]
    if kind == "constant":
        return f"{src['value']:g}"
    start = f" at {src['time']:g} s" if src.get("time") else ""
    if kind == "step":
        base = f"{src['initial']:g} \u2192 " if src["initial"] else ""
        return f"step {base}{src['value']:g}{start}"
    if kind == "ramp":
        return f"ramp {src['slope']:g}/s{start}"
    if kind == "sine":
        offset = f"{src['offset']:g} + " if src["offset"] else ""
        return f"{offset}{src['amplitude']:g} sin {src['frequency']:g} Hz"
    every = f" every {src['period']:g} s" if src["period"] > 0 else ""
    return f"pulse {src['value']:g}{start}, {src['width']:g} s{every}"
