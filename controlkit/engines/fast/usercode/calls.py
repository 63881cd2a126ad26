"""What a user function's compiled text calls instead of numba's own operations, where
numba's numbers are not Python's or numpy's (:mod:`controlkit.kernels.user_calls`,
:mod:`controlkit.kernels.numpy_calls`): ``a @ b``, ``a ** b``, ``math.pow``, ``np.sum``,
``np.mean``, ``np.linalg.norm``, ``np.trace``, their methods, the LU of
``np.linalg.solve``, ``det``, ``slogdet``, numpy's signed zeros (``np.sign``, ``maximum``,
``minimum``, ``mod``, ``floor_divide``, ``divmod``), integers of floats (``int``,
``round``, ``math.floor``, ``ceil``, ``trunc``), Python's ``sum`` and ``pow``, and
``math``'s overflows; ``a.var()``, ``a.std()``, numpy's scalar types narrower than 64 bits
and calls of those functions with arguments their compiled forms do not take refused.
"""

from __future__ import annotations

import ast
import builtins
import inspect
import math
import types as pytypes

import numpy as np

from ...source import NotCompilable, as_written

#: ``math``'s functions that raise where numba's return inf or NaN (an overflow, an
#: argument outside the domain): compiled user code calls ``math_<name>`` of
#: :mod:`controlkit.kernels.user_calls` instead, which raises Python's error.
RAISING = ("exp", "expm1", "sinh", "cosh", "sqrt", "log", "log10", "log2", "log1p", "acos",
           "asin", "acosh", "atanh")


