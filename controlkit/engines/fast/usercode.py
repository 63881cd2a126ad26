"""Turning a user's ``(t, x, u, params)`` function into a kernel the fast engine can call.

python-control documents update and output functions as ``f(t, x, u, params)``
with ``params`` a dict. numba cannot compile a dict of mixed values, but the
values in force for one simulation are fixed: this module reads the
function's source, replaces ``params["k"]`` and ``params.get("k", default)``
by the value in force, freezes the function's globals and closure variables
(numbers, numpy arrays, modules, compiled functions) as module-level
constants, and writes the result as a small module next to the engine's
loops, where numba compiles and caches it. The kernel it returns has the
block contract's signature ``kernel(t, x, u, p, out)`` (``p`` unused).

A function that cannot be rewritten or compiled (no source, a call of a plain
Python object, a ``params`` used otherwise than by key) gets the reason
instead; the engine then calls it from Python inside its own loop.
"""

from __future__ import annotations

import ast
import builtins
import copy
import hashlib
import importlib.util
import os
import sys as pysys
import types as pytypes
from pathlib import Path

import numpy as np

from ... import _jit
from ..source import NotCompilable, function_node


def store(r, out):
    """Copy a user function's result (number, sequence or array) into ``out``.

    Examples
    --------
    >>> store([1.0, 2.0], np.empty(2)).tolist()
    [1.0, 2.0]
    """
    out[:] = np.asarray(r, dtype=float).reshape(-1)
    return out


if _jit.HAVE_NUMBA:
    from numba import types as _nbtypes
    from numba.extending import overload

    @overload(store)
    def _store_overload(r, out):
        if isinstance(r, _nbtypes.Number):
            def impl(r, out):
                out[0] = r
                return out
        elif isinstance(r, _nbtypes.Array):
            def impl(r, out):
                flat = r.ravel()
                for i in range(out.size):
                    out[i] = flat[i]
                return out
        elif isinstance(r, (_nbtypes.UniTuple, _nbtypes.List)):
            def impl(r, out):
                for i in range(len(r)):
                    out[i] = r[i]
                return out
        else:
            return None
        return impl


class _Params(ast.NodeTransformer):
    """``params["k"]`` and ``params.get("k", d)`` -> a frozen constant's name."""

    def __init__(self, name, values):
        self.name, self.values, self.used = name, values, {}

    def _constant(self, key, node):
        if key not in self.values:
            return None
        alias = f"_param_{len(self.used)}" if key not in self.used else self.used[key][0]
        self.used[key] = (alias, self.values[key])
        return ast.copy_location(ast.Name(alias, ast.Load()), node)

    def visit_Subscript(self, node):
        if (isinstance(node.value, ast.Name) and node.value.id == self.name
                and isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, str)):
            key = node.slice.value
            if key not in self.values:
                raise NotCompilable(f"params has no key {key!r}")
            return self._constant(key, node)
        return self.generic_visit(node)

    def visit_Call(self, node):
        f = node.func
        if (isinstance(f, ast.Attribute) and f.attr == "get" and isinstance(f.value, ast.Name)
                and f.value.id == self.name and node.args
                and isinstance(node.args[0], ast.Constant) and not node.keywords):
            key = node.args[0].value
            if key in self.values:
                return self._constant(key, node)
            if len(node.args) == 2:
                return self.visit(node.args[1])
            return ast.copy_location(ast.Constant(None), node)
        return self.generic_visit(node)


def _literal(name, value, lines, imports):
    """A module-level line freezing ``value`` as ``name`` (or NotCompilable)."""
    if isinstance(value, pytypes.ModuleType):
        imports.append(f"import {value.__name__} as {name}")
    elif isinstance(value, (bool, int, float)) or value is None:
        lines.append(f"{name} = {value!r}")
    elif isinstance(value, complex):
        lines.append(f"{name} = complex({value.real!r}, {value.imag!r})")
    elif isinstance(value, (np.ndarray, np.generic, list, tuple)):
        array = np.asarray(value)
        if array.dtype.kind not in "biuf":
            raise NotCompilable(f"{name} is not a numeric array")
        text = repr(array.tolist()).replace("inf", "_np_.inf").replace("nan", "_np_.nan")
        if isinstance(value, (np.ndarray, list)) or array.ndim:
            lines.append(f"{name} = _np_.array({text}, dtype=_np_.{array.dtype.name})")
        else:
            lines.append(f"{name} = _np_.{array.dtype.name}({text})")
    elif hasattr(value, "py_func") and hasattr(value, "targetoptions"):  # a numba function
        module = value.py_func.__module__
        if module in (None, "__main__") or "<" in value.py_func.__qualname__:
            raise NotCompilable(f"it calls the compiled function {name} defined in a notebook; "
                                f"define it in the same cell as a plain function instead")
        imports.append(f"from {module} import {value.py_func.__name__} as {name}")
    elif callable(value) and getattr(value, "__module__", None) in ("numpy", "math"):
        imports.append(f"from {value.__module__} import {value.__name__} as {name}")
    else:
        raise NotCompilable(f"it reads {name!r}, a {type(value).__name__}, which numba "
                            f"cannot compile")


