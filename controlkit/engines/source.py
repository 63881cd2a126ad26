"""Reading a user's ``(t, x, u, params)`` function from its source.

What a function reads can only be known from its source: which ``params`` keys
(for the ``params`` check every backend makes), whether it reads ``u`` (its
feedthrough, for the fast engine's evaluation order), and the statements the fast
engine compiles. This module turns a function, as python-control's examples and
course notebooks write them, into a :class:`Plan`: its statements with every read
of the run-time ``params`` in one canonical form, the helper functions it calls
(planned the same way, transitively) and the values it reads from outside (its
module, its closure, the objects it was bound to), which the compiler freezes.

What is understood:

- ``params["k"]``, ``params.get("k", default)``, ``"k" in params``;
  ``map(params.get, ["a", "b"])``; an alias (``p = params``); a key held in a
  variable assigned one string (``name = "k"; params[name]``), looped over
  (``for name in ("a", "b"): ... params[name]``) or collected
  (``[params[k] for k in ("a", "b")]``);
- ``params`` handed to another function (``motor_torque(omega, params)``), which is
  planned with it, as are functions called with a string key or an object (a
  ``StateSpace``, a ``self``) whose attributes they read;
- values read from objects: ``actuator.params["umax"]``, ``P.A`` (a python-control
  system's matrix), ``self.kp``, read when the plan is made;
- callables that are not plain functions: a :func:`functools.partial`, a bound
  method, an object with ``__call__``, a decorated function (what Python runs: the
  wrapper, calling the function it wraps as a helper, never the wrapped body alone);
- imports inside the function (``from math import sin``), hoisted.

Anything else is recorded, not guessed: a ``params`` use that is not understood
makes the keys read unknown (the ``params`` check then accepts every key, as
python-control does) and the function not compilable, with the reason.
"""

from __future__ import annotations

import ast
import builtins
import copy
import functools
import importlib
import inspect
import linecache
import types
import weakref
from dataclasses import dataclass, field

import numpy as np

from .. import _jit


class NotCompilable(Exception):
    """Why a user function cannot be compiled (the message is shown by ``explain``).

    Examples
    --------
    >>> str(NotCompilable("no source"))
    'no source'
    """


#: The call every read of the run-time ``params`` becomes in a plan's statements:
#: ``__controlkit_param__(params, key, how, default)`` with ``how`` one of ``"item"``
#: (``params[key]``), ``"get"`` (``params.get(key, default)``) or ``"in"`` (``key in
#: params``). The compiler replaces it by the read of the packed parameter vector.
PARAM_READ = "__controlkit_param__"

#: Modules whose functions numba compiles itself: calls into them are left as written.
NUMERIC_MODULES = ("numpy", "math", "cmath")

#: Packages whose plain Python functions are never compiled as helpers (their internals
#: are not numerical kernels: a python-control system's methods, numpy's Python layer).
_NOT_HELPERS = ("control", "numpy", "scipy", "controlkit", "numba", "functools", "builtins")


# --- the source of a function ---------------------------------------------------------------

def _lambda_body(code):
    """The expression of a lambda, cut from its file by the positions of its code."""
    # (line, end line, column, end column) of each instruction, not the zero-width ones
    spans = [(line, end, col, end_col) for line, end, col, end_col in code.co_positions()
             if None not in (line, end, col, end_col) and (line, col) != (end, end_col)]
    lines = linecache.getlines(code.co_filename)
    if not spans or not lines:
        raise NotCompilable("its source is not available")
    first = min((line, col) for line, _, col, _ in spans)
    last = max((end, end_col) for _, end, _, end_col in spans)
    chunk = lines[first[0] - 1:last[0]]
    if not chunk:
        raise NotCompilable("its source is not available")
    chunk[-1] = chunk[-1].encode()[:last[1]].decode(errors="ignore")
    chunk[0] = chunk[0].encode()[first[1]:].decode(errors="ignore")
    try:
        node = ast.parse("(" + "".join(chunk) + ")", mode="eval").body
    except SyntaxError:
        raise NotCompilable("its source could not be parsed") from None
    return node.body if isinstance(node, ast.Lambda) else node


#: Definitions by code object: the def's source, written out once (or the NotCompilable).
_PARSED: dict = {}


def _definition(code):
    """``(arguments, body)`` of the def or lambda whose code is ``code``, a fresh tree.

    The source is found from the code object itself, never through ``__wrapped__``
    (``inspect.getsource`` of a decorated function gives the function it wraps). It is
    read once per code object and parsed again for each plan (``ast.parse`` is ten times
    faster than copying the tree).
    """
    hit = _PARSED.get(code)
    if hit is None:
        try:
            arguments, body = _parse_definition(code)
            node = ast.FunctionDef(name="f", args=arguments, body=body, decorator_list=[],
                                   returns=None, type_params=[])
            hit = ast.unparse(ast.fix_missing_locations(ast.Module([node], [])))
        except NotCompilable as why:
            hit = why
        _PARSED[code] = hit
    if isinstance(hit, NotCompilable):
        raise NotCompilable(str(hit))
    node = ast.parse(hit).body[0]
    return node.args, node.body


