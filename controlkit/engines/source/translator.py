"""Translating one function's statements into a plan's: every read of the run-time
``params`` written as one :data:`~.reading.PARAM_READ` call, keys held in variables made
constants, names from outside and helper calls handed to :mod:`.outside`.
"""

from __future__ import annotations

import ast
import functools
import importlib
import math
import re
import types

from .outside import _OutsideReads
from .reading import PARAM_READ, PARAMS, RUNTIME, _outside_effect
from .rewrites import _store_counts, _stored_names, _string_items, _Unroll, walk
from .values import _MISSING, _UNKNOWN, _is_plain

#: A value a function reads from outside itself (a global, a closure's cell) is frozen into
#: module text as ``_g<i>_<name>``, ``i`` the function's index among the planned ones
_FROZEN = re.compile(r"\b_g\d+_")


def as_written(text: str) -> str:
    """``text``, a name or code of module text, with its frozen names as the user wrote
    them (for messages, and for recognising ``np``).

    Examples
    --------
    >>> as_written("_g2_np.clip(x, _g2_lo)"), as_written("_np_")
    ('np.clip(x, lo)', '_np_')
    """
    return _FROZEN.sub("", text)


class _Translator(_OutsideReads, ast.NodeTransformer):
    """One function's statements -> a plan's (params reads, helpers, frozen values)."""

    def __init__(self, build, plan, fn, bindings):
        self.build, self.plan, self.fn, self.bindings = build, plan, fn, bindings
        self.fixed = {}       # names bound for this plan only: hoisted imports, objects
        self.sources = {}     # name -> RUNTIME (the params vector) or a frozen dict
        self.renamed = {}     # free name -> module-level name
        self.strings = {}     # name -> the one string it is assigned

    # -- setting up ------------------------------------------------------------------------

    def translate(self, body):
        plan, prologue, kept = self.plan, [], set()
        for name, binding in self.bindings.items():
            if binding is RUNTIME:
                plan.arguments.append(name)
            elif binding == PARAMS:
                plan.arguments.append(name)
                self.sources[name] = RUNTIME
            elif isinstance(binding.value, dict):
                self.sources[name] = binding.value
            elif isinstance(binding.value, str):
                self.strings[name] = binding.value  # a key handed in: reads are constant
            elif _is_plain(binding.value) and not callable(binding.value) \
                    and not isinstance(binding.value, types.ModuleType):
                frozen = self._freeze_value(name, binding.value)
                prologue.append(ast.Assign([ast.Name(name, ast.Store())],
                                           ast.Name(frozen, ast.Load()), lineno=0))
                kept.add(name)
            else:  # an object, a module, a function: read as a name from outside is
                self.fixed[name] = binding.value  # (a default np.tanh by numpy's last bits)
        body = self._hoist_imports(body)
        body = _Unroll(self._lookup).visit(ast.Module(body, [])).body
        counts = _store_counts(body)
        self._find_aliases(body)
        self._find_strings(body, counts)
        self.local = (_stored_names(body) | kept | set(plan.arguments)) - set(self.sources)
        outside = {node.id for node in walk(ast.Module(body, []))  # (integers from outside
                   if isinstance(node, ast.Name) and node.id not in self.local}  # count too)
        read = {name: self._lookup_getter(name)[1] for name in outside}
        self.known = {name: value for name, value in read.items() if type(value) is int}
        self.known.update({name: self.bindings[name].value for name in kept - _stored_names(
            body) if type(self.bindings[name].value) is int})
        self.ints = _integer_names(body, self.known)
        for name in self.sources:
            if counts.get(name, 0) > (1 if name not in self.bindings else 0):
                self._opaque(f"params ({name!r}) is assigned more than once")
        plan.body = prologue + self.visit(ast.Module(body, [])).body or [ast.Pass()]

    def _hoist_imports(self, body):
        kept = []
        for stmt in body:
            if isinstance(stmt, ast.Import):
                for alias in stmt.names:  # (import a.b imports a.b and binds a)
                    module, top = importlib.import_module(alias.name), alias.name.split(".")[0]
                    self.fixed[alias.asname or top] = (module if alias.asname
                                                       else importlib.import_module(top))
            elif isinstance(stmt, ast.ImportFrom) and not stmt.level:
                module = importlib.import_module(stmt.module)
                for alias in stmt.names:
                    if alias.name == "*":
                        self._problem("it imports * inside itself")
                        continue
                    value = getattr(module, alias.name)  # (read again at each call)
                    self.plan.checks.append((functools.partial(getattr, module, alias.name,
                                                               _MISSING), value))
                    self.fixed[alias.asname or alias.name] = value
            else:
                kept.append(stmt)
        return kept

    def _find_aliases(self, body):
        changed = True
        while changed:
            changed = False
            for node in walk(ast.Module(body, [])):
                if isinstance(node, ast.Assign) and len(node.targets) == 1 \
                        and isinstance(node.targets[0], ast.Name) \
                        and isinstance(node.value, ast.Name) and node.value.id in self.sources \
                        and node.targets[0].id not in self.sources:
                    self.sources[node.targets[0].id] = self.sources[node.value.id]
                    changed = True

    def _find_strings(self, body, counts):
        for node in walk(ast.Module(body, [])):
            if isinstance(node, ast.Assign) and len(node.targets) == 1 \
                    and isinstance(node.targets[0], ast.Name) \
                    and isinstance(node.value, ast.Constant) \
                    and isinstance(node.value.value, str) \
                    and counts.get(node.targets[0].id) == 1 \
                    and node.targets[0].id not in self.bindings:
                self.strings[node.targets[0].id] = node.value.value

    # -- recording ---------------------------------------------------------------------------

    def _problem(self, why):
        if self.plan.problem is None:
            self.plan.problem = why

    def _opaque(self, why):
        if self.plan.opaque is None:
            self.plan.opaque = why

    def _freeze_value(self, name, value):
        frozen = f"_g{self.plan.index}_{name}"
        self.plan.frozen[frozen] = value
        return frozen

    # -- params reads -------------------------------------------------------------------------

    def _key(self, node):
        """The constant a key expression stands for, else a sentinel."""
        if isinstance(node, ast.Constant):
            return node.value
        if isinstance(node, ast.Name) and node.id in self.strings:
            return self.strings[node.id]
        if isinstance(node, ast.Name) and node.id not in self.local \
                and node.id not in self.sources:
            found, value = self._lookup(node.id)
            if found and isinstance(value, str):
                return value
        return _UNKNOWN

    def _read(self, source_name, key, how, default, node):
        source = self.sources[source_name]
        if key is _UNKNOWN:
            self._opaque(f"params is read with a key that is not known: {ast.unparse(node)[:60]}")
            return ast.copy_location(ast.Constant(None), node)
        if default is not None:
            default = self.visit(default)
        if source is RUNTIME:
            self.plan.keys.add(key)
            call = ast.Call(ast.Name(PARAM_READ, ast.Load()),
                            [ast.Name(source_name, ast.Load()), ast.Constant(key),
                             ast.Constant(how), default or ast.Constant(None)], [])
            return ast.copy_location(call, node)
        # a dict known when the plan is made (a default {}, a dict handed to a helper)
        self.plan.checks.append((functools.partial(source.get, key, _MISSING),
                                 source.get(key, _MISSING)))
        if how == "in":
            return ast.copy_location(ast.Constant(key in source), node)
        if key in source:  # (read as a name from outside is: np.tanh by numpy's last bits)
            return self._value_read(source_name, source[key], node, key)
        if how == "item":
            self._problem(f"params has no key {key!r}")
            return ast.copy_location(ast.Constant(None), node)
        return default or ast.copy_location(ast.Constant(None), node)

    def _is_source(self, node):
        return isinstance(node, ast.Name) and node.id in self.sources

    # -- visitors ---------------------------------------------------------------------------

    def visit_Subscript(self, node):
        if self._is_source(node.value) and isinstance(node.ctx, ast.Load):
            return self._read(node.value.id, self._key(node.slice), "item", None, node)
        if self._is_source(node.value):
            self._opaque("it writes into params")
            return node
        return self._chain_or_visit(node)

    def visit_Attribute(self, node):
        if self._is_source(node.value):
            self._opaque(f"it uses params.{node.attr}")
            return node
        return self._chain_or_visit(node)

    def _chain_or_visit(self, node):
        """A read from an object outside, frozen (:meth:`_chain`), else ``node`` visited."""
        chain = self._chain(node)
        return chain if chain is not None else self.generic_visit(node)

    def visit_Compare(self, node):
        if len(node.ops) == 1 and isinstance(node.ops[0], ast.In | ast.NotIn) \
                and self._is_source(node.comparators[0]):
            read = self._read(node.comparators[0].id, self._key(node.left), "in", None, node)
            if isinstance(node.ops[0], ast.NotIn):
                read = ast.copy_location(ast.UnaryOp(ast.Not(), read), node)
            return read
        return self.generic_visit(node)

    def visit_Assign(self, node):
        if len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and self._is_source(node.value):
            if self.sources[node.value.id] is RUNTIME:
                return node  # an alias of the parameter vector
            return []  # an alias of a dict known now: its reads are constants
        if len(node.targets) == 1 and isinstance(node.targets[0], ast.Name) \
                and node.targets[0].id in self.strings:
            return []  # a key held in a variable: its reads are constants
        return self.generic_visit(node)

    def visit_Name(self, node):
        name = node.id
        if name in self.sources:
            if isinstance(node.ctx, ast.Load):
                self._opaque(f"it uses params ({name!r}) otherwise than as params['key'] "
                             f"or params.get('key', default)")
            return node
        if isinstance(node.ctx, ast.Load) and name in self.strings:
            return ast.copy_location(ast.Constant(self.strings[name]), node)
        if name in self.local or not isinstance(node.ctx, ast.Load):
            return node
        return self._free(node)

    def visit_Global(self, node):
        self._problem("it declares a global")
        return node

    # -- what compiled code would do otherwise than Python --------------------------------

    def _python_only(self, node):
        """Calls whose compiled meaning is not Python's: the function then runs as Python."""
        f = node.func
        name = f.id if isinstance(f, ast.Name) and f.id not in self.local else None
        effect = _outside_effect(node, self.local, lambda outside: isinstance(
            self._lookup(outside)[1], types.ModuleType))
        if effect is not None:
            self._problem("".join(effect))
        elif name == "round" and (len(node.args) > 1 or node.keywords):
            self._problem("it rounds to digits (round(x, n)): compiled code rounds some "
                          "halves otherwise than Python (round(0.35, 1) gives 0.4, Python 0.3)")
        elif isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name) \
                and f.value.id == "math" and f.attr in ("factorial", "comb", "perm"):
            self._problem(f"it calls math.{f.attr}, whose integers can outgrow the 64 bits "
                          f"of compiled code")

    def visit_BinOp(self, node):
        if (isinstance(node.op, ast.LShift) or isinstance(node.op, ast.Pow | ast.Mult) and (
                _integer(node.left, self.ints) and _integer(node.right, self.ints))) \
                and not -2 ** 63 <= _known(node, self.known) < 2 ** 63:  # (2 * N: its value)
            self._problem(f"it computes {ast.unparse(node)[:40]} with integers, which can "
                          f"outgrow the 64 bits of compiled code (Python's integers do not)")
        return self.generic_visit(node)

    visit_Nonlocal = visit_Global

    def visit_ExceptHandler(self, node):  # (numba refuses the others, after a compile)
        if node.name or node.type is not None and ast.unparse(node.type) != "Exception":
            self._problem(f"it catches {ast.unparse(node.type)[:30]}"
                          f"{' as ' + node.name if node.name else ''}: compiled code (numba) "
                          f"catches every exception with 'except Exception:', or none")
        return self.generic_visit(node)

    def visit_Import(self, node):
        self._problem("it imports inside a block")
        return node

    visit_ImportFrom = visit_Import

    def visit_Call(self, node):
        f = node.func
        self._python_only(node)
        # params.get("k", default)
        if isinstance(f, ast.Attribute) and self._is_source(f.value) and f.attr == "get" \
                and node.args and len(node.args) <= 2 and not node.keywords:
            default = node.args[1] if len(node.args) == 2 else None
            return self._read(f.value.id, self._key(node.args[0]), "get", default, node)
        # map(params.get, ["a", "b"]) -> a tuple of reads
        if isinstance(f, ast.Name) and f.id == "map" and f.id not in self.local \
                and len(node.args) == 2 and isinstance(node.args[0], ast.Attribute) \
                and self._is_source(node.args[0].value) \
                and node.args[0].attr in ("get", "__getitem__"):
            keys = _string_items(node.args[1], self._lookup)
            if keys is None:
                self._opaque("params is mapped over keys that are not known")
                return node
            how = "get" if node.args[0].attr == "get" else "item"
            items = [self._read(node.args[0].value.id, k, how, None, node) for k in keys]
            return ast.copy_location(ast.Tuple(items, ast.Load()), node)
        # list(...) / tuple(...) of a tuple written out above
        if isinstance(f, ast.Name) and f.id in ("list", "tuple") and f.id not in self.local \
                and len(node.args) == 1 and not node.keywords:
            inner = self.visit(node.args[0])
            if isinstance(inner, ast.Tuple):
                kind = ast.List if f.id == "list" else ast.Tuple
                return ast.copy_location(kind(inner.elts, ast.Load()), node)
            node.args[0] = inner
            return node
        target = self._callee(f)
        if target is not None:
            return self._helper_call(node, *target)
        for arg in [*node.args, *(k.value for k in node.keywords)]:
            if self._is_source(arg) or (isinstance(arg, ast.Starred)
                                        and self._is_source(arg.value)):
                self._opaque(f"params is handed to {ast.unparse(f)[:40]}, which is not compiled")
                return node
        return self.generic_visit(node)