def _free_names(args, body):
    stored = set(args)
    loaded = []
    for node in ast.walk(ast.Module(body, [])):
        if isinstance(node, ast.Name):
            if isinstance(node.ctx, ast.Store):
                stored.add(node.id)
            elif node.id not in loaded:
                loaded.append(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.Lambda)):
            raise NotCompilable("it defines a function inside itself")
    return [n for n in loaded if n not in stored]


def _literal_items(value):
    """The elements of ``[a, b]``, ``(a, b)`` or ``np.array([a, b])``, else None."""
    if isinstance(value, ast.Call) and isinstance(value.func, ast.Attribute) \
            and value.func.attr in ("array", "asarray") and len(value.args) == 1 \
            and not value.keywords:
        value = value.args[0]
    if isinstance(value, (ast.List, ast.Tuple)) and not any(
            isinstance(e, ast.Starred) for e in value.elts):
        return value.elts
    return None


class _WriteOut(ast.NodeTransformer):
    """``return [a, b]`` -> ``out[0] = a; out[1] = b; return out``: no array per call."""

    def visit_Return(self, node):
        items = _literal_items(node.value)
        if items is None:
            raise NotCompilable("not a literal return")
        lines = [ast.Assign([ast.Subscript(ast.Name("out", ast.Load()), ast.Constant(i),
                                           ast.Store())], item) for i, item in enumerate(items)]
        return [*lines, ast.Return(ast.Name("out", ast.Load()))]

    def visit_FunctionDef(self, node):
        return node


def kernel_source(fn, values: dict, direct: bool = True) -> str:
    """The module source of the kernel compiled from ``fn`` with the parameter ``values``.

    Raises
    ------
    NotCompilable
        Saying why ``fn`` cannot be turned into a kernel.

    Examples
    --------
    >>> src = kernel_source(lambda t, x, u, params: params["k"] * x, {"k": 2.0})
    >>> "_param_0 = 2.0" in src
    True
    """
    fn = _jit.python_function(fn)
    if not isinstance(fn, pytypes.FunctionType):
        raise NotCompilable(f"it is a {type(fn).__name__}, not a Python function")
    key = (fn.__code__, frozenset(k for k in values if isinstance(k, str)), bool(direct))
    template = _TEMPLATES.get(key)
    if template is None:
        try:
            template = _template(fn, key[1], direct)
        except NotCompilable as why:
            template = why
        _TEMPLATES[key] = template
    if isinstance(template, NotCompilable):
        raise NotCompilable(str(template))
    user, call, aliases, free = template
    scope = dict(fn.__globals__)
    if fn.__closure__:
        scope.update(zip(fn.__code__.co_freevars,
                         (c.cell_contents for c in fn.__closure__), strict=True))
    lines = []
    imports = ["import numpy as _np_", "from controlkit.engines.fast.usercode import store"]
    for name, alias in aliases.items():
        value = values[name]
        if isinstance(value, (list, tuple)):
            value = np.asarray(value, dtype=float)
        _literal(alias, value, lines, imports)
    for name in free:
        if name in scope:
            _literal(name, scope[name], lines, imports)
        elif not hasattr(builtins, name):
            raise NotCompilable(f"it reads {name!r}, which is not defined")
    return "\n".join([
        f"# generated by controlkit from {fn.__qualname__} ({fn.__code__.co_filename}): "
        f"do not edit",
        *imports, *lines, "", "", user, "", "",
        "def kernel(t, x, u, p, out):",
        call,
        "",
    ])


#: Rewritten functions by (code, parameter names given, direct): parsing is the costly part.
_TEMPLATES: dict = {}


def _template(fn, keys, direct):
    """``(user source, kernel call line, {param: alias}, free names)`` of ``fn``."""
    args, body = function_node(fn)
    rewrite = _Params(args[3], dict.fromkeys(keys))
    body = [rewrite.visit(stmt) for stmt in body]
    for node in ast.walk(ast.Module(body, [])):
        if isinstance(node, ast.Name) and node.id == args[3]:
            raise NotCompilable("it uses params other than as params['key'] or "
                                "params.get('key', default)")
    free = [n for n in _free_names(args, body) if not n.startswith("_param_")]
    arguments = ast.arguments(posonlyargs=[], args=[ast.arg(a) for a in args], kwonlyargs=[],
                              kw_defaults=[], defaults=[])
    user = ast.FunctionDef(name="user", args=arguments, body=body, decorator_list=[],
                           returns=None, type_params=[])
    user = ast.unparse(ast.fix_missing_locations(ast.Module([user], [])))
    call = f"    return store(user(t, x, u, {None!r}), out)"
    if direct and "out" not in args and all(
            _literal_items(n.value) is not None for n in ast.walk(ast.Module(body, []))
            if isinstance(n, ast.Return)):
        # every return is a literal list: write its items into out (no array per call)
        written = [_WriteOut().visit(stmt) for stmt in copy.deepcopy(body)]
        written = [line for stmt in written for line in (stmt if isinstance(stmt, list)
                                                          else [stmt])]
        write = ast.FunctionDef(
            name="user_out", args=ast.arguments(
                posonlyargs=[], args=[*arguments.args, ast.arg("out")], kwonlyargs=[],
                kw_defaults=[], defaults=[]), body=written, decorator_list=[], returns=None,
            type_params=[])
        user += "\n\n\n" + ast.unparse(ast.fix_missing_locations(ast.Module([write], [])))
        call = f"    return user_out(t, x, u, {None!r}, out)"
    aliases = {k: alias for k, (alias, _) in rewrite.used.items()}
    return user, call, aliases, free