def _parse_definition(code):
    if code.co_name == "<lambda>":
        names = code.co_varnames[:code.co_argcount]
        arguments = ast.arguments(posonlyargs=[], args=[ast.arg(n) for n in names],
                                  vararg=None, kwonlyargs=[], kw_defaults=[], kwarg=None,
                                  defaults=[])
        if code.co_flags & (inspect.CO_VARARGS | inspect.CO_VARKEYWORDS) \
                or code.co_kwonlyargcount:
            raise NotCompilable("it is a lambda taking *args or keyword-only arguments")
        return arguments, [ast.Return(_lambda_body(code))]
    try:
        lines, _ = inspect.getsourcelines(code)
    except (OSError, TypeError) as error:
        raise NotCompilable(f"its source is not available ({error})") from None
    text = "".join(lines)
    if text[:1] in (" ", "\t"):  # a nested def: parse it inside a block, not dedented
        text = "if 1:\n" + text
    try:
        tree = ast.parse(text)
    except SyntaxError:
        raise NotCompilable("its source could not be parsed") from None
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef) and node.name == code.co_name:
            return node.args, node.body
    if any(isinstance(node, ast.AsyncFunctionDef) for node in ast.walk(tree)):
        raise NotCompilable("it is a coroutine")
    raise NotCompilable("its definition was not found in its source")


def function_node(fn):
    """The positional argument names and body statements of ``fn`` (a def or a lambda).

    The source is that of ``fn``'s own code: for a decorated function, the wrapper.

    Examples
    --------
    >>> names, body = function_node(lambda t, x, u, params: -x)
    >>> names, type(body[0]).__name__
    (['t', 'x', 'u', 'params'], 'Return')
    """
    fn = _jit.python_function(fn)
    if not isinstance(fn, types.FunctionType):
        raise NotCompilable(f"it is a {type(fn).__name__}, not a Python function")
    arguments, body = _definition(fn.__code__)
    return [a.arg for a in arguments.posonlyargs + arguments.args], body


# --- what Python calls ------------------------------------------------------------------

def call_target(fn):
    """``(function, bound positional values, bound keyword values)``: what calling ``fn`` runs.

    ``fn(t, x, u, params)`` runs ``function(*bound, t, x, u, params, **keywords)``. A
    :func:`functools.partial` adds its arguments, a bound method its ``self``, an object
    with ``__call__`` itself; a numba function is planned from its Python source.

    Raises
    ------
    NotCompilable
        For a callable that is none of these (a builtin, a C extension).

    Examples
    --------
    >>> import functools
    >>> def f(t, x, u, params, gain=1.0):
    ...     return gain * x
    >>> target, bound, keywords = call_target(functools.partial(f, gain=2.0))
    >>> target is f, bound, keywords
    (True, [], {'gain': 2.0})
    """
    fn = _jit.python_function(fn)
    if isinstance(fn, types.FunctionType):
        return fn, [], {}
    if isinstance(fn, functools.partial):
        target, bound, keywords = call_target(fn.func)
        return target, bound + list(fn.args), {**keywords, **fn.keywords}
    if isinstance(fn, types.MethodType):
        target, bound, keywords = call_target(fn.__func__)
        return target, bound + [fn.__self__], keywords
    call = vars(type(fn)).get("__call__") if callable(fn) else None
    for kind in type(fn).__mro__[1:]:
        call = call or vars(kind).get("__call__")
    if isinstance(call, types.FunctionType):
        return call, [fn], {}
    raise NotCompilable(f"it is a {type(fn).__name__}, not a Python function")


# --- plans -----------------------------------------------------------------------------------

class _Runtime:
    """Binding of an argument to a value known only when the function runs."""

    def __repr__(self):
        return "runtime"


#: A function argument given a value at run time (kept in the compiled signature).
RUNTIME = _Runtime()
#: A function argument that receives the run-time ``params`` (the packed vector, compiled).
PARAMS = "params"


@dataclass(eq=False)
class Frozen:
    """A function argument bound to a value known when the plan is made (dropped from
    the compiled signature): a partial's argument, a default, a method's ``self``.

    Examples
    --------
    >>> Frozen(2.0).value
    2.0
    """

    value: object


