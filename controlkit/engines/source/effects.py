"""What a user's function changes outside itself, read from its source: a ``print``, a
file, an object from outside or one of its arguments, directly (``x[0] = v``), through a
name bound to one (``xs = x[:]; xs[0] = v``, ``m = MEMORY; m[0] = v``) or through a
helper that writes into what it is given. python-control calls a block's functions
several times a step, on its own arrays; compiled code and the engine's Python run call
them otherwise, so a diagram holding such a function runs as python-control runs it.
"""

from __future__ import annotations

import ast
import builtins
import functools
import inspect
import random
import types

import numpy as np

from .reading import MUTATORS, NotCompilable, _definition, _outside_effect, call_target
from .rewrites import walk
from .values import _is_number

#: Methods whose result may be the object itself or a view of it.
VIEW_METHODS = frozenset({"reshape", "ravel", "view", "transpose", "swapaxes", "squeeze",
                          "diagonal", "get", "setdefault"})
#: numpy's functions whose result may be their first argument or a view of it.
VIEW_FUNCTIONS = frozenset({"asarray", "asanyarray", "ascontiguousarray", "atleast_1d",
                            "atleast_2d", "atleast_3d", "reshape", "ravel", "squeeze",
                            "transpose", "swapaxes", "moveaxis", "diagonal", "broadcast_to",
                            "expand_dims", "real", "imag"})
#: numpy's functions that write into their first argument.
INTO_FIRST = frozenset({"copyto", "put", "place", "putmask", "fill_diagonal",
                        "put_along_axis", "setattr", "delattr", "setitem", "delitem",
                        "heappush", "heappop", "heapify", "heapreplace", "heappushpop",
                        "insort", "insort_left", "insort_right", "shuffle"})
#: The random generators whose methods' draws change their state.
_GENERATORS = (np.random.Generator, np.random.RandomState, random.Random)
#: How deep helpers calling helpers are followed.
HELPER_DEPTH = 6


def side_effect(fn) -> str | None:
    """What ``fn`` does outside itself, as its source says (a ``print``, a file, a change
    to an object from outside or to its arguments, also through a name bound to one or a
    helper it calls), or None.

    Examples
    --------
    >>> def noisy(t, x, u, params):
    ...     print(t)
    ...     return x
    >>> side_effect(noisy)
    'it calls print()'
    >>> side_effect(lambda t, x, u, params: 2 * x) is None
    True
    >>> def in_place(t, x, u, params):
    ...     xs = x[:]
    ...     xs[0] += u[0]
    ...     return xs
    >>> side_effect(in_place)
    "it writes into its argument 'x' (through 'xs')"
    """
    return _read(fn)[0]


def _read(fn) -> tuple[str | None, str | None, tuple]:
    """:func:`side_effect`, :func:`draws` and :func:`params_changed` of ``fn``: one
    reading, kept. The answers
    follow from the code, what its outside names are (a module, an array) and the classes
    of what it is bound to (a method's self: its methods); they are asked again at every
    job made (a diagram built anew, new parameter values), 0.1 ms a function to read."""
    try:
        target, bound, _ = call_target(fn)
    except NotCompilable:
        return None, None, ()
    key = (target.__code__, *map(type, bound))
    if key not in _READ:
        try:
            reading = _Effects(target, 0, bound)
            _READ[key] = reading.first()[0], reading.draw(), tuple(reading.in_place)
        except NotCompilable:  # (no source: nothing is known)
            _READ[key] = None, None, ()
    return _READ[key]


#: :func:`_read`'s answers, by code object and the classes of what it is bound to.
_READ: dict = {}


def draws(fn) -> str | None:
    """The random draw ``fn`` makes (``rng.normal``, ``np.random.randn``,
    ``random.random``), as its source says, or None: a generator's state is outside the
    function, so how often it is called decides the numbers.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> draws(lambda t, x, u, params: x + 0.01 * rng.normal())
    'rng.normal'
    >>> draws(lambda t, x, u, params: x) is None
    True
    """
    return _read(fn)[1]


