"""Calls as data: how the editor builds a block and writes the Python that builds it.

A block the editor can make is described by a small tree of :class:`Call`,
:class:`Ref`, :class:`Op`, :class:`Clip` and plain values. The same tree is
*evaluated* (:func:`evaluate`: constructors looked up in the fixed :data:`REGISTRY`,
values passed as they are) and *written* (:func:`to_ast`, then :func:`ast.unparse`):
there is no text that is pasted together and no ``eval``, so nothing read from a file
can become code. Every name in the tree is checked when the tree is made: a
constructor must be in :data:`REGISTRY`, a keyword a Python identifier; every value
becomes an :class:`ast.Constant` (or a list of them).
"""

from __future__ import annotations

import ast
import importlib
import keyword
import math
from dataclasses import dataclass

import numpy as np

#: Import lines the written code may need, by the alias it uses (in this order).
IMPORTS = {
    "ct": "import control as ct",
    "np": "import numpy as np",
    "controlkit": "import controlkit",
    "sc": "from controlkit.blocks import spacecraft as sc",
    "mec": "from controlkit.blocks import mec",
    "frit": "from controlkit.blocks import frit",
    "cmg": "from controlkit.blocks import cmg",
    "common": "from controlkit.blocks import common",
    "scenario": "from controlkit.studies.spacecraft import scenario",
}

_MODULES = {"ct": "control", "np": "numpy", "controlkit": "controlkit",
            "sc": "controlkit.blocks.spacecraft", "mec": "controlkit.blocks.mec",
            "frit": "controlkit.blocks.frit", "cmg": "controlkit.blocks.cmg",
            "common": "controlkit.blocks.common",
            "scenario": "controlkit.studies.spacecraft.scenario"}

#: The only callables a call tree may name: ``alias.attribute``.
REGISTRY = frozenset({
    "ct.tf", "ct.ss", "ct.nlsys", "ct.summing_junction", "ct.sample_system",
    "np.clip", "controlkit.sample_nlsys", "controlkit.interconnect",
    "controlkit.input_output_response",
    "sc.spacecraft_plant", "sc.io_linearizer", "sc.attitude_output", "sc.outer_controller",
    "sc.paper_momentum",
    "mec.nominal_model", "mec.mec_compensator", "mec.constant_gain",
    "frit.frit_tuner", "common.lowpass_filter",
    "cmg.cmg_plant", "cmg.adaptive_smc", "cmg.reference_generator", "cmg.torque_saturation",
    "scenario.true_plant",
})


def is_identifier(name):
    """Whether ``name`` may be written as a Python name: an identifier and no keyword.

    Examples
    --------
    >>> is_identifier("plant"), is_identifier("lambda"), is_identifier("F=1, x")
    (True, False, False)
    """
    return isinstance(name, str) and name.isidentifier() and not keyword.iskeyword(name)


def check_identifier(name, what):
    """``name`` if it is a Python identifier (not a keyword); else a ValueError naming ``what``."""
    if not is_identifier(name):
        raise ValueError(f"{what} must be a Python identifier (letters, digits and _, not "
                         f"starting with a digit, not a keyword), got {name!r}")
    return name


@dataclass(frozen=True)
class Ref:
    """A callable of :data:`REGISTRY`, such as ``"ct.tf"``."""

    name: str

    def __post_init__(self):
        if self.name not in REGISTRY:
            raise ValueError(f"{self.name!r} is not a constructor the editor knows; "
                             f"known: {sorted(REGISTRY)}")

    @property
    def alias(self):
        return self.name.split(".")[0]


@dataclass(frozen=True)
class Var:
    """A variable of the written code (a block built above, a parameter of the function)."""

    name: str

    def __post_init__(self):
        check_identifier(self.name, "a variable name")


@dataclass(frozen=True)
class Call:
    """``func(*args, **kwargs)``; ``kwargs`` a tuple of ``(identifier, value)`` pairs."""

    func: Ref
    args: tuple = ()
    kwargs: tuple = ()

    def __post_init__(self):
        if not isinstance(self.func, Ref):
            raise ValueError("a call names a constructor of the registry")
        for key, _ in self.kwargs:
            check_identifier(key, "a keyword argument")


def call(function, /, *args, **kwargs):
    """A :class:`Call` of registry entry ``function``.

    Examples
    --------
    >>> ast.unparse(to_ast(call("ct.tf", [1.0], [1.0, 2.0], name="lag")))
    "ct.tf([1.0], [1.0, 2.0], name='lag')"
    """
    return Call(Ref(function), tuple(args), tuple(kwargs.items()))


_OPS = {"+": (ast.Add, lambda a, b: a + b), "-": (ast.Sub, lambda a, b: a - b),
        "*": (ast.Mult, lambda a, b: a * b), "/": (ast.Div, lambda a, b: a / b)}