@dataclass(eq=False)
class Plan:
    """One function, specialised to how it is called: what the compiler needs.

    Attributes
    ----------
    function : function
        The Python function.
    name : str
        Its name in the generated module.
    arguments : list of str
        The arguments it keeps (the run-time ones), in order.
    body : list of ast.stmt
        Its statements, params reads as :data:`PARAM_READ` calls, helper calls renamed
        to their plans' names, values from outside renamed to the keys of ``frozen``.
    frozen : dict
        Module-level name -> value (a number, array, string, module or function) read
        from outside the function.
    helpers : list of Plan
        The plans of the functions it calls.
    keys : set
        The run-time ``params`` keys it reads itself.
    opaque : str or None
        Why the keys it reads cannot all be known (``params`` used otherwise than by key).
    problem : str or None
        Why it cannot be compiled.
    input_name : str or None
        The name of its argument bound to ``u`` (for the top plan).
    checks : list
        ``(read, value)`` for each value read from outside the function: ``read()`` reads
        it again (see :meth:`valid`).
    written : dict
        The compiler's text of the plan's functions, by parameter layout.

    Examples
    --------
    >>> def pi_output(t, x, u, params):
    ...     return params.get("kp", 0.5) * u[0] + params["ki"] * x[0]
    >>> plan = plan_function(pi_output)
    >>> plan.arguments, sorted(plan.keys), plan.why_not()
    (['t', 'x', 'u', 'params'], ['ki', 'kp'], None)
    """

    function: object
    name: str
    index: int = 0
    arguments: list = field(default_factory=list)
    body: list = field(default_factory=list)
    frozen: dict = field(default_factory=dict)
    helpers: list = field(default_factory=list)
    keys: set = field(default_factory=set)
    opaque: str | None = None
    problem: str | None = None
    input_name: str | None = None
    checks: list = field(default_factory=list)
    code: object = None
    defaults: object = None
    kwdefaults: object = None
    written: dict = field(default_factory=dict)

    def valid(self) -> bool:
        """Whether everything this plan (and each plan it calls) read from outside its
        function is still what it was: the same code and defaults, the same objects under
        the same names, the same numbers in the same attributes and dicts. Arrays are
        compared by identity: their contents are read again whenever code is written."""
        for plan in self.tree():
            fn = plan.function
            if fn.__code__ is not plan.code or fn.__defaults__ is not plan.defaults \
                    or fn.__kwdefaults__ is not plan.kwdefaults:
                return False
            if not all(_same(getter(), value) for getter, value in plan.checks):
                return False
        return True

    def tree(self):
        """This plan and every plan it calls, each once (callers first)."""
        seen, order, stack = set(), [], [self]
        while stack:
            plan = stack.pop()
            if id(plan) in seen:
                continue
            seen.add(id(plan))
            order.append(plan)
            stack.extend(reversed(plan.helpers))
        return order

    def params_read(self):
        """The run-time keys read by this plan and its helpers, or None if unknown."""
        keys = set()
        for plan in self.tree():
            if plan.opaque is not None:
                return None
            keys |= plan.keys
        return keys

    def why_not(self):
        """Why the plan cannot be compiled (the first reason found), or None."""
        for plan in self.tree():
            reason = plan.opaque or plan.problem
            if reason is not None:
                where = "" if plan.name == "user" else f" (in {plan.function.__qualname__})"
                return reason + where
        return None


def plan_function(fn):
    """The :class:`Plan` of ``fn`` called as python-control calls it, ``fn(t, x, u, params)``.

    Raises
    ------
    NotCompilable
        When ``fn`` is not a Python callable whose source can be read.

    Examples
    --------
    >>> def servo(t, x, u, params):
    ...     J, b = map(params.get, ["J", "b"])
    ...     return [x[1], (u[0] - b * x[1]) / J]
    >>> plan = plan_function(servo)
    >>> sorted(plan.params_read()), plan.why_not()
    (['J', 'b'], None)
    """
    try:
        cached = _PLANS.get(fn)
    except TypeError:  # not hashable or not weakly referable: planned each time
        cached = None
    if cached is not None and cached.valid():
        return cached
    target, bound, keywords = call_target(fn)
    build = _Build()
    call = [Frozen(v) for v in bound] + [RUNTIME, RUNTIME, RUNTIME, PARAMS]
    bindings = _bind(target, call, {k: Frozen(v) for k, v in keywords.items()})
    if isinstance(bindings, str):
        raise NotCompilable(bindings)
    _definition(target.__code__)  # no source: NotCompilable, nothing is known
    plan = build.plan(target, bindings, name="user")
    plan.input_name = _input_name(bindings)
    try:
        _PLANS[fn] = plan
    except TypeError:
        pass
    return plan


#: Plans by the callable they were made for, kept while it lives and used again while
#: :meth:`Plan.valid` (a simulation asks for each block's plans several times).
_PLANS = weakref.WeakKeyDictionary()


def _input_name(bindings):
    """The argument that receives ``u`` (the third of t, x, u, params)."""
    runtime = [name for name, b in bindings.items() if b is RUNTIME or b == PARAMS]
    return runtime[2] if len(runtime) == 4 else None