def params_changed(fn) -> tuple:
    """``(key, indexed, text)`` of each value read from ``params`` (``params[key]``, or
    ``indexed`` integer indexes into it) that an operator changes through a name (``total
    = params["acc"]; total += u[0]``), also through a slice, a view or a helper: in place
    if the value there is an array or a list (python-control's run then changes the
    block's own), a new number bound if it is a number. The caller, who knows the values,
    decides; ``key`` is None where the key is not known (any value may be the one). Every
    binding of a name counts, wherever it is.

    Examples
    --------
    >>> def accumulate(t, x, u, params):
    ...     total = params["acc"]
    ...     total += u[0]
    ...     return x + total[0]
    >>> params_changed(accumulate)
    (('acc', 0, 'total += u[0]'),)
    """
    return _read(fn)[2]


#: A name found neither in a function's module nor among the builtins (a closure's).
_UNKNOWN = object()


def _nothing_to_write_into(value) -> bool:
    """A value from outside that holds no data to change: a module, a function, a class,
    a number, a text (not an array, a list, a dict, an object, a closure's unknown)."""
    return value is None or _is_number(value) or isinstance(value, (
        str, bytes, type, types.ModuleType, types.FunctionType, types.BuiltinFunctionType,
        np.ufunc))


class _Effects:
    """One function's reading (see :func:`side_effect`)."""

    def __init__(self, function, depth, bound=(), params=None):
        self.function, self.depth = function, depth
        # (what its first parameters are bound to: a method's self, a partial's values)
        self.bound = dict(zip(function.__code__.co_varnames, bound, strict=False))
        code = function.__code__
        _, body = _definition(code, copy=False)
        self.nodes = list(walk(ast.Module(body, [])))
        stored = [n for n in self.nodes
                  if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)]
        self.stored = {n.id for n in stored}
        self.local = self.stored | set(code.co_varnames)
        self.parameters = list(code.co_varnames[:code.co_argcount + code.co_kwonlyargcount])
        # name -> ((the argument it may be bound to, or None for an outside object, the
        # text of what), whether the object itself or a view: not maybe an element)
        self.origin = {p: ((p, p), True) for p in self.parameters}
        # a block's time and params (t, params of t, x, u, params, after what is bound):
        # a number, which `t -= 1.0` binds anew; a dict, whose values may be arrays
        given = len(bound)
        self.time, self.params = code.co_varnames[given:given + 4:3] \
            if depth == 0 and code.co_argcount >= given + 4 else (None, params)
        self.in_place = []  # (key, indexed, text): see params_changed
        pairs = self._bindings()
        for p in self.parameters:  # (bound anew, first: its own copy is its own, an
            values = [v for t, v in pairs if isinstance(t, ast.Name) and t.id == p]
            found = [self._source(v) for v in values]  # element of itself a number)
            if values and not any(found):
                del self.origin[p]
            elif values:
                self.origin[p] = ((p, p), any(f[1] for f in found if f))
        changed = True
        while changed:  # (names bound to names bound to ...)
            changed = False
            for target, value in pairs:
                found = self._source(value)
                unpacked = not isinstance(target, ast.Name)
                for name in _bound_names(target):
                    if found is not None and name not in self.origin:
                        self.origin[name] = (found[0], found[1] and not unpacked)
                        changed = True
        # name -> {(params key or None for a key not known, indexes into it)} of the values
        # it may be bound to, over all its bindings (a flow-free reading: any may be in force)
        self.keys = {}
        expanded = []
        for target, value in pairs:  # (`a, b = p, q` pairwise; `a, b = M`: its rows)
            if isinstance(target, ast.Tuple) and isinstance(value, ast.Tuple | ast.List) \
                    and len(target.elts) == len(value.elts):
                expanded += zip(target.elts, value.elts, strict=True)
            elif isinstance(target, ast.Tuple):
                expanded += [(element, ast.Subscript(value, ast.Constant(0)))
                             for element in target.elts]
            else:
                expanded.append((target, value))
        changed = self.params is not None
        while changed:
            changed = False
            for target, value in expanded:
                name = getattr(target, "id", None)
                found = self._key(value) - self.keys.get(name, set()) if name else set()
                if found:
                    self.keys[name] = self.keys.get(name, set()) | found
                    changed = True

    def _bindings(self):
        """``(target, value)`` of each binding of a name in the function."""
        pairs = []
        for node in self.nodes:
            if isinstance(node, ast.Assign):
                pairs += [(t, node.value) for t in node.targets]
            elif isinstance(node, ast.For | ast.comprehension):  # (an element, maybe a row)
                pairs.append((node.target, ast.Subscript(node.iter, ast.Constant(0))))
            elif isinstance(node, ast.NamedExpr | ast.AnnAssign) and node.value is not None:
                pairs.append((node.target, node.value))
        return pairs

    def _outside(self, name):
        namespace = self.function.__globals__
        return namespace[name] if name in namespace else getattr(builtins, name, _UNKNOWN)

    def _source(self, node):
        """``origin`` (see ``__init__``) of what ``node`` may be bound to, else None."""
        if isinstance(node, ast.Name):
            if node.id in self.origin:
                return self.origin[node.id]
            if node.id not in self.local and not _nothing_to_write_into(
                    self._outside(node.id)):
                return (None, node.id), True
            return None
        if isinstance(node, ast.Subscript | ast.Attribute):
            found = self._source(node.value)
            whole = isinstance(node, ast.Subscript) and isinstance(
                node.slice, ast.Slice | ast.Tuple) or isinstance(node, ast.Attribute) \
                and node.attr in ("T", "real", "imag", "flat")
            return (found[0], whole and found[1]) if found else None
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if node.func.attr in VIEW_METHODS:
                found = self._source(node.func.value)  # (a dict's get: a number, or not)
                whole = node.func.attr not in ("get", "setdefault")
                return (found[0], found[1] and whole) if found else None
            if node.func.attr in VIEW_FUNCTIONS and node.args:
                return self._source(node.args[0])
        if isinstance(node, ast.IfExp):
            return self._source(node.body) or self._source(node.orelse)
        if isinstance(node, ast.BoolOp):
            return next(filter(None, map(self._source, node.values)), None)
        if isinstance(node, ast.NamedExpr | ast.Starred):
            return self._source(node.value)
        return None

    def _key(self, node) -> set:
        """``{(key, indexed)}`` of the ``params`` values ``node`` may be, index into (by
        ``indexed`` integers) or view; ``key`` None where the key is not known."""
        whole = ((self.params, self.params), True)
        if isinstance(node, ast.Name):
            return self.keys.get(node.id, set())
        if isinstance(node, ast.Subscript):
            if self._source(node.value) == whole:  # (params[...]: a key, known or not)
                key = node.slice.value if isinstance(node.slice, ast.Constant) else \
                    self._value(node.slice) if isinstance(node.slice, ast.Name) else None
                return {(key if isinstance(key, str | int | bytes) else None, 0)}
            if isinstance(node.value, ast.List | ast.Tuple):  # ([a, b][0]: one of them)
                return set().union(*map(self._key, node.value.elts))
            if isinstance(node.value, ast.Call) and getattr(node.value.func, "attr", "") in (
                    "values", "items") and self._source(node.value.func.value) == whole:
                # (an element of params.values(): a value; of .items(), a pair holding one)
                return {(None, 0 if node.value.func.attr == "values" else -1)}
            indexes = node.slice.elts if isinstance(node.slice, ast.Tuple) else [node.slice]
            taken = sum(isinstance(e, ast.Constant) and type(e.value) is int or isinstance(
                e, ast.UnaryOp) and isinstance(e.operand, ast.Constant) for e in indexes)
            return {(key, indexed + taken) for key, indexed in self._key(node.value)}
        if isinstance(node, ast.Attribute) and node.attr in ("T", "real", "imag"):
            return self._key(node.value)
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if node.func.attr in ("get", "setdefault") and node.args and \
                    self._source(node.func.value) == whole:
                first = node.args[0]
                return {(first.value if isinstance(first, ast.Constant) else None, 0)}
            if node.func.attr in VIEW_METHODS:
                return self._key(node.func.value)
        if isinstance(node, ast.Call) and node.args and getattr(
                node.func, "attr", getattr(node.func, "id", None)) in VIEW_FUNCTIONS:
            return self._key(node.args[0])
        if isinstance(node, ast.IfExp):
            return self._key(node.body) | self._key(node.orelse)
        if isinstance(node, ast.BoolOp):
            return set().union(*map(self._key, node.values))
        if isinstance(node, ast.NamedExpr):
            return self._key(node.value)
        return set()

    def draw(self) -> str | None:
        """The first call of a random generator's method, see :func:`draws`."""
        for node in self.nodes:
            if isinstance(node, ast.Call) and isinstance(getattr(
                    self._value(node.func), "__self__", None), _GENERATORS):
                return ast.unparse(node.func)[:40]
        return None

    def _said(self, found, through, text):
        """``(what, the argument written into or None, False)``: see :meth:`first`."""
        argument, _ = found[0]
        if argument is None:
            return f"it changes an object from outside ({text[:40]})", None, False
        via = f" (through {through!r})" if through not in (None, argument) else ""
        return f"it writes into its argument {argument!r}{via}", argument, False

    def first(self):
        """``(what the function does outside itself, the argument it writes into, whether
        only by an operator such as ``+=``, in place on arrays alone)``, or ``(None, None,
        False)``."""
        is_module = lambda name: isinstance(self._outside(name), types.ModuleType)  # noqa: E731
        for node in self.nodes:
            if isinstance(node, ast.Global | ast.Nonlocal):
                assigned = [name for name in node.names if name in self.stored]
                if assigned:
                    return f"it assigns {', '.join(assigned)} outside itself", None, False
            if isinstance(node, ast.Call):
                said = _outside_effect(node, self.local, is_module)
                said = (said[0], None, False) if said is not None else self._call(node)
                if said is not None:
                    return said
            if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
                said = self._getter(node)
                if said is not None:
                    return said, None, False
            for written in _targets(node):
                if isinstance(written, ast.Name):  # (bound anew; in place if an array)
                    found = self.origin.get(written.id)
                    if isinstance(node, ast.AugAssign) and found and found[1] \
                            and written.id != self.time:
                        return (*self._said(found, written.id, ast.unparse(written))[:2],
                                True)
                    if isinstance(node, ast.AugAssign):  # (a params value's, perhaps)
                        known = self.keys.get(written.id) or ({(None, 0)} if found and (
                            self.params is not None and found[0][0] == self.params) else ())
                        self.in_place += [(*key, ast.unparse(node)) for key in sorted(
                            known, key=repr)]
                    continue
                base = _base_name(written)
                if base is not None and base not in self.local:
                    return (f"it changes an object from outside "
                            f"({ast.unparse(written)[:40]})"), None, False
                found = self._source(written)
                if found is not None:
                    return self._said(found, base, ast.unparse(written))
        return None, None, False

    def _call(self, node):
        """:meth:`first` of a call writing into what the function may not own: a method
        that changes its object, numpy's ``out`` (by keyword, or a ufunc's by position)
        or ``copyto``, or a helper writing into what it is given (or acting outside
        itself); else None."""
        func = node.func
        if isinstance(func, ast.Attribute) and func.attr in MUTATORS:
            found = self._source(func.value)
            if found is not None:
                return self._said(found, _base_name(func.value), ast.unparse(func))
        name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
        called = self._value(func)
        written = [node.args[0]] if name in INTO_FIRST and node.args else []
        written += [k.value for k in node.keywords if k.arg == "out"]
        if isinstance(called, np.ufunc):  # (np.add(a, b, c) writes c)
            written += node.args[called.nin:]
        for value in written:
            found = self._source(value)
            if found is not None:
                return self._said(found, _base_name(value), ast.unparse(node))
        if not isinstance(called, types.FunctionType) or self.depth >= HELPER_DEPTH \
                or (called.__module__ or "").split(".")[0] in ("numpy", "control",
                                                               "controlkit"):
            return None
        # a method of an object the function is bound to, `self.step(x)`: self comes first
        owner = self._value(func.value) if isinstance(func, ast.Attribute) else None
        method = owner is not None and not isinstance(owner, types.ModuleType)
        code = called.__code__
        whole = ((self.params, self.params), True)  # (params handed on: the helper's own)
        handed = [code.co_varnames[i + method] for i, value in enumerate(node.args)
                  if i + method < code.co_argcount and self._source(value) == whole]
        handed += [k.arg for k in node.keywords if k.arg and self._source(k.value) == whole]
        try:
            helper = _Effects(called, self.depth + 1, (owner,) if method else (),
                              params=handed[0] if handed and self.params else None)
            said, parameter, by_operator = helper.first()
        except NotCompilable:
            return None
        self.in_place += helper.in_place
        if said is None:
            return None
        if parameter is None:
            return f"it calls {name}(), which {said.removeprefix('it ')}", None, False
        position = code.co_varnames.index(parameter) - method
        given = [k.value for k in node.keywords if k.arg == parameter]
        if 0 <= position < len(node.args) and position < code.co_argcount - method:
            given.append(node.args[position])
        for value in given:
            found = self._source(value)
            # (`v += 1` on a number given is the helper's own: in place on arrays only)
            if found is not None and (found[1] or not by_operator):
                return self._said(found, _base_name(value), ast.unparse(node))
            if by_operator:
                self.in_place += [(*key, ast.unparse(node)[:40])
                                  for key in sorted(self._key(value), key=repr)]
        return None

    def _getter(self, node):
        """What reading the attribute ``node`` of an object does outside the function
        when the attribute is a property (or another descriptor) whose getter is Python
        code acting outside itself, else None: python-control runs the getter at every
        call of the block's function, compiled code would read the value once."""
        owner = self._value(node.value) if self.depth < HELPER_DEPTH else None
        if owner is None or isinstance(owner, (types.ModuleType, *_GENERATORS)):
            return None
        found = inspect.getattr_static(owner, node.attr, None)
        if isinstance(found, property | functools.cached_property):
            getter, bound = getattr(found, "fget", None) or found.func, owner
        else:  # (a descriptor of its own; a plain value or a function has none in Python)
            getter, bound = getattr(type(found), "__get__", None), found
        if not isinstance(getter, types.FunctionType):
            return None
        try:
            said, written, _ = _Effects(getter, self.depth + 1, (bound,)).first()
        except NotCompilable:
            return None
        if said is None:
            return None
        text = ast.unparse(node)[:40]
        return (f"it reads {text}, whose getter changes {ast.unparse(node.value)[:40]}"
                if written is not None else f"it reads {text}, whose getter "
                                            f"{said.removeprefix('it ')}")

    def _value(self, node):
        """What a called name stands for when it can be known without running anything:
        a name of the function's module, closure or defaults, or a module's attribute."""
        if isinstance(node, ast.Attribute):  # (of a module, a generator, or a method)
            owner = self._value(node.value)
            if isinstance(owner, (types.ModuleType, *_GENERATORS)):
                return getattr(owner, node.attr, None)
            found = inspect.getattr_static(owner, node.attr, None) if owner is not None \
                else None  # (no getter of the object's is run: a function, or a value)
            plain = isinstance(found, types.FunctionType) or not hasattr(type(found), "__get__")
            return found if plain else None
        if not isinstance(node, ast.Name):
            return None
        if node.id in self.bound:
            return self.bound[node.id]
        code, function = self.function.__code__, self.function
        if node.id in code.co_freevars and function.__closure__:
            try:
                return function.__closure__[code.co_freevars.index(node.id)].cell_contents
            except ValueError:  # (an empty cell)
                return None
        defaults = dict(zip(code.co_varnames[code.co_argcount - len(
            function.__defaults__ or ()):code.co_argcount], function.__defaults__ or (),
            strict=True))
        if node.id in defaults:
            return defaults[node.id]
        value = self._outside(node.id) if node.id not in self.local else None
        return None if value is _UNKNOWN else value