class Calls(ast.NodeTransformer):
    """The rewrites of a function's statements, ``frozen`` its values from outside:
    ``a @ b`` -> ``_ck_matmul(a, b)`` (numpy's sums), ``a ** b`` and ``math.pow(a, b)`` ->
    ``_ck_power`` (Python's ``pow``), ``np.sum``, ``np.mean``, ``np.linalg.norm``,
    ``a.sum()``, ``a.mean()`` -> ``_ck_sum``, ``_ck_mean``, ``_ck_norm`` (numpy's order).

    Examples
    --------
    >>> import numpy as np
    >>> tree = Calls({"np": np}).visit(ast.parse("y = np.sum(x ** 3) + v.mean()"))
    >>> ast.unparse(tree)
    'y = _ck_sum(_ck_power(x, 3)) + _ck_mean(v)'
    """

    #: Operators and what is called instead
    CALLS = {ast.MatMult: "_ck_matmul", ast.Pow: "_ck_power"}
    #: Functions whose numbers numba's own would not give: what is called instead
    INSTEAD = {np.sum: "_ck_sum", np.mean: "_ck_mean", np.linalg.norm: "_ck_norm",
               np.dot: "_ck_dot", np.trace: "_ck_trace", np.linalg.solve: "_ck_solve",
               np.linalg.det: "_ck_det", np.linalg.slogdet: "_ck_slogdet",
               np.sign: "_ck_sign", np.maximum: "_ck_maximum", np.minimum: "_ck_minimum",
               np.mod: "_ck_mod", np.floor_divide: "_ck_floor_divide",
               np.divmod: "_ck_divmod", builtins.sum: "_ck_python_sum",
               # math's functions that raise in Python, where numba's return inf or NaN
               **{getattr(math, name): f"_ck_math_{name}" for name in RAISING}}
    #: Python's functions that make an integer of a float: their argument is checked first
    INTEGERS = (builtins.int, builtins.round, math.floor, math.ceil, math.trunc)
    #: ``math``'s functions numba does not compile (0.59-0.68): a function calling one runs
    #: as Python from the start, where numba's refusal cost a compile first (0.4-1 s)
    NUMBA_LACKS = tuple(getattr(math, name) for name in (
        "cbrt", "dist", "fmod", "fsum", "isclose", "isqrt", "lcm", "modf", "prod",
        "remainder", "ulp") if hasattr(math, name))
    #: numpy's functions of a sequence of arrays, which numba takes as a tuple only
    SEQUENCES = (np.concatenate, np.stack, np.vstack, np.hstack, np.column_stack)
    #: What the rewritten text calls: ``_ck_<name>`` is ``<name>`` of
    #: :mod:`controlkit.kernels.numpy_calls`, else ``<function>`` of :mod:`.user_calls`
    NUMPY_CALLS = ("sum", "mean", "norm", "trace", "solve", "det", "slogdet", "sign",
                   "maximum", "minimum", "mod", "floor_divide", "divmod")
    USER_CALLS = {"_ck_matmul": "matmul", "_ck_dot": "numpy_dot", "_ck_int64": "within_int64",
                  "_ck_invert": "invert",
                  "_ck_python_sum": "python_sum", "_ck_missing": "missing_parameter",
                  "store": "store", **{f"_ck_math_{name}": f"math_{name}"
                                       for name in RAISING}}

    def __init__(self, frozen):
        self.frozen = frozen

    def _target(self, f):
        """What ``f`` names among the module's frozen values (a module's attribute too, a
        builtin the function does not shadow)."""
        if isinstance(f, ast.Name):
            if f.id == "_np_":
                return np
            return self.frozen.get(f.id, getattr(builtins, f.id, None))
        if isinstance(f, ast.Attribute):
            module = self._target(f.value)
            if isinstance(module, pytypes.ModuleType):
                return getattr(module, f.attr, None)
        return None

    def _as_value(self, node):  # (s = np.sum; s(v): numba's own sum, other last bits)
        target = None if getattr(node, "_called", False) or isinstance(node, ast.Name) and \
            node.id not in self.frozen else self._target(node)  # (a local named sum: no)
        if callable(target) and (target in self.INSTEAD or target in (builtins.pow, math.pow)):
            raise NotCompilable(f"it uses {as_written(ast.unparse(node))[:30]} otherwise than "
                                f"in a call of it by name, where compiled code would call "
                                f"numba's own, with other numbers")
        return self.generic_visit(node)

    visit_Name = visit_Attribute = _as_value

    def visit_Call(self, node):
        node.func._called = True
        node = self.generic_visit(node)
        f, target = node.func, self._target(node.func)
        name = self.INSTEAD.get(target) if callable(target) else None
        if target is builtins.pow and len(node.args) == 2 and not node.keywords:
            # pow(a, b) is a ** b (three arguments: an integer power modulo, numba's own)
            return ast.copy_location(ast.Call(ast.Name("_ck_power", ast.Load()), node.args,
                                              []), node)
        if target is math.pow and len(node.args) == 2 and not node.keywords:
            # math.pow(a, b) -> _ck_power(float(a), float(b))
            floats = [ast.Call(ast.Name("float", ast.Load()), [a], []) for a in node.args]
            return ast.copy_location(ast.Call(ast.Name("_ck_power", ast.Load()), floats, []), node)
        if name is not None:
            return ast.copy_location(_taken(name, node, node.args), node)
        if any(target is f for f in self.NUMBA_LACKS):
            raise NotCompilable(f"it calls math.{target.__name__}, which numba does not "
                                f"compile")
        if any(target is f for f in self.SEQUENCES) and node.args \
                and isinstance(node.args[0], ast.List):  # [a, b] -> (a, b): the same arrays
            node.args[0] = ast.copy_location(ast.Tuple(node.args[0].elts, ast.Load()),
                                             node.args[0])
            return node
        if target is builtins.float and len(node.args) == 1 and not node.keywords and (
                isinstance(node.args[0], ast.Compare) or isinstance(node.args[0], ast.UnaryOp)
                and isinstance(node.args[0].op, ast.Not)):  # float(u > 0.5): numba's takes
            return ast.copy_location(ast.IfExp(node.args[0], ast.Constant(1.0),  # numbers
                                               ast.Constant(0.0)), node)
        if any(target is f for f in self.INTEGERS) and len(node.args) == 1 \
                and not node.keywords:  # int(x) -> int(_ck_int64(x)); round(x, n) is a float
            node.args = [ast.Call(ast.Name("_ck_int64", ast.Load()), node.args, [])]
            return node
        if isinstance(f, ast.Attribute) and f.attr in ("var", "std") and target is None \
                and not isinstance(self._target(f.value), pytypes.ModuleType):
            raise NotCompilable(f"it calls .{f.attr}() of an array, which numba sums in "
                                "another order than numpy, with other last bits")
        if isinstance(f, ast.Attribute) and f.attr in ("sum", "mean", "dot", "trace") \
                and target is None \
                and not isinstance(self._target(f.value), pytypes.ModuleType):
            # an array's own a.sum(), a.mean(), a.dot(b), a.trace()
            return ast.copy_location(_taken(f"_ck_{f.attr}", node, [f.value, *node.args]),
                                     node)
        return node

    def visit_GeneratorExp(self, node):
        raise NotCompilable(f"it uses a generator expression ({ast.unparse(node)[:40]}), "
                            f"which numba does not compile (a list comprehension compiles)")

    def visit_BinOp(self, node):
        node = self.generic_visit(node)
        name = self.CALLS.get(type(node.op))
        if name is None:
            return node
        return ast.copy_location(ast.Call(ast.Name(name, ast.Load()),
                                          [node.left, node.right], []), node)

    def visit_UnaryOp(self, node):  # ~a -> _ck_invert(a): a Python bool's ~ is not numpy's
        node = self.generic_visit(node)
        if not isinstance(node.op, ast.Invert) or isinstance(node.operand, ast.Call) and \
                isinstance(self._target(node.operand.func), np.ufunc):
            return node  # (~np.isnan(v): numpy's bool, whose ~ is numba's)
        return ast.copy_location(ast.Call(ast.Name("_ck_invert", ast.Load()), [node.operand],
                                          []), node)

    def visit_AugAssign(self, node):  # y **= 3, the same as y = y ** 3 for a name
        node = self.generic_visit(node)
        if type(node.op) not in self.CALLS or not isinstance(node.target, ast.Name):
            return node
        value = self.visit_BinOp(ast.copy_location(ast.BinOp(
            ast.Name(node.target.id, ast.Load()), node.op, node.value), node))
        return ast.copy_location(ast.Assign([node.target], value), node)


def _taken(name, call, args):
    """The call of ``name`` (a value of :attr:`Calls.INSTEAD`) with ``args`` and the
    keywords of ``call``, which it must take: numba's own function takes more (an axis, an
    ord), and gives other numbers."""
    from ....kernels import numpy_calls, user_calls

    function = getattr(numpy_calls, f"numpy_{name.removeprefix('_ck_')}", None) or getattr(
        user_calls, Calls.USER_CALLS[name])
    parameters = list(inspect.signature(function).parameters.values())
    try:
        inspect.Signature(parameters).bind(*args, **{k.arg: k for k in call.keywords})
    except TypeError:
        called = as_written(ast.unparse(call))[:50]
        if "_ck_" in called:  # (arguments rewritten already, x ** 2 as _ck_power: not shown)
            given = [*(["..."] * len(call.args)), *(f"{k.arg}=..." for k in call.keywords)]
            called = f"{as_written(ast.unparse(call.func))[:30]}({', '.join(given)})"
        raise NotCompilable(f"it calls {called}: its compiled form takes "
                            f"({', '.join(p.name for p in parameters)}) only (numba's own "
                            f"gives other numbers, or none)") from None
    return ast.Call(ast.Name(name, ast.Load()), args, call.keywords)