def _bind(fn, positional, keywords):
    """Each argument name of ``fn`` -> its binding, as Python would bind the call, or
    the reason it cannot be bound."""
    try:
        arguments, _ = _definition(fn.__code__)
    except NotCompilable as why:
        return str(why)
    if arguments.vararg is not None or arguments.kwarg is not None:
        return f"{fn.__qualname__} takes *args or **kwargs"
    names = [a.arg for a in arguments.posonlyargs + arguments.args]
    kwonly = [a.arg for a in arguments.kwonlyargs]
    if len(positional) > len(names):
        return f"{fn.__qualname__} is called with {len(positional)} arguments"
    bindings = dict(zip(names, positional, strict=False))
    for key, value in keywords.items():
        if key in bindings or key not in names + kwonly:
            return f"{fn.__qualname__} cannot take the argument {key!r}"
        bindings[key] = value
    defaults = dict(zip(names[len(names) - len(fn.__defaults__ or ()):],
                        fn.__defaults__ or (), strict=True))
    defaults.update(fn.__kwdefaults__ or {})
    for name in names + kwonly:
        if name not in bindings:
            if name not in defaults:
                return f"{fn.__qualname__} is called without its argument {name!r}"
            bindings[name] = Frozen(defaults[name])
    return {name: bindings[name] for name in names + kwonly}


def _binding_key(binding):
    if isinstance(binding, Frozen):
        return ("frozen", id(binding.value))
    return ("params",) if binding == PARAMS else ("runtime",)


class _Build:
    """The plans made for one function and its helpers (each specialisation once)."""

    def __init__(self):
        self.plans = {}
        self.count = 0

    def plan(self, fn, bindings, name=None):
        key = (fn, tuple((n, _binding_key(b)) for n, b in bindings.items()))
        if key in self.plans:
            return self.plans[key]
        self.count += 1
        plan = Plan(fn, name or f"_h{self.count}_{fn.__name__.strip('<>')}", self.count,
                    code=fn.__code__, defaults=fn.__defaults__, kwdefaults=fn.__kwdefaults__)
        self.plans[key] = plan
        try:
            _, body = _definition(fn.__code__)
        except NotCompilable as why:
            plan.problem = str(why)
            if any(b == PARAMS or _is_dict_binding(b) for b in bindings.values()):
                plan.opaque = f"params is handed to {fn.__qualname__}, whose source is unknown"
            return plan
        try:
            _Translator(self, plan, fn, bindings).translate(body)
        except Exception as error:  # noqa: BLE001 - a construct not foreseen: nothing known
            plan.problem = plan.opaque = (f"it could not be read ({type(error).__name__}: "
                                          f"{error})")
        return plan


def _is_dict_binding(binding):
    return isinstance(binding, Frozen) and isinstance(binding.value, dict)


# --- values read from outside ----------------------------------------------------------------

def _is_number(value):
    return isinstance(value, bool | int | float | complex | np.number | np.bool_)


def _is_array_like(value):
    """A numpy array, or a list or tuple of numbers (nested lists: a matrix)."""
    if isinstance(value, np.ndarray):
        return True
    if isinstance(value, list | tuple) and value:
        try:
            return np.asarray(value).dtype.kind in "biufc"
        except (ValueError, TypeError):
            return False
    return False


def _is_numeric_function(value):
    """A function numba compiles itself: numpy's, math's, a ufunc."""
    module = getattr(value, "__module__", None) or ""
    return callable(value) and not isinstance(value, type) and (
        isinstance(value, np.ufunc) or module.split(".")[0] in NUMERIC_MODULES)


def _is_numba_function(value):
    return hasattr(value, "py_func") and hasattr(value, "targetoptions")


def _is_plain(value):
    """A value the compiler can freeze as it is (not an object to read attributes of)."""
    return (value is None or isinstance(value, str) or _is_number(value)
            or _is_array_like(value) or isinstance(value, types.ModuleType)
            or _is_numeric_function(value) or _is_numba_function(value)
            or isinstance(value, types.FunctionType))


def _helper_allowed(fn):
    module = (getattr(fn, "__module__", None) or "").split(".")[0]
    return module not in _NOT_HELPERS


def _stored_names(body):
    """Names bound anywhere in ``body`` (assigned, loop targets, inner functions' args)."""
    names = set()
    for node in ast.walk(ast.Module(body, [])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store | ast.Del):
            names.add(node.id)
        elif isinstance(node, ast.arg):
            names.add(node.arg)
        elif isinstance(node, ast.FunctionDef | ast.ClassDef):
            names.add(node.name)
        elif isinstance(node, ast.ExceptHandler) and node.name:
            names.add(node.name)
        elif isinstance(node, ast.alias):
            names.add((node.asname or node.name).split(".")[0])
    return names


def _store_counts(body):
    counts = {}
    for node in ast.walk(ast.Module(body, [])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store | ast.Del):
            counts[node.id] = counts.get(node.id, 0) + 1
        elif isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Name):
            counts[node.target.id] = counts.get(node.target.id, 0) + 1
    return counts


