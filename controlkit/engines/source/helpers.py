"""The part of the translator that plans the functions a function calls: each call site
bound as Python binds it, the callee planned for those bindings (once per kind of
binding), the call renamed to the helper's plan.
"""

from __future__ import annotations

import ast
import functools
import types

from .reading import PARAMS, RUNTIME, Frozen, NotCompilable, _bind, _definition, call_target
from .values import _helper_allowed, _is_numba_function, _is_plain


class _HelperCalls:
    """Methods of :class:`~.translator._Translator` for calls to helper functions (it
    provides ``build``, ``plan``, ``local``, ``sources``, the lookups of
    :class:`~.outside._OutsideReads` and the recording methods)."""

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
        key = self._key(arg) if isinstance(arg, ast.Name | ast.Constant) else None
        if isinstance(key, str):
            return Frozen(key)  # a key handed on
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
        given = dict(zip(list(bindings)[len(bound):], node.args, strict=False))
        given.update((k.arg, k.value) for k in node.keywords)
        args = [given[name] if self._is_source(given[name]) else self.visit(given[name])
                for name in plan.arguments]
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
            arguments, _ = _definition(fn.__code__, copy=False)
        except NotCompilable as why:
            self._problem(f"{fn.__qualname__}: {why}")
            return None
        names = [a.arg for a in arguments.posonlyargs + arguments.args]
        plan = self.build.plan(fn, dict.fromkeys(names, RUNTIME))
        self.plan.helpers.append(plan)
        return plan

