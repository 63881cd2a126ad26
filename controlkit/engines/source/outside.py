"""The part of the translator that reads names and objects from outside the function: a
number or array frozen, a function planned as a helper, ``obj.attr[...]`` evaluated now.
"""

from __future__ import annotations

import ast
import builtins
import functools
import importlib
import types

import numpy as np

from ...kernels.user_calls import clip
from .values import (
    _MISSING,
    _UNKNOWN,
    NUMERIC_MODULES,
    _cell,
    _evaluate,
    _is_numba_function,
    _is_plain,
    _reevaluate,
)


class _OutsideReads:
    """Methods of :class:`~.translator._Translator` for names read from outside the function
    (it provides ``fn``, ``fixed``, ``local``, ``sources``, ``renamed``, ``plan`` and the
    recording methods)."""

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
        if isinstance(value, types.FunctionType | functools.partial) \
                or _is_numba_function(value) and not self._importable(value):
            plan = self._helper_plan(value)
            return node if plan is None else ast.copy_location(ast.Name(plan.name, ast.Load()),
                                                               node)
        if not _is_plain(value):
            self._problem(f"it reads {name!r}, a {type(value).__name__}, which numba "
                          f"cannot compile")
            return node
        if name not in self.renamed:  # (np.clip: the compiled clip, which takes numbers too)
            self.renamed[name] = self._freeze_value(name, clip if value is np.clip else value)
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
                    if _evaluate(value, parts[1]) is np.clip:
                        return ast.copy_location(ast.Name(self._freeze_value(
                            "clip", clip), ast.Load()), node)
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