def _string_items(node, lookup):
    """The strings of a literal list/tuple of strings (or of a name holding one), else None.

    ``lookup(name)`` is ``(found, value)`` for a name read from outside the function.
    """
    if isinstance(node, ast.List | ast.Tuple):
        if node.elts and all(isinstance(e, ast.Constant) and isinstance(e.value, str)
                             for e in node.elts):
            return [e.value for e in node.elts]
        return None
    if isinstance(node, ast.Name):
        found, value = lookup(node.id)
        if found and isinstance(value, list | tuple) and value \
                and all(isinstance(v, str) for v in value):
            return list(value)
    return None


class _Substitute(ast.NodeTransformer):
    """Loads of ``name`` -> a constant."""

    def __init__(self, name, value):
        self.name, self.value = name, value

    def visit_Name(self, node):
        if node.id == self.name and isinstance(node.ctx, ast.Load):
            return ast.copy_location(ast.Constant(self.value), node)
        return node


def _has_jump(statements):
    for node in ast.walk(ast.Module(statements, [])):
        if isinstance(node, ast.Break | ast.Continue):
            return True
    return False


class _Unroll(ast.NodeTransformer):
    """Loops and comprehensions over a literal sequence of strings (params keys), written
    out one copy per string, so that each key is a constant."""

    def __init__(self, lookup):
        self.lookup = lookup

    def visit_For(self, node):
        node = self.generic_visit(node)
        keys = _string_items(node.iter, self.lookup)
        if keys is None or not isinstance(node.target, ast.Name) or node.orelse \
                or _has_jump(node.body):
            return node
        out = []
        for key in keys:
            for stmt in copy.deepcopy(node.body):
                out.append(_Substitute(node.target.id, key).visit(stmt))
        return out or [ast.Pass()]

    def _expand(self, node, make):
        if len(node.generators) != 1:
            return node
        gen = node.generators[0]
        keys = _string_items(gen.iter, self.lookup)
        if keys is None or gen.ifs or not isinstance(gen.target, ast.Name):
            return node
        items = [_Substitute(gen.target.id, k).visit(copy.deepcopy(node.elt)) for k in keys]
        return ast.copy_location(make(items), node)

    def visit_ListComp(self, node):
        node = self.generic_visit(node)
        return self._expand(node, lambda items: ast.List(items, ast.Load()))

    def visit_GeneratorExp(self, node):
        node = self.generic_visit(node)
        return self._expand(node, lambda items: ast.Tuple(items, ast.Load()))