def load_kernel(source: str, folder: Path):
    """Write ``source`` as an importable module in ``folder``; its ``kernel``, compiled.

    Returns ``(kernel, module_name)``.

    Examples
    --------
    >>> import tempfile
    >>> src = kernel_source(lambda t, x, u, params: 3.0 * u, {})
    >>> kernel, name = load_kernel(src, Path(tempfile.mkdtemp()))
    >>> kernel(0.0, np.zeros(0), np.ones(1), np.zeros(0), np.empty(1)).tolist()
    [3.0]
    """
    key = hashlib.sha256((source + str(_jit.HAVE_NUMBA) + str(_jit.CACHE_FORMAT)).encode()
                         ).hexdigest()[:20]
    name = f"controlkit_user_{key}"
    if name in pysys.modules:
        return pysys.modules[name].kernel, name
    path = folder / f"{name}.py"
    if not path.exists():
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    if str(folder) not in pysys.path:
        pysys.path.append(str(folder))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    pysys.modules[name] = module
    spec.loader.exec_module(module)
    if _jit.HAVE_NUMBA:
        module.user = _jit.numba.njit(cache=True)(module.user)
        if hasattr(module, "user_out"):
            module.user_out = _jit.numba.njit(cache=True)(module.user_out)
        module.kernel = _jit.numba.njit(cache=True)(module.kernel)
    return module.kernel, name


def compiled_kernel(fn, values: dict, folder: Path, n_out: int, n_x: int, n_u: int):
    """``(kernel, module_name)`` of ``fn``, checked against ``fn`` itself at a trial point.

    Raises :class:`NotCompilable` with the reason when it cannot be compiled.

    Examples
    --------
    >>> import tempfile
    >>> f = lambda t, x, u, params: [x[0] + params.get("k", 2.0) * u[0]]
    >>> kernel, _ = compiled_kernel(f, {}, Path(tempfile.mkdtemp()), 1, 1, 1)
    >>> kernel(0.0, np.ones(1), np.ones(1), np.zeros(0), np.empty(1)).tolist()
    [3.0]
    """
    rng = np.random.default_rng(0)
    x, u = rng.uniform(0.1, 0.9, n_x), rng.uniform(0.1, 0.9, n_u)
    for direct in (True, False):  # writing a literal result into out, else copying it
        source = kernel_source(fn, values, direct)
        kernel, name = load_kernel(source, folder)
        try:
            ours = kernel(0.0, x, u, np.zeros(0), np.full(n_out, np.nan))
            break
        except Exception as error:  # numba's typing errors: the first line says what failed
            message = str(error).strip().splitlines()
            first = next((m for m in message if m.strip() and "TypingError" not in m), "")
            if not direct or "user_out" not in source:
                raise NotCompilable(f"numba cannot compile it: {first.strip()[:200]}") from None
    try:
        ref = np.asarray(fn(0.0, x.copy(), u.copy(), dict(values)), dtype=float).reshape(-1)
    except Exception:  # undefined at the trial point: trust the compiled code
        return kernel, name
    if ref.shape != (n_out,):
        raise NotCompilable(f"it returns {ref.size} values, the block declares {n_out}")
    if not np.allclose(ours, ref, rtol=1e-12, atol=1e-12, equal_nan=True):
        raise NotCompilable("its compiled version differs from it at a trial point")
    return kernel, name


def python_kernel(fn, values: dict):
    """A kernel ``(t, x, u, p, out)`` calling the user's ``fn`` from Python.

    Examples
    --------
    >>> k = python_kernel(lambda t, x, u, params: params["a"] * x, {"a": 2.0})
    >>> k(0.0, np.ones(1), np.zeros(0), None, np.empty(1)).tolist()
    [2.0]
    """
    params = dict(values)

    def kernel(t, x, u, p, out):
        out[:] = np.asarray(fn(t, x, u, params), dtype=float).reshape(-1)
        return out

    return kernel