def _bound_names(target):
    """The names an assignment to ``target`` binds (``a``, ``a, *b``), not those it writes
    into (``dx[0] = ...`` binds nothing)."""
    if isinstance(target, ast.Name):
        return [target.id]
    if isinstance(target, ast.Starred):
        return _bound_names(target.value)
    if isinstance(target, ast.Tuple | ast.List):
        return [name for element in target.elts for name in _bound_names(element)]
    return []


def _targets(node):
    """What an assignment (or ``del``) ``node`` writes, tuples unpacked; else nothing."""
    if isinstance(node, ast.Assign | ast.Delete):
        todo = list(node.targets)
    elif isinstance(node, ast.AugAssign | ast.AnnAssign):
        todo = [node.target]
    else:
        return []
    targets = []
    while todo:
        target = todo.pop()
        if isinstance(target, ast.Tuple | ast.List):
            todo.extend(target.elts)
        else:
            targets.append(target.value if isinstance(target, ast.Starred) else target)
    return targets


def _base_name(target):
    """The name ``x`` of ``x[0].a``, ``x.a[1]``, ``x.reshape(2, 2)[0]`` or ``x``, else None."""
    while isinstance(target, ast.Subscript | ast.Attribute | ast.Call):
        target = target.func if isinstance(target, ast.Call) else target.value
    return target.id if isinstance(target, ast.Name) else None