class _Translator(ast.NodeTransformer):
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
            elif _is_plain(binding.value) and not isinstance(binding.value, types.ModuleType
                                                                    | types.FunctionType):
                frozen = self._freeze_value(name, binding.value)
                prologue.append(ast.Assign([ast.Name(name, ast.Store())],
                                           ast.Name(frozen, ast.Load()), lineno=0))
                kept.add(name)
            else:
                self.fixed[name] = binding.value  # an object, a module, a function
        body = self._hoist_imports(body)
        body = [_Unroll(self._lookup).visit(stmt) for stmt in body]
        body = [s for stmt in body for s in (stmt if isinstance(stmt, list) else [stmt])]
        counts = _store_counts(body)
        self._find_aliases(body, counts)
        self._find_strings(body, counts)
        self.local = _stored_names(body) | kept | set(plan.arguments)
        self.local -= set(self.sources)
        for name in self.sources:
            if counts.get(name, 0) > (1 if name not in self.bindings else 0):
                self._opaque(f"params ({name!r}) is assigned more than once")
        body = [self.visit(stmt) for stmt in body]
        body = [s for stmt in body for s in (stmt if isinstance(stmt, list) else [stmt])]
        plan.body = prologue + body or [ast.Pass()]

    def _hoist_imports(self, body):
        kept = []
        for stmt in body:
            if isinstance(stmt, ast.Import):
                for alias in stmt.names:
                    module = importlib.import_module(alias.name)
                    if alias.asname:
                        self.fixed[alias.asname] = module
                    else:
                        self.fixed[alias.name.split(".")[0]] = importlib.import_module(
                            alias.name.split(".")[0])
            elif isinstance(stmt, ast.ImportFrom) and not stmt.level:
                module = importlib.import_module(stmt.module)
                for alias in stmt.names:
                    if alias.name == "*":
                        self._problem("it imports * inside itself")
                        continue
                    self.fixed[alias.asname or alias.name] = getattr(module, alias.name)
            else:
                kept.append(stmt)
        return kept

    def _find_aliases(self, body, counts):
        changed = True
        while changed:
            changed = False
            for node in ast.walk(ast.Module(body, [])):
                if isinstance(node, ast.Assign) and len(node.targets) == 1 \
                        and isinstance(node.targets[0], ast.Name) \
                        and isinstance(node.value, ast.Name) and node.value.id in self.sources \
                        and node.targets[0].id not in self.sources:
                    self.sources[node.targets[0].id] = self.sources[node.value.id]
                    changed = True

    def _find_strings(self, body, counts):
        for node in ast.walk(ast.Module(body, [])):
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
            self._opaque(f"params is read with a key that is not known: "
                         f"{ast.unparse(node)[:60]}")
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
        self.plan.checks.append((functools.partial(_global, source, key), source.get(
            key, _MISSING)))
        if how == "in":
            return ast.copy_location(ast.Constant(key in source), node)
        if key in source:
            return ast.copy_location(ast.Name(self._freeze_value(
                f"param_{len(self.plan.frozen)}", source[key]), ast.Load()), node)
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
        chain = self._chain(node)
        if chain is not None:
            return chain
        return self.generic_visit(node)

    def visit_Attribute(self, node):
        if self._is_source(node.value):
            self._opaque(f"it uses params.{node.attr}")
            return node
        chain = self._chain(node)
        if chain is not None:
            return chain
        return self.generic_visit(node)

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

    visit_Nonlocal = visit_Global

    def visit_Import(self, node):
        self._problem("it imports inside a block")
        return node

    visit_ImportFrom = visit_Import

    def visit_Call(self, node):
        f = node.func
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
                self._opaque(f"params is handed to {ast.unparse(f)[:40]}, which is not "
                             f"compiled")
                return node
        return self.generic_visit(node)

    # -- names and objects from outside -------------------------------------------------------

    def _lookup(self, name):
        """``(found, value)`` of a name read from outside the function, as Python finds it
        now (closure, module, builtins); the read is recorded for :meth:`Plan.valid`."""
        found, value, getter = self._lookup_getter(name)
        if getter is not None:  # (a builtin is checked for not being shadowed since)
            self.plan.checks.append((getter, getter()))
        return found, value

    def _lookup_getter(self, name):
        if name in self.fixed:
            return True, self.fixed[name], None
        code = self.fn.__code__
        if self.fn.__closure__ and name in code.co_freevars:
            cell = self.fn.__closure__[code.co_freevars.index(name)]
            return True, _cell(cell), functools.partial(_cell, cell)
        module = self.fn.__globals__
        getter = functools.partial(_global, module, name)
        value = getter()
        if value is not _MISSING:
            return True, value, getter
        if name in vars(builtins):
            return True, vars(builtins)[name], getter
        return False, None, getter

    def _root_getter(self, name):
        found, value, getter = self._lookup_getter(name)
        return getter if getter is not None else (lambda: value)

    def _free(self, node):
        """A name read from outside the function: frozen, imported, or a helper."""
        name = node.id
        found, value = self._lookup(name)
        if not found:
            self._problem(f"it reads {name!r}, which is not defined")
            return node
        if getattr(builtins, name, None) is value and name in vars(builtins):
            return node  # a builtin numba knows (or reports)
        if isinstance(value, types.FunctionType | functools.partial) \
                or _is_numba_function(value) and not self._importable(value):
            plan = self._helper_plan(value)
            return node if plan is None else ast.copy_location(ast.Name(plan.name, ast.Load()),
                                                               node)
        if not _is_plain(value):
            self._problem(f"it reads {name!r}, a {type(value).__name__}, which numba "
                          f"cannot compile")
            return node
        if value is np.clip:
            return ast.copy_location(ast.Name(self._freeze_value(name, _clip()), ast.Load()),
                                     node)
        if name not in self.renamed:
            self.renamed[name] = self._freeze_value(name, value)
        return ast.copy_location(ast.Name(self.renamed[name], ast.Load()), node)

    @staticmethod
    def _importable(value):
        fn = value.py_func
        module = getattr(fn, "__module__", None)
        if module in (None, "__main__") or "<" in fn.__qualname__:
            return False
        try:
            return getattr(importlib.import_module(module), fn.__name__, None) is value
        except ImportError:
            return False

    def _chain_parts(self, node):
        """``root, [steps]`` of ``root.a[b].c`` with constant subscripts, else None."""
        steps = []
        while isinstance(node, ast.Attribute | ast.Subscript):
            if isinstance(node, ast.Attribute):
                steps.append(("attr", node.attr))
            else:
                key = self._key(node.slice)
                if key is _UNKNOWN:
                    return None
                steps.append(("item", key))
            node = node.value
        if not isinstance(node, ast.Name) or node.id in self.local or node.id in self.sources:
            return None
        return node.id, steps[::-1]

    def _outside(self, node):
        """What ``obj.attr[...]`` read from an object or a user module is, evaluated now.

        Returns None when the chain is left to numba as written (its root is local, a
        number or an array, or a numeric module), else ``(value, text, rest)``: the value
        reached once a number, array or function is met (or the end), the text read so
        far and the steps left for numba. Raises what Python would raise reading it.
        """
        parts = self._chain_parts(node)
        if parts is None:
            return None
        root, steps = parts
        found, value = self._lookup(root)
        if not found or (_is_plain(value) and not isinstance(value, types.ModuleType)):
            return None
        if isinstance(value, types.ModuleType) and value.__name__.split(".")[0] \
                in NUMERIC_MODULES:
            return None
        done = 0
        while done < len(steps) and not (_is_plain(value) and not isinstance(
                value, types.ModuleType)):
            value = self._evaluate(value, steps[done:done + 1])
            done += 1
        if done:
            self.plan.checks.append((functools.partial(
                _reevaluate, self._root_getter(root), tuple(steps[:done])), value))
        text = root + "".join(f".{s}" if kind == "attr" else f"[{s!r}]"
                              for kind, s in steps[:done])
        return value, text, steps[done:]

    def _chain(self, node):
        """``obj.attr[...]`` read from an object or a module: evaluated now and frozen (a
        number, an array, a helper function), or None to leave ``node`` to numba."""
        parts = self._chain_parts(node)
        if parts is not None:
            found, value = self._lookup(parts[0])
            if found and isinstance(value, types.ModuleType) \
                    and value.__name__.split(".")[0] in NUMERIC_MODULES:
                try:
                    if self._evaluate(value, parts[1]) is np.clip:
                        return ast.copy_location(ast.Name(self._freeze_value(
                            "clip", _clip()), ast.Load()), node)
                except Exception:  # noqa: BLE001 - numba reports what does not exist
                    pass
                return None
        try:
            reached = self._outside(node)
        except Exception as error:  # noqa: BLE001 - what Python would raise, as a reason
            self._problem(f"reading {ast.unparse(node)[:60]} fails: {error!r}")
            return node
        if reached is None:
            return None
        value, text, rest = reached
        if isinstance(value, types.FunctionType | types.MethodType | functools.partial) \
                or _is_numba_function(value):
            if rest:
                self._problem(f"it reads {text} and then more of it")
                return node
            plan = self._helper_plan(value)
            return node if plan is None else ast.copy_location(
                ast.Name(plan.name, ast.Load()), node)
        if not _is_plain(value) or isinstance(value, types.ModuleType):
            self._problem(f"it reads {text}, a {type(value).__name__}, which numba cannot "
                          f"compile")
            return node
        frozen = ast.Name(self._freeze_value(f"{parts[0]}_{len(self.plan.frozen)}", value),
                          ast.Load())
        for kind, step in rest:
            frozen = (ast.Attribute(frozen, step, ast.Load()) if kind == "attr"
                      else ast.Subscript(frozen, ast.Constant(step), ast.Load()))
        return ast.copy_location(frozen, node)

    @staticmethod
    def _evaluate(value, steps):
        for kind, step in steps:
            value = getattr(value, step) if kind == "attr" else value[step]
        return value

    # -- helpers -------------------------------------------------------------------------------

    def _callee(self, f):
        """``(function, bound values, bound keywords)`` of a call's function, if a helper."""
        if isinstance(f, ast.Name):
            if f.id in self.local or f.id in self.sources:
                return None
            found, value = self._lookup(f.id)
            if not found:
                return None
        elif isinstance(f, ast.Attribute | ast.Subscript):
            try:
                reached = self._outside(f)
            except Exception:  # noqa: BLE001 - left to the visit, which reports it
                return None
            if reached is None or reached[2]:
                return None
            value = reached[0]
        else:
            return None
        if _is_numba_function(value) and self._importable(value):
            return None  # imported as it is
        if not (isinstance(value, types.FunctionType | types.MethodType | functools.partial)
                or _is_numba_function(value)):
            return None
        try:
            return call_target(value)
        except NotCompilable:
            return None

    def _argument_binding(self, arg):
        """How an argument at a call site binds: PARAMS, Frozen(value) or RUNTIME."""
        if self._is_source(arg):
            source = self.sources[arg.id]
            return PARAMS if source is RUNTIME else Frozen(source)
        key = self._key(arg) if isinstance(arg, ast.Name) else _UNKNOWN
        if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
            return Frozen(arg.value)
        if key is not _UNKNOWN and isinstance(key, str):
            return Frozen(key)
        if isinstance(arg, ast.Name) and arg.id not in self.local:
            found, value = self._lookup(arg.id)
            if found and not _is_plain(value):
                return Frozen(value)  # an object: its attributes are read by the helper
        if isinstance(arg, ast.Attribute | ast.Subscript):
            try:
                reached = self._outside(arg)
            except Exception:  # noqa: BLE001 - left to the visit, which reports it
                reached = None
            if reached is not None and not reached[2] and not _is_plain(reached[0]):
                return Frozen(reached[0])  # an object handed on (a dict: its params)
        return RUNTIME

    def _helper_call(self, node, fn, bound, keywords):
        if not _helper_allowed(fn):
            for arg in [*node.args, *(k.value for k in node.keywords)]:
                if self._is_source(arg):
                    self._opaque(f"params is handed to {fn.__qualname__}, which is not "
                                 f"compiled")
            self._problem(f"it calls {fn.__module__}.{fn.__qualname__}, which is not compiled")
            return node
        if any(isinstance(a, ast.Starred) for a in node.args) \
                or any(k.arg is None for k in node.keywords):
            if any(self._is_source(getattr(a, "value", a)) for a in
                   [*node.args, *(k.value for k in node.keywords)]):
                self._opaque("params is handed on with * or **")
            self._problem("it calls a function with *args or **kwargs")
            return node
        positional = [Frozen(v) for v in bound] + [self._argument_binding(a) for a in node.args]
        named = {k: Frozen(v) for k, v in keywords.items()}
        named.update({k.arg: self._argument_binding(k.value) for k in node.keywords})
        bindings = _bind(fn, positional, named)
        if isinstance(bindings, str):
            if any(b == PARAMS for b in positional + list(named.values())):
                self._opaque(f"params is handed to {fn.__qualname__}: {bindings}")
            self._problem(bindings)
            return node
        plan = self.build.plan(fn, bindings)
        self.plan.helpers.append(plan)
        # the run-time arguments, in the helper's order
        given = {}
        names = list(bindings)
        for i, a in enumerate(node.args):
            given[names[len(bound) + i]] = a
        for k in node.keywords:
            given[k.arg] = k.value
        args = []
        for name in plan.arguments:
            arg = given[name]
            args.append(arg if self._is_source(arg) else self.visit(arg))
        return ast.copy_location(ast.Call(ast.Name(plan.name, ast.Load()), args, []), node)

    def _helper_plan(self, value):
        """The plan of a function used as a value (all its arguments at run time)."""
        try:
            fn, bound, keywords = call_target(value)
        except NotCompilable as why:
            self._problem(str(why))
            return None
        if bound or keywords or not _helper_allowed(fn):
            self._problem(f"it uses {getattr(value, '__qualname__', value)!r} as a value")
            return None
        try:
            arguments, _ = _definition(fn.__code__)
        except NotCompilable as why:
            self._problem(f"{fn.__qualname__}: {why}")
            return None
        names = [a.arg for a in arguments.posonlyargs + arguments.args]
        plan = self.build.plan(fn, dict.fromkeys(names, RUNTIME))
        self.plan.helpers.append(plan)
        return plan