@dataclass(frozen=True)
class Op:
    """``left <op> right`` for one of ``+ - * /`` (transfer-function arithmetic)."""

    left: object
    op: str
    right: object

    def __post_init__(self):
        if self.op not in _OPS:
            raise ValueError(f"operator must be one of {sorted(_OPS)}, got {self.op!r}")


@dataclass(frozen=True)
class Clip:
    """``lambda t, x, u, params: np.clip(u, lower, upper)``: a saturation's output function.

    The limits are numbers bound in the function (not in ``params``, which
    python-control merges across blocks: two saturations would share one limit).
    """

    lower: float
    upper: float

    def function(self):
        lower, upper = _number(self.lower), _number(self.upper)
        return lambda t, x, u, params: np.clip(u, lower, upper)


def _number(value):
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"a number in a call must be finite, got {value}")
    return value


def plain(value):
    """``value`` as JSON-like Python data (numpy numbers and arrays as floats and lists)."""
    if isinstance(value, np.ndarray):
        return [plain(v) for v in value.tolist()]
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def _constant(value):
    value = plain(value)
    if isinstance(value, list):
        return ast.List([_constant(v) for v in value], ast.Load())
    if isinstance(value, dict):
        keys = list(value)
        for key in keys:
            if not isinstance(key, str):
                raise ValueError(f"a dict in a call must have string keys, got {key!r}")
        return ast.Dict([ast.Constant(k) for k in keys], [_constant(value[k]) for k in keys])
    if isinstance(value, float) and not math.isfinite(value):
        raise ValueError(f"a number in a call must be finite, got {value}")
    if value is None or isinstance(value, (bool, int, float, str)):
        return ast.Constant(value)
    raise ValueError(f"a value in a call must be a number, a string, None or a list of "
                     f"them, got {type(value).__name__}")


def to_ast(node):
    """The :mod:`ast` expression of a call tree (write it with :func:`ast.unparse`)."""
    if isinstance(node, Ref):
        alias, attribute = node.name.split(".")
        return ast.Attribute(ast.Name(alias, ast.Load()), attribute, ast.Load())
    if isinstance(node, Var):
        return ast.Name(node.name, ast.Load())
    if isinstance(node, Call):
        return ast.Call(to_ast(node.func), [to_ast(a) for a in node.args],
                        [ast.keyword(k, to_ast(v)) for k, v in node.kwargs])
    if isinstance(node, Op):
        return ast.BinOp(to_ast(node.left), _OPS[node.op][0](), to_ast(node.right))
    if isinstance(node, Clip):
        arguments = ast.arguments(posonlyargs=[], args=[ast.arg(a) for a in
                                                        ("t", "x", "u", "params")],
                                  kwonlyargs=[], kw_defaults=[], defaults=[])
        body = ast.Call(ast.Attribute(ast.Name("np", ast.Load()), "clip", ast.Load()),
                        [ast.Name("u", ast.Load()), _constant(_number(node.lower)),
                         _constant(_number(node.upper))], [])
        return ast.Lambda(arguments, body)
    return _constant(node)


def source(node):
    """Python source of a call tree.

    Examples
    --------
    >>> source(Op(2.0, "*", call("ct.tf", "s")))
    "2.0 * ct.tf('s')"
    """
    return ast.unparse(ast.fix_missing_locations(to_ast(node)))


def aliases(node):
    """The import aliases (keys of :data:`IMPORTS`) a call tree uses."""
    if isinstance(node, Ref):
        return {node.alias}
    if isinstance(node, Call):
        found = aliases(node.func)
        for a in node.args:
            found |= aliases(a)
        for _, v in node.kwargs:
            found |= aliases(v)
        return found
    if isinstance(node, Op):
        return aliases(node.left) | aliases(node.right)
    if isinstance(node, Clip):
        return {"np"}
    return set()


def resolve(name):
    """The callable of registry entry ``name`` (imported on first use)."""
    Ref(name)  # checks the name
    alias, attribute = name.split(".")
    return getattr(importlib.import_module(_MODULES[alias]), attribute)


def evaluate(node, variables=None):
    """The object a call tree builds: constructors called, values passed as they are."""
    if isinstance(node, Ref):
        return resolve(node.name)
    if isinstance(node, Var):
        return (variables or {})[node.name]
    if isinstance(node, Call):
        return evaluate(node.func)(*[evaluate(a, variables) for a in node.args],
                                   **{k: evaluate(v, variables) for k, v in node.kwargs})
    if isinstance(node, Op):
        return _OPS[node.op][1](evaluate(node.left, variables),
                                evaluate(node.right, variables))
    if isinstance(node, Clip):
        return node.function()
    return plain(node)
