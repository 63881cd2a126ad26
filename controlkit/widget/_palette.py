"""The blocks the editor can build: a fixed registry of constructors with checked arguments.

Every entry turns a recipe - its key and keyword arguments (``kwargs``) - into a call
tree (:mod:`._calls`), which is both evaluated to build the block and written as the
Python that builds it (:meth:`DiagramModel.code`): the block in the editor and the
written code are one description. Every keyword argument has a rule
(:mod:`._schema`): a recipe read from a file is checked before anything is built.

Entries with ``shown=False`` are not in the palette: they are how the editor rebuilds
the blocks of an opened diagram that it recognises (state-space blocks, summing
junctions, controlkit's factories; see :mod:`._recognise`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control as ct
import numpy as np

from ._calls import IMPORTS, Clip, Op, call, evaluate, source
from ._rules import LIMITS, NAME, Flag, Identifier, Items, Number, Rule, Text, Timebase, matrix

__all__ = ["ENTRIES", "IMPORTS", "PALETTE", "PaletteEntry", "build", "defaults", "is_system"]

_SIGNALS = Items(NAME, LIMITS["signals"])


class _Signs(Rule):
    allowed = "a string of 2 to 16 characters '+' or '-'"

    def check(self, value, path):
        if not isinstance(value, str) or not 2 <= len(value) <= 16 or set(value) - {"+", "-"}:
            self.refuse(value, path)
        return value


class _JunctionInputs(Rule):
    allowed = "a list of 1 to 50 signal names, each optionally preceded by '-'"

    def check(self, value, path):
        names = Items(Text(LIMITS["name"] + 1), 50, least=1).check(value, path)
        for i, n in enumerate(names):
            NAME.check(n[1:] if n.startswith("-") else n, f"{path}[{i}]")
        return names


@dataclass(frozen=True)
class PaletteEntry:
    """One kind of block the editor can build.

    Attributes
    ----------
    key : str
        Identifier (stored in saved diagrams).
    title : str
        What the palette shows.
    group : str
        ``"python-control"`` or ``"controlkit"``.
    name : str
        Default block name (made unique with a number when taken).
    defaults : dict
        Keyword arguments of a new block; ``Ts`` is filled with the diagram's period.
    rules : dict
        The rule (:class:`~controlkit.widget._rules.Rule`) of each keyword argument; no
        other keyword is accepted.
    make : callable
        ``make(name, kwargs)``: the call tree of the block (continuous for an LTI entry:
        ``(num, den)`` or an expression of transfer functions).
    lti : bool
        A linear block, sampled with ``control.sample_system`` in a discrete diagram.
    follows_period : bool
        A continuous block (a plant, an LTI design) that joins a discrete diagram
        sampled at its period under zero-order hold.
    shown : bool
        Listed in the palette (else used to rebuild recognised blocks only).
    """

    key: str
    title: str
    group: str
    name: str
    defaults: dict = field(default_factory=dict)
    rules: dict = field(default_factory=dict)
    make: object = None
    lti: bool = False
    follows_period: bool = False
    shown: bool = True
    required: tuple = ()

    def check_kwargs(self, kwargs, path="kwargs"):
        """``kwargs`` checked against :attr:`rules` (a ValueError names the bad one)."""
        if not isinstance(kwargs, dict):
            raise ValueError(f"{path}: must be an object of keyword arguments, got "
                             f"{type(kwargs).__name__}")
        for key in kwargs:
            if key not in self.rules:
                shown = repr(key) if len(repr(key)) <= 80 else repr(key)[:77] + "..."
                raise ValueError(f"{path}: {self.key!r} takes no keyword argument {shown}; "
                                 f"allowed: {sorted(self.rules) or 'none'}")
        for key in self.required:
            if key not in kwargs:
                raise ValueError(f"{path}: {self.key!r} needs the keyword argument {key!r}")
        return {k: self.rules[k].check(v, f"{path}.{k}") for k, v in kwargs.items()}

    def parameters(self, kwargs):
        """The numeric keyword arguments, which the editor shows as sliders."""
        return {k: v for k, v in kwargs.items() if k != "Ts" and isinstance(
            self.rules.get(k), Number) and not self.rules[k].integer}

    def tree(self, name, kwargs, sampled=None):
        """The call tree that builds this block named ``name``; ``sampled`` ``{"Ts": ...}``
        samples it under zero-order hold."""
        kwargs = self.check_kwargs(kwargs)
        core = self.make(name, kwargs)
        if self.lti:
            labels = {"inputs": "u", "outputs": "y", "name": name}
            tf = call("ct.tf", *core) if isinstance(core, tuple) else core
            if sampled:
                return call("ct.sample_system", tf, float(sampled["Ts"]), **labels)
            if isinstance(core, tuple):
                return call("ct.tf", *core, **labels)
            return call("ct.tf", core, **labels)
        if sampled:
            options = {k: sampled[k] for k in ("method", "substeps") if k in sampled}
            return call("controlkit.sample_nlsys", core, float(sampled["Ts"]), **options)
        return core

    def source(self, name, kwargs, sampled=None):
        """Python source of the call that builds this block named ``name``."""
        return source(self.tree(name, kwargs, sampled))


def _factory(function):
    """``make`` for a controlkit factory: its keyword arguments and ``name``."""
    def make(name, kwargs):
        return call(function, **kwargs, name=name)
    return make


def _pid(name, kw):
    s = call("ct.tf", "s")
    integral = Op(kw["ki"], "/", s)
    derivative = Op(Op(kw["kd"], "*", s), "/", Op(Op(kw["tf"], "*", s), "+", 1))
    return Op(Op(kw["kp"], "+", integral), "+", derivative)


def _junction(name, kw):
    signs = kw["signs"]
    return call("ct.summing_junction",
                inputs=[f"{'-' if s == '-' else ''}u{i + 1}" for i, s in enumerate(signs)],
                output="y", name=name)


def _state_space(name, kw):
    extra = {k: kw[k] for k in ("dt", "inputs", "outputs", "states") if k in kw}
    return call("ct.ss", kw["A"], kw["B"], kw["C"], kw["D"], **extra, name=name)


def _transfer(name, kw):
    extra = {k: kw[k] for k in ("dt", "inputs", "outputs") if k in kw}
    return call("ct.tf", kw["num"], kw["den"], **extra, name=name)


_REAL = Number()
_POSITIVE = Number(positive=True)
_POLY = Items(Number(), 30, least=1)
_PERIOD = Number(positive=True, high=1e6)

ENTRIES = [
    PaletteEntry("gain", "gain", "python-control", "gain", {"k": 2.0}, {"k": _REAL},
                 lambda n, kw: call("ct.tf", kw["k"], 1, dt=None, inputs="u", outputs="y",
                                    name=n)),
    PaletteEntry("transfer_function", "transfer function", "python-control", "tf",
                 {"num": [1.0], "den": [1.0, 1.0]}, {"num": _POLY, "den": _POLY},
                 lambda n, kw: (kw["num"], kw["den"]), lti=True, follows_period=True),
    PaletteEntry("pi", "PI controller", "python-control", "pi", {"kp": 1.0, "ki": 0.1},
                 {"kp": _REAL, "ki": _REAL},
                 lambda n, kw: ([kw["kp"], kw["ki"]], [1.0, 0.0]), lti=True,
                 follows_period=True),
    PaletteEntry("pid", "PID controller", "python-control", "pid",
                 {"kp": 1.0, "ki": 0.1, "kd": 0.1, "tf": 0.01},
                 {"kp": _REAL, "ki": _REAL, "kd": _REAL, "tf": _POSITIVE}, _pid, lti=True,
                 follows_period=True),
    PaletteEntry("summing_junction", "summing junction", "python-control", "sum",
                 {"signs": "+-"}, {"signs": _Signs()}, _junction),
    PaletteEntry("saturation", "saturation", "python-control", "saturation", {"limit": 1.0},
                 {"limit": _POSITIVE},
                 lambda n, kw: call("ct.nlsys", None, Clip(-kw["limit"], kw["limit"]),
                                    inputs="u", outputs="y", dt=None, name=n)),
    PaletteEntry("spacecraft_plant", "spacecraft plant", "controlkit", "plant", {}, {},
                 _factory("sc.spacecraft_plant"), follows_period=True),
    PaletteEntry("io_linearizer", "IO linearizer", "controlkit", "linearizer", {}, {},
                 _factory("sc.io_linearizer")),
    PaletteEntry("attitude_output", "attitude output h(q)", "controlkit", "output", {}, {},
                 _factory("sc.attitude_output")),
    PaletteEntry("outer_controller", "outer controller F", "controlkit", "controller",
                 {"F": 0.0009, "output": "mu"}, {"F": _POSITIVE, "output": Identifier()},
                 _factory("sc.outer_controller")),
    PaletteEntry("nominal_model", "nominal model L_n", "controlkit", "nominal", {"Ts": 0.1},
                 {"Ts": _PERIOD, "h0": Items(Number(), 2, least=2)},
                 _factory("mec.nominal_model")),
    PaletteEntry("mec_compensator", "MEC compensator", "controlkit", "mec", {}, {},
                 _factory("mec.mec_compensator")),
    PaletteEntry("constant_gain", "constant gain K", "controlkit", "gain", {"K": 0.1},
                 {"K": _REAL}, _factory("mec.constant_gain")),
    PaletteEntry("frit_tuner", "FRIT tuner", "controlkit", "tuner", {"F": 0.0009, "Ts": 0.1},
                 {"F": _POSITIVE, "Ts": _PERIOD}, _factory("frit.frit_tuner")),
    PaletteEntry("lowpass_filter", "low-pass filter", "controlkit", "lowpass",
                 {"tau": 10.0, "Ts": 0.1}, {"tau": _POSITIVE, "Ts": _PERIOD},
                 _factory("common.lowpass_filter")),
    PaletteEntry("cmg_plant", "CMG plant", "controlkit", "cmg", {}, {},
                 _factory("cmg.cmg_plant"), follows_period=True),
    PaletteEntry("adaptive_smc", "adaptive SMC", "controlkit", "smc", {"Ts": 0.001},
                 {"Ts": _PERIOD}, _factory("cmg.adaptive_smc")),
    PaletteEntry("reference_generator", "CMG references", "controlkit", "reference", {}, {},
                 _factory("cmg.reference_generator")),
    PaletteEntry("torque_saturation", "CMG torque limits", "controlkit", "saturation",
                 {"T1_max": 0.6, "T2_max": 2.4}, {"T1_max": _POSITIVE, "T2_max": _POSITIVE},
                 _factory("cmg.torque_saturation")),
    # rebuilding recognised blocks of an opened diagram (not in the palette)
    PaletteEntry("state_space", "state space", "python-control", "sys", {}, {
        "A": matrix(), "B": matrix(), "C": matrix(), "D": matrix(), "dt": Timebase(),
        "inputs": _SIGNALS, "outputs": _SIGNALS, "states": _SIGNALS}, _state_space,
        shown=False, required=("A", "B", "C", "D")),
    PaletteEntry("transfer_function_data", "transfer function", "python-control", "sys", {},
                 {"num": _POLY, "den": _POLY, "dt": Timebase(), "inputs": _SIGNALS,
                  "outputs": _SIGNALS}, _transfer, shown=False, required=("num", "den")),
    PaletteEntry("junction", "summing junction", "python-control", "sum", {},
                 {"inputs": _JunctionInputs(), "output": NAME},
                 lambda n, kw: call("ct.summing_junction", inputs=kw["inputs"],
                                    output=kw["output"], name=n), shown=False,
                 required=("inputs", "output")),
    PaletteEntry("true_plant", "spacecraft plant (paper)", "controlkit", "plant",
                 {"model_error": True},
                 {"model_error": Flag()}, _factory("scenario.true_plant"),
                 follows_period=True, shown=False),
]
PALETTE = {entry.key: entry for entry in ENTRIES}


def build(key, name, kwargs, sampled=None):
    """The block of palette entry ``key``, named ``name``, built from its call tree.

    Parameters
    ----------
    key : str
        A key of :data:`PALETTE`.
    name : str
        Block name.
    kwargs : dict
        Keyword arguments, checked by the entry's rules.
    sampled : dict, optional
        ``{"Ts": period}`` (and ``method``, ``substeps``): the block sampled under
        zero-order hold.

    Returns
    -------
    control.InputOutputSystem

    Examples
    --------
    >>> build("pi", "pi", {"kp": 2.0, "ki": 1.0}).num[0][0].tolist()
    [2.0, 1.0]
    >>> build("gain", "g", {"k": "__import__('os')"})
    Traceback (most recent call last):
    ValueError: kwargs.k: must be a finite number, got "__import__('os')"
    """
    if key not in PALETTE:
        raise ValueError(f"palette entry must be one of {sorted(PALETTE)}, got {key!r}")
    NAME.check(name, "name")
    return evaluate(PALETTE[key].tree(name, kwargs, sampled))


def defaults(key, Ts):
    """A new block's keyword arguments: the entry's defaults with the diagram's ``Ts``."""
    kwargs = dict(PALETTE[key].defaults)
    if "Ts" in kwargs and Ts:
        kwargs["Ts"] = float(Ts)
    return kwargs


def is_number(value):
    """A real number that is not a bool (a parameter a slider can show)."""
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_))


def is_system(value):
    """Whether ``value`` is a block the editor can hold (any python-control I/O system)."""
    return isinstance(value, ct.InputOutputSystem)