class _Unknown:
    def __repr__(self):
        return "<unknown>"


_UNKNOWN = _Unknown()


def _cell(cell):
    try:
        return cell.cell_contents
    except ValueError:  # an empty cell: a name defined later in the enclosing function
        return None


class _Missing:
    def __repr__(self):
        return "<missing>"


_MISSING = _Missing()


def _global(namespace, name):
    return namespace.get(name, _MISSING)


def _reevaluate(root, steps):
    try:
        return _Translator._evaluate(root(), steps)
    except Exception:  # noqa: BLE001 - not readable now: the plan is out of date
        return _MISSING


def _same(a, b) -> bool:
    """Whether a value read now is the one a plan was made with."""
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, str) or _is_number(a):
        return bool(a == b) or (a != a and b != b)
    if isinstance(a, types.MethodType):  # a new bound method object at each read
        return a.__func__ is b.__func__ and a.__self__ is b.__self__
    return False


def _clip():
    from .fast.usercode import clip  # the compiled clip that takes numbers too

    return clip


# --- what the params check and the engine ask ---------------------------------------------

def used_params(fn):
    """The ``params`` keys a ``(t, x, u, params)`` function reads, or None if unknown.

    Keys read through helpers it hands ``params`` to count; an alias, a key in a
    variable or ``map(params.get, [...])`` are understood. Where ``params`` is used in a
    way not understood (or the source is not available) the answer is None.

    Examples
    --------
    >>> sorted(used_params(lambda t, x, u, params: params["k"] * x + params.get("b", 0.0)))
    ['b', 'k']
    >>> def f(t, x, u, params):
    ...     p = params
    ...     return [p["gain"] * u[0]]
    >>> used_params(f)
    {'gain'}
    >>> used_params(lambda t, x, u, params: sum(params.values())) is None
    True
    """
    try:
        return plan_function(fn).params_read()
    except NotCompilable:
        return None


def reads_input(fn):
    """Whether a ``(t, x, u, params)`` function reads ``u`` (None when its source is unknown).

    Examples
    --------
    >>> reads_input(lambda t, x, u, params: 2 * x)
    False
    """
    try:
        target, bound, keywords = call_target(fn)
        _, body = _definition(target.__code__)
    except NotCompilable:
        return None
    call = [Frozen(v) for v in bound] + [RUNTIME, RUNTIME, RUNTIME, PARAMS]
    bindings = _bind(target, call, {k: Frozen(v) for k, v in keywords.items()})
    name = None if isinstance(bindings, str) else _input_name(bindings)
    if name is None:
        return None
    return any(isinstance(n, ast.Name) and n.id == name
               for n in ast.walk(ast.Module(body, [])))
