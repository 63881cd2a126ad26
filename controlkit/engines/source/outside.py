"""The part of the translator that reads names and objects from outside the function: a
number or array frozen, ``obj.attr[...]`` evaluated now, a function planned as a helper
(each call site bound as Python binds it, the callee planned for those bindings, once per
kind of binding, and the call renamed to the helper's plan).
"""

from __future__ import annotations

import ast
import builtins
import functools
import types

import numpy as np

from ...kernels.user_calls import clip
from .reading import PARAMS, RUNTIME, Frozen, NotCompilable, _bind, _definition, call_target
from .values import (
    _MISSING,
    _UNKNOWN,
    NUMERIC_MODULES,
    _cell,
    _evaluate,
    _helper_allowed,
    _import_name,
    _is_numba_function,
    _is_plain,
    _reevaluate,
    numpy_last_bits,
)


def _items(value):
    """A list's items as they are now (a tuple), else None."""
    return tuple(value) if isinstance(value, list) else None


class _OutsideReads:
    """Methods of :class:`~.translator._Translator` for names read from outside the function
    and calls to helper functions (it provides ``build``, ``fn``, ``fixed``, ``local``,
    ``sources``, ``renamed``, ``plan`` and the recording methods)."""

    def _lookup(self, name):
        """``(found, value)`` of a name read from outside the function, as Python finds it
        now (closure, module, builtins); the read is recorded for :meth:`Plan.valid`."""
        found, value, getter = self._lookup_getter(name)
        if getter is not None:  # (a builtin is checked for not being shadowed since)
            self.plan.checks.append((getter, getter()))
        if isinstance(value, list):  # its strings may be written into the plan (a loop over
            # keys unrolled): changed in place, they are another plan
            read = getter or (lambda: value)
            self.plan.checks.append((lambda: _items(read()), _items(value)))
        return found, value

    def _lookup_getter(self, name):
        if name in self.fixed:
            return True, self.fixed[name], None
        code = self.fn.__code__
        if self.fn.__closure__ and name in code.co_freevars:
            cell = self.fn.__closure__[code.co_freevars.index(name)]
            return True, _cell(cell), functools.partial(_cell, cell)
        module = self.fn.__globals__
        getter = functools.partial(module.get, name, _MISSING)
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
        return self._value_read(name, value, node)

    def _value_read(self, name, value, node, key=None):
        """``node``, which reads ``value`` from outside the function (by ``name``, or by
        ``key`` from a dict known now), as compiled code reads it: frozen, a helper's plan,
        or left as it is with the reason it cannot be compiled."""
        why = numpy_last_bits(value)
        if why:
            self._problem(why)
            return node
        if isinstance(value, types.FunctionType | functools.partial) \
                or _is_numba_function(value) and not self._importable(value):
            return self._helper_name(value, node)
        shown = name if key is None else f"{name}[{key!r}]"
        if not _is_plain(value):
            self._problem(f"it reads {shown!r}, a {type(value).__name__}, which numba "
                          f"cannot compile")
            return node
        value = clip if value is np.clip else value  # (the compiled clip takes numbers too)
        if key is not None:  # (each read its own frozen name)
            return ast.copy_location(ast.Name(self._freeze_value(
                f"param_{len(self.plan.frozen)}", value), ast.Load()), node)
        if name not in self.renamed:
            self.renamed[name] = self._freeze_value(name, value)
        return ast.copy_location(ast.Name(self.renamed[name], ast.Load()), node)

    @staticmethod
    def _importable(value):
        fn = value.py_func
        return fn.__module__ != "__main__" and "<" not in fn.__qualname__ \
            and _import_name(value) is not None

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
        if isinstance(value, types.ModuleType) and value.__name__.split(".")[0] in NUMERIC_MODULES:
            return None
        done = 0
        while done < len(steps) and not (_is_plain(value) and not isinstance(
                value, types.ModuleType)):
            value = _evaluate(value, steps[done:done + 1])
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
                    target = _evaluate(value, parts[1])
                except Exception:  # noqa: BLE001 - numba reports what does not exist
                    return None
                if target is np.clip:
                    return ast.copy_location(ast.Name(self._freeze_value(
                        "clip", clip), ast.Load()), node)
                why = numpy_last_bits(target)
                if why:
                    self._problem(why)
                    return node
                return None
        try:
            reached = self._outside(node)
        except Exception as error:  # noqa: BLE001 - what Python would raise, as a reason
            self._problem(f"reading {ast.unparse(node)[:60]} fails: {error!r}")
            return node
        if reached is None:
            return None
        value, text, rest = reached
        why = numpy_last_bits(value)  # (a method: rng.normal of a Generator)
        if why:
            self._problem(why)
            return node
        if isinstance(value, types.FunctionType | types.MethodType | functools.partial) \
                or _is_numba_function(value):
            if rest:
                self._problem(f"it reads {text} and then more of it")
                return node
            return self._helper_name(value, node)
        if not _is_plain(value) or isinstance(value, types.ModuleType):
            self._problem(f"it reads {text}, a {type(value).__name__}, which numba cannot compile")
            return node
        frozen = ast.Name(self._freeze_value(f"{parts[0]}_{len(self.plan.frozen)}", value),
                          ast.Load())
        for kind, step in rest:
            frozen = (ast.Attribute(frozen, step, ast.Load()) if kind == "attr"
                      else ast.Subscript(frozen, ast.Constant(step), ast.Load()))
        return ast.copy_location(frozen, node)

    # -- calls to helper functions -----------------------------------------------------------

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
                    self._opaque(f"params is handed to {fn.__qualname__}, which is not compiled")
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

    def _helper_name(self, value, node):
        """``node``, a function used as a value, renamed to its plan (all its arguments at
        run time); left as it is when it cannot be planned."""
        try:
            fn, bound, keywords = call_target(value)
        except NotCompilable as why:  # (PART = partial(np.tanh): "it uses PART: it is a ufunc")
            shown = ast.unparse(node)[:40]
            self._problem(str(why) if shown in str(why) else f"it uses {shown}: {why}")
            return node
        if bound or keywords or not _helper_allowed(fn):
            self._problem(f"it uses {getattr(value, '__qualname__', value)!r} as a value")
            return node
        try:
            arguments, _ = _definition(fn.__code__, copy=False)
        except NotCompilable as why:
            self._problem(f"{fn.__qualname__}: {why}")
            return node
        names = [a.arg for a in arguments.posonlyargs + arguments.args]
        plan = self.build.plan(fn, dict.fromkeys(names, RUNTIME))
        self.plan.helpers.append(plan)
        return ast.copy_location(ast.Name(plan.name, ast.Load()), node)