def _integer(node, ints=frozenset()) -> bool:
    """Whether ``node`` is an integer for sure: an int literal, ``int(...)``, ``len(...)``,
    ``round(x)``, a name in ``ints`` (assigned one of these), or arithmetic of them.

    Examples
    --------
    >>> _integer(ast.parse("n * n * 3", mode="eval").body, {"n"})
    True
    >>> _integer(ast.parse("n * x", mode="eval").body, {"n"})
    False
    """
    if isinstance(node, ast.Constant):
        return isinstance(node.value, int) and not isinstance(node.value, bool)
    if isinstance(node, ast.Name):
        return node.id in ints
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        return _integer(node.operand, ints)
    if isinstance(node, ast.BinOp) and isinstance(
            node.op, ast.Add | ast.Sub | ast.Mult | ast.FloorDiv | ast.Mod | ast.Pow):
        return _integer(node.left, ints) and _integer(node.right, ints)
    return (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)
            and node.func.id in ("int", "len", "round") and len(node.args) == 1)


def _known(node, known) -> float:
    """The value of ``node`` when it is integer arithmetic of numbers known now (literals,
    the names of ``known``), else infinity (or a power or shift past 64 bits).

    Examples
    --------
    >>> _known(ast.parse("2 * N - 1", mode="eval").body, {"N": 3})
    5
    >>> _known(ast.parse("N * int(u)", mode="eval").body, {"N": 3})
    inf
    """
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return node.value
    if isinstance(node, ast.Name) and node.id in known:
        return known[node.id]
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        value = _known(node.operand, known)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.BinOp) and isinstance(
            node.op, ast.Add | ast.Sub | ast.Mult | ast.Pow | ast.LShift):
        a, b = _known(node.left, known), _known(node.right, known)
        if math.inf in (abs(a), abs(b)) or isinstance(node.op, ast.Pow | ast.LShift) and (
                not 0 <= b <= 64):
            return math.inf
        if isinstance(node.op, ast.Add | ast.Sub):
            return a + b if isinstance(node.op, ast.Add) else a - b
        return a * b if isinstance(node.op, ast.Mult) else a ** b if isinstance(
            node.op, ast.Pow) else a << b
    return math.inf


def _integer_names(body, ints=frozenset()) -> set:
    """The names a function assigns integers to, only integers (``n = int(u[0])``), and
    ``ints``, names of integers known already."""
    assigned, ints = {}, set(ints)
    for node in walk(ast.Module(body, [])):
        if isinstance(node, ast.Assign) and len(node.targets) == 1 \
                and isinstance(node.targets[0], ast.Name):
            assigned.setdefault(node.targets[0].id, []).append(node.value)
        elif isinstance(node, ast.AugAssign | ast.For) and isinstance(
                getattr(node, "target", None), ast.Name):
            assigned.setdefault(node.target.id, []).append(None)
    changed = True
    while changed:  # (a name assigned from another integer name)
        changed = False
        for name, values in assigned.items():
            if name not in ints and all(v is not None and _integer(v, ints) for v in values):
                ints.add(name)
                changed = True
    return ints
