"""Turning a user's ``(t, x, u, params)`` function into a kernel the fast engine can call.

python-control documents update and output functions as ``f(t, x, u, params)``
with ``params`` a dict. numba cannot compile a dict of mixed values, so the
function is compiled once for the *types and shapes* of its parameters, never
their values: :mod:`..source` plans the function (every read of ``params``, the
helpers it calls, the values it reads from outside), each read becomes a read of
the block contract's packed vector ``p`` (:class:`ParamLayout`: a float at one
index, an int or bool cast back where the code needs one, an array as a slice
reshaped, a complex as two floats), and :meth:`ParamLayout.pack` builds ``p`` from
the values in force for each run. The functions' globals and closure variables
(numbers, arrays, modules, compiled functions, attributes of objects) are frozen
as module-level constants, and the result is written as a small module in the
cache folder (:func:`.loader.cache_folder`), where numba compiles and caches it.
A new parameter value is a new ``p``: nothing is written or compiled again.

The user's functions and helpers are inlined into the kernel, and compiled with
numba's numpy error model: a division by zero gives ``inf`` or ``nan``, as it does in
Python for the numpy numbers that ``x`` and ``u`` hold, instead of a check per division
that made a kernel three times slower. (Python raises ``ZeroDivisionError`` when both
numbers are Python floats, such as two parameters; then the Python function raises at
every trial point below and the block runs as Python.)

Before a compiled function is trusted it is compared with the Python function at
several trial points (the run's initial state and inputs among them). A function
that cannot be planned, compiled or matched gets the reason instead; the engine
then calls it from Python inside its own loop.
"""

from __future__ import annotations

import ast
import copy
import hashlib
import importlib
import importlib.util
import os
import sys as pysys
import types as pytypes
from pathlib import Path
from typing import NamedTuple

import numpy as np

from ... import _jit
from ..source import PARAM_READ, NotCompilable, Plan, plan_function


def store(r, out):
    """Copy a user function's result (number, sequence or array) into ``out``.

    Examples
    --------
    >>> store([1.0, 2.0], np.empty(2)).tolist()
    [1.0, 2.0]
    """
    out[:] = np.asarray(r, dtype=float).reshape(-1)
    return out


def clip(a, a_min, a_max):
    """:func:`numpy.clip`, which compiled user functions call instead (numba's takes arrays
    only; python-control's examples clip numbers: ``np.clip(u[0], -umax, umax)``).

    Examples
    --------
    >>> clip(2.5, 0.0, 1.0), clip(-1.0, 0, None)
    (np.float64(1.0), np.float64(0.0))
    """
    return np.clip(a, a_min, a_max)


if _jit.HAVE_NUMBA:
    from numba import types as _nbtypes
    from numba.extending import overload

    @overload(store)
    def _store_overload(r, out):
        if isinstance(r, _nbtypes.Number | _nbtypes.Boolean):
            def impl(r, out):
                out[0] = r
                return out
        elif isinstance(r, _nbtypes.Array):
            def impl(r, out):
                flat = r.ravel()
                for i in range(out.size):
                    out[i] = flat[i]
                return out
        elif isinstance(r, _nbtypes.UniTuple | _nbtypes.List | _nbtypes.Tuple):
            def impl(r, out):
                for i in range(len(r)):
                    out[i] = r[i]
                return out
        else:
            return None
        return impl

    def _none(bound):
        return bound is None or isinstance(bound, _nbtypes.NoneType | _nbtypes.Omitted)

    @overload(clip)
    def _clip_overload(a, a_min, a_max):
        if isinstance(a, _nbtypes.Array):
            def impl(a, a_min, a_max):
                return np.clip(a, a_min, a_max)
            return impl
        if not isinstance(a, _nbtypes.Number):
            return None
        # numpy's order: maximum with a_min, then minimum with a_max; NaN anywhere wins
        if _none(a_min) and _none(a_max):
            return None
        if _none(a_min):
            def impl(a, a_min, a_max):
                return a if a <= a_max or a != a else a_max
        elif _none(a_max):
            def impl(a, a_min, a_max):
                return a if a >= a_min or a != a else a_min
        else:
            def impl(a, a_min, a_max):
                low = a if a >= a_min or a != a else a_min
                return low if low <= a_max or low != low else a_max
        return impl


@_jit.jit
def missing_parameter(key):
    """What a compiled ``params[key]`` becomes when ``params`` has no ``key``: Python's
    ``KeyError`` if it runs (numba refuses to compile it unless it is in a branch that
    can never run, such as one under ``if key in params:``).

    Examples
    --------
    >>> missing_parameter("kp")
    Traceback (most recent call last):
    ...
    KeyError: 'kp'
    """
    raise KeyError(key)


# --- the packed parameter vector ----------------------------------------------------------

#: Integers up to this size are exact in a float64 (larger ones run as Python).
_EXACT_INT = 2 ** 53


class ParamEntry(NamedTuple):
    """Where one parameter sits in ``p``: ``kind`` is ``float``, ``int``, ``bool``,
    ``complex``, ``none``, ``absent`` or ``array-f``/``array-i``/``array-b``.

    Examples
    --------
    >>> ParamLayout(["pole"], {"pole": -0.5 + 1j}).entries[0]
    ParamEntry(key='pole', kind='complex', shape=(), offset=0, size=2)
    """

    key: object
    kind: str
    shape: tuple
    offset: int
    size: int


def _kind(key, value):
    """``(kind, shape)`` of a parameter value, or NotCompilable naming the parameter."""
    if value is None:
        return "none", ()
    if isinstance(value, bool | np.bool_):
        return "bool", ()
    if isinstance(value, int | np.integer):
        return "int", ()
    if isinstance(value, float | np.float64):
        return "float", ()
    if isinstance(value, complex | np.complex128):
        return "complex", ()
    if isinstance(value, np.ndarray | list | tuple):
        try:
            array = np.asarray(value)
        except (ValueError, TypeError):
            array = None
        if array is not None and (array.dtype.kind in "iub" or array.dtype == np.float64):
            if array.ndim == 0:
                return _kind(key, array.item())
            return "array-" + {"b": "b", "i": "i", "u": "i", "f": "f"}[array.dtype.kind], \
                array.shape
        described = f"an array of {array.dtype}" if array is not None else "a ragged sequence"
        raise NotCompilable(f"parameter {key!r} is {described}, which compiled code cannot "
                            f"take (numbers, and arrays of float64, int or bool, can)")
    raise NotCompilable(f"parameter {key!r} is a {type(value).__name__} ({value!r:.40}), "
                        f"which compiled code cannot take")


class ParamLayout:
    """The packed parameter vector ``p`` of a block's user functions.

    One entry per ``params`` key the functions read, sorted by key: its kind and
    shape (from the values in force), offset and size in ``p``. The compiled code
    depends on the entries, never on the values; :meth:`pack` builds ``p``.

    Examples
    --------
    >>> layout = ParamLayout(["K", "kp", "umax"], {"K": [[1.0, 2.0]], "kp": 2})
    >>> [(e.key, e.kind, e.shape, e.offset) for e in layout.entries]
    [('K', 'array-f', (1, 2), 0), ('kp', 'int', (), 2), ('umax', 'absent', (), 3)]
    >>> layout.pack({"K": [[1.0, 2.0]], "kp": 3}).tolist()
    [1.0, 2.0, 3.0]
    """

    def __init__(self, keys, values):
        entries, offset = [], 0
        for key in sorted(keys, key=repr):
            if key in values:
                kind, shape = _kind(key, values[key])
            else:
                kind, shape = "absent", ()
            size = (2 if kind == "complex" else 1 if kind in ("float", "int", "bool")
                    else int(np.prod(shape, dtype=int)) if kind.startswith("array") else 0)
            entries.append(ParamEntry(key, kind, shape, offset, size))
            offset += size
        self.entries = tuple(entries)
        self.size = offset
        self.by_key = {e.key: e for e in entries}

    @classmethod
    def of(cls, plans, values):
        """The layout of the keys read by ``plans`` (NotCompilable if they are unknown)."""
        keys = set()
        for plan in plans:
            read = plan.params_read()
            if read is None:
                raise NotCompilable(plan.why_not() or "the params it reads are not known")
            keys |= read
        return cls(keys, values)

    @property
    def has_ints(self) -> bool:
        """Whether an entry is an integer (read as a float first, cast back if needed)."""
        return any(e.kind in ("int", "array-i") for e in self.entries)

    def pack(self, values) -> np.ndarray:
        """``p`` for the parameter ``values`` in force (same kinds and shapes as the layout).

        Raises
        ------
        NotCompilable
            When a value does not fit (another type or shape, an integer beyond 2**53).
        """
        p = np.empty(self.size)
        for e in self.entries:
            if e.kind == "absent":
                if e.key in values:
                    raise NotCompilable(f"parameter {e.key!r} was not given when compiled")
                continue
            value = values[e.key]
            kind, shape = _kind(e.key, value)
            if (kind, shape) != (e.kind, e.shape):
                raise NotCompilable(f"parameter {e.key!r} is now a {kind} {shape}, compiled "
                                    f"for a {e.kind} {e.shape}")
            if kind == "complex":
                p[e.offset:e.offset + 2] = value.real, value.imag
            elif kind.startswith("array"):
                array = np.asarray(value)
                if kind == "array-i" and array.size and np.abs(array).max() > _EXACT_INT:
                    raise NotCompilable(f"parameter {e.key!r} holds integers beyond 2**53")
                p[e.offset:e.offset + e.size] = array.reshape(-1)
            elif kind != "none":
                if kind == "int" and abs(int(value)) > _EXACT_INT:
                    raise NotCompilable(f"parameter {e.key!r} = {value} is an integer beyond "
                                        f"2**53, which a float64 does not hold exactly")
                p[e.offset] = value
        return p


class _Reads(ast.NodeTransformer):
    """``__controlkit_param__(params, key, how, default)`` -> the read of ``p``."""

    def __init__(self, layout, exact):
        self.layout, self.exact = layout, exact

    def visit_Call(self, node):
        node = self.generic_visit(node)
        if not (isinstance(node.func, ast.Name) and node.func.id == PARAM_READ):
            return node
        vector, key, how, default = node.args
        e = self.layout.by_key[key.value]
        if e.kind == "absent":
            if how.value == "in":
                return ast.copy_location(ast.Constant(False), node)
            if how.value == "item":  # KeyError if run, as in Python (``if "k" in params:``
                # around it compiles to ``if False:``, which numba drops)
                return ast.copy_location(ast.Call(ast.Name("_ck_missing", ast.Load()),
                                                  [ast.Constant(key.value)], []), node)
            return default
        if how.value == "in":
            return ast.copy_location(ast.Constant(True), node)
        return ast.copy_location(ast.parse(self._read(vector.id, e), mode="eval").body, node)

    def _read(self, p, e):
        i = e.offset
        if e.kind == "none":
            return "None"
        if e.kind == "float" or e.kind == "int" and not self.exact:
            return f"{p}[{i}]"
        if e.kind == "int":
            return f"int({p}[{i}])"
        if e.kind == "bool":
            return f"({p}[{i}] != 0.0)"
        if e.kind == "complex":
            return f"complex({p}[{i}], {p}[{i + 1}])"
        text = f"{p}[{i}:{i + e.size}]"
        if e.kind == "array-b":
            text = f"({text} != 0.0)"
        elif e.kind == "array-i" and self.exact:
            text = f"{text}.astype(_np_.int64)"
        return text if len(e.shape) == 1 else f"{text}.reshape({e.shape!r})"


# --- the generated module -----------------------------------------------------------------

def _number(value) -> str:
    value = float(value)
    if value != value:
        return "_np_.nan"
    if value in (np.inf, -np.inf):
        return "_np_.inf" if value > 0 else "-_np_.inf"
    return repr(value)


def _literal(name, value, lines, imports):
    """A module-level line freezing ``value`` as ``name`` (or NotCompilable)."""
    if isinstance(value, pytypes.ModuleType):
        imports.append(f"import {value.__name__} as {name}")
    elif value is None or isinstance(value, bool | str):
        lines.append(f"{name} = {value!r}")
    elif isinstance(value, np.bool_):
        lines.append(f"{name} = _np_.bool_({bool(value)!r})")
    elif isinstance(value, int) or isinstance(value, float) and type(value) is float:
        lines.append(f"{name} = {_number(value) if isinstance(value, float) else repr(value)}")
    elif isinstance(value, complex):
        lines.append(f"{name} = complex({_number(value.real)}, {_number(value.imag)})")
    elif isinstance(value, np.ndarray | np.generic | list | tuple):
        array = np.asarray(value)
        if array.dtype.kind not in "biufc":
            raise NotCompilable(f"it reads {name.split('_', 2)[-1]!r}, which is not numeric")
        if array.dtype.kind == "c":
            text = repr(array.tolist())
        else:
            text = repr(array.tolist()).replace("inf", "_np_.inf").replace("nan", "_np_.nan")
        if isinstance(value, np.ndarray | list | tuple):
            lines.append(f"{name} = _np_.array({text}, dtype=_np_.{array.dtype.name})")
        else:  # a numpy scalar keeps its type
            lines.append(f"{name} = _np_.{array.dtype.name}({text})")
    elif callable(value) and getattr(value, "__module__", None) and getattr(
            value, "__name__", None):
        fn = _jit.python_function(value)
        module, attr = getattr(fn, "__module__", None), getattr(fn, "__name__", "")
        try:
            ok = module is not None and getattr(importlib.import_module(module), attr,
                                                None) is value
        except ImportError:
            ok = False
        if not ok:
            raise NotCompilable(f"it calls {attr!r}, which cannot be imported by name")
        imports.append(f"from {module} import {attr} as {name}")
    else:
        raise NotCompilable(f"it reads {name.split('_', 2)[-1]!r}, a {type(value).__name__}, "
                            f"which numba cannot compile")


def _literal_items(value):
    """The elements of ``[a, b]``, ``(a, b)`` or ``np.array([a, b])``, else None."""
    if isinstance(value, ast.Call) and isinstance(value.func, ast.Attribute) \
            and value.func.attr in ("array", "asarray") and len(value.args) == 1 \
            and not value.keywords:
        value = value.args[0]
    if isinstance(value, ast.List | ast.Tuple) and not any(
            isinstance(e, ast.Starred) for e in value.elts):
        return value.elts
    return None


#: The name of the output buffer in a function that writes its result into it.
_OUT = "_ck_out"


class _WriteOut(ast.NodeTransformer):
    """``return [a, b]`` -> ``out[0] = a; out[1] = b; return out``: no array per call."""

    def visit_Return(self, node):
        items = _literal_items(node.value)
        lines = [ast.Assign([ast.Subscript(ast.Name(_OUT, ast.Load()), ast.Constant(i),
                                           ast.Store())], item, lineno=0)
                 for i, item in enumerate(items)]
        return [*lines, ast.Return(ast.Name(_OUT, ast.Load()))]

    def visit_FunctionDef(self, node):
        return node

    def visit_Lambda(self, node):
        return node


def _returns(body):
    """The return statements of ``body`` itself (not of functions defined in it)."""
    found, stack = [], list(body)
    while stack:
        node = stack.pop()
        if isinstance(node, ast.Return):
            found.append(node)
        elif not isinstance(node, ast.FunctionDef | ast.Lambda | ast.ClassDef):
            stack.extend(ast.iter_child_nodes(node))
    return found


def _function(name, arguments, body):
    args = ast.arguments(posonlyargs=[], args=[ast.arg(a) for a in arguments], vararg=None,
                         kwonlyargs=[], kw_defaults=[], kwarg=None, defaults=[])
    node = ast.FunctionDef(name=name, args=args, body=body, decorator_list=[], returns=None,
                           type_params=[])
    return ast.unparse(ast.fix_missing_locations(ast.Module([node], [])))


def kernel_source(fn, values: dict, direct: bool = False, *, layout=None, exact=False,
                  plan: Plan | None = None) -> str:
    """The module source of the kernel compiled from ``fn`` for the types of ``values``.

    ``direct`` writes a literal result straight into ``out`` (NotCompilable when a return
    is not a literal list); ``exact`` casts integer
    parameters back to integers (else they are read as floats, so that ``kp=1`` and
    ``kp=1.5`` share one compiled kernel).

    Raises
    ------
    NotCompilable
        Saying why ``fn`` cannot be turned into a kernel.

    Examples
    --------
    >>> src = kernel_source(lambda t, x, u, params: params["k"] * x, {"k": 2.0})
    >>> "return params[0] * x" in src, "2.0" in src
    (True, False)
    """
    plan = plan or plan_function(fn)
    why = plan.why_not()
    if why is not None:
        raise NotCompilable(why)
    layout = layout or ParamLayout.of([plan], values)
    written = plan.written  # the functions' text, per layout
    key = (layout.entries, bool(direct), bool(exact))
    if key not in written:
        try:
            written[key] = _functions(plan, layout, direct, exact)
        except NotCompilable as why:
            written[key] = why
    if isinstance(written[key], NotCompilable):
        raise NotCompilable(str(written[key]))
    functions, call = written[key]
    imports = ["import numpy as _np_",
               "from controlkit.engines.fast.usercode import missing_parameter as _ck_missing",
               "from controlkit.engines.fast.usercode import store"]
    lines = []
    for each in plan.tree():  # read now: an array may have been changed in place
        for name, value in each.frozen.items():
            _literal(name, value, lines, imports)
    code = plan.function.__code__
    return "\n".join([
        f"# generated by controlkit from {plan.function.__qualname__} "
        f"({code.co_filename}:{code.co_firstlineno}): do not edit",
        *dict.fromkeys(imports), *lines, "", "", functions, "", "",
        "def kernel(t, x, u, p, out):",
        call,
        "",
    ])


def _functions(plan, layout, direct, exact):
    """The text of the plan's functions, params read from ``p``, and the kernel's call."""
    if direct:
        returns = _returns(plan.body)
        if not returns or _OUT in {n.id for n in ast.walk(ast.Module(plan.body, []))
                                   if isinstance(n, ast.Name)} \
                or any(_literal_items(r.value) is None for r in returns):
            raise NotCompilable("not every return is a literal list")
    functions = []
    for each in plan.tree():
        reads = _Reads(layout, exact)
        body = [reads.visit(stmt) for stmt in copy.deepcopy(each.body)]
        functions.append(_function(each.name, each.arguments, body))
        if each is plan:
            top = body
    call = "    return store(user(t, x, u, p), out)"
    if direct:
        written = [_WriteOut().visit(stmt) for stmt in copy.deepcopy(top)]
        written = [s for stmt in written for s in (stmt if isinstance(stmt, list) else [stmt])]
        functions.append(_function("user_out", [*plan.arguments, _OUT], written))
        call = "    return user_out(t, x, u, p, out)"
    return "\n\n\n".join(functions), call


def load_kernel(source: str, folder: Path):
    """Write ``source`` as an importable module in ``folder``; its ``kernel``, compiled.

    Every function of the module is compiled with numba (cached on disk), the user's
    functions inlined into ``kernel``. Loading is
    all or nothing: a module that fails to load is not left behind in ``sys.modules``.
    Returns ``(kernel, module_name)``.

    Raises
    ------
    NotCompilable
        When the module cannot be loaded.

    Examples
    --------
    >>> import tempfile
    >>> src = kernel_source(lambda t, x, u, params: 3.0 * u, {})
    >>> kernel, name = load_kernel(src, Path(tempfile.mkdtemp()))
    >>> kernel(0.0, np.zeros(0), np.ones(1), np.zeros(0), np.empty(1)).tolist()
    [3.0]
    """
    key = hashlib.sha256((source + str(_jit.HAVE_NUMBA) + str(_jit.CACHE_FORMAT)
                          + _COMPILE_OPTIONS).encode()).hexdigest()[:20]
    name = f"controlkit_user_{key}"
    if name in pysys.modules:
        return pysys.modules[name].kernel, name
    path = folder / f"{name}.py"
    if not path.exists():  # keep an existing file's date: numba's cache keys on it
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    if str(folder) not in pysys.path:
        pysys.path.append(str(folder))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    pysys.modules[name] = module  # numba's disk cache re-imports it by name
    try:
        spec.loader.exec_module(module)
        if _jit.HAVE_NUMBA:
            defined = [n for n, v in vars(module).items()
                       if isinstance(v, pytypes.FunctionType) and v.__module__ == name]
            for n in defined:
                # the user's functions and helpers are inlined into the kernel by numba:
                # called as separate functions, reads of p cost 50 ns a call more
                inline = "never" if n == "kernel" else "always"
                setattr(module, n, _jit.numba.njit(cache=True, inline=inline,
                                                   error_model="numpy")(getattr(module, n)))
        kernel = module.kernel
    except Exception as error:  # the generated module does not load: nothing is kept
        del pysys.modules[name]
        raise NotCompilable(f"its compiled module does not load ({type(error).__name__}: "
                            f"{error})") from None
    return kernel, name


#: How the modules' functions are compiled, part of their names: numba's disk cache would
#: otherwise hand back code compiled with other options from the same source.
_COMPILE_OPTIONS = "inline=always,error_model=numpy"


class CompiledKernel(NamedTuple):
    """A user function compiled: ``kernel(t, x, u, p, out)``, and ``pack(values) -> p``.

    Examples
    --------
    >>> import tempfile
    >>> f = lambda t, x, u, params: [params["k"] * u[0]]
    >>> compiled = compiled_kernel(f, {"k": 2.0}, Path(tempfile.mkdtemp()), 1, 0, 1)
    >>> compiled.pack({"k": 5.0}).tolist(), compiled.layout.size
    ([5.0], 1)
    """

    kernel: object
    pack: object
    module: str
    layout: ParamLayout


def _trial_points(n_x, n_u, trials):
    """The run's own points first, then all zeros, then three random ones."""
    points = [(float(t), np.array(x, dtype=float).reshape(-1), np.array(u, dtype=float)
               .reshape(-1)) for t, x, u in trials or ()]
    points = [(t, x, u) for t, x, u in points if x.size == n_x and u.size == n_u]
    points.append((0.0, np.zeros(n_x), np.zeros(n_u)))
    rng = np.random.default_rng(0)
    for t in (0.0, 0.37, 1.9):
        points.append((t, rng.uniform(0.1, 0.9, n_x), rng.uniform(0.1, 0.9, n_u)))
    return points


def _is_compile_error(error) -> bool:
    if isinstance(error, RecursionError):  # a recursive helper, inlined without end
        return True
    if not _jit.HAVE_NUMBA:
        return False
    from numba.core.errors import NumbaError

    return isinstance(error, NumbaError)


def _first_line(error) -> str:
    message = str(error).strip().splitlines()
    first = next((m for m in message if m.strip() and "TypingError" not in m
                  and "Failed in nopython" not in m), "")
    return first.strip()[:200]


def compiled_kernel(fn, values: dict, folder: Path, n_out: int, n_x: int, n_u: int, *,
                    layout: ParamLayout | None = None, trials=(),
                    plan: Plan | None = None) -> CompiledKernel:
    """``fn`` compiled for the types of ``values``, checked against ``fn`` at trial points.

    The compiled kernel is compared with ``fn`` itself at ``trials`` (``(t, x, u)``
    points, such as the run's initial state and inputs), at zero and at random points;
    it must agree wherever ``fn`` can be evaluated, and ``fn`` must be evaluable at one
    point at least. ``layout`` (the block's, shared by its functions) and ``plan`` (of
    ``fn``) are made here when not given.

    Raises
    ------
    NotCompilable
        With the reason, when it cannot be compiled or does not agree with ``fn``.

    Examples
    --------
    >>> import tempfile
    >>> f = lambda t, x, u, params: [x[0] + params.get("k", 2.0) * u[0]]
    >>> compiled = compiled_kernel(f, {"k": 3.0}, Path(tempfile.mkdtemp()), 1, 1, 1)
    >>> p = compiled.pack({"k": 0.5})
    >>> compiled.kernel(0.0, np.ones(1), np.ones(1), p, np.empty(1)).tolist()
    [1.5]
    """
    plan = plan or plan_function(fn)
    why = plan.why_not()
    if why is not None:
        raise NotCompilable(why)
    layout = layout or ParamLayout.of([plan], values)
    p = layout.pack(values)
    points = _trial_points(n_x, n_u, trials)
    attempts = [(False, True), (False, False)]
    if layout.has_ints:
        attempts += [(True, True), (True, False)]
    failure = None
    for exact, direct in attempts:
        try:
            source = kernel_source(fn, values, direct, layout=layout, exact=exact, plan=plan)
        except NotCompilable as why:
            if direct:
                continue  # not every return is a literal list: copy the result instead
            raise
        kernel, name = load_kernel(source, folder)
        ours = []
        try:
            for t, x, u in points:
                try:
                    ours.append(kernel(t, x.copy(), u.copy(), p, np.full(n_out, np.nan)))
                except Exception as error:  # noqa: BLE001 - compared with Python's below
                    if _is_compile_error(error):
                        raise
                    ours.append(error)
        except Exception as error:  # noqa: BLE001 - numba's typing errors
            failure = failure or error
            continue
        break
    else:
        raise NotCompilable(f"numba cannot compile it: {_first_line(failure)}")
    compared = 0
    for (t, x, u), mine in zip(points, ours, strict=True):
        try:
            ref = np.asarray(fn(t, x.copy(), u.copy(), dict(values)), dtype=float).reshape(-1)
        except Exception:  # noqa: BLE001 - undefined there: not a point to compare at
            continue
        if ref.shape != (n_out,):
            raise NotCompilable(f"it returns {ref.size} values, the block declares {n_out}")
        if isinstance(mine, Exception):
            raise NotCompilable(f"its compiled version raises {type(mine).__name__} at "
                                f"t = {t:g}, where Python's does not")
        if not np.allclose(mine, ref, rtol=1e-12, atol=1e-12, equal_nan=True):
            raise NotCompilable(f"its compiled version differs from it at t = {t:g} "
                                f"(x = {np.round(x, 6).tolist()}, u = {np.round(u, 6).tolist()})")
        compared += 1
    if not compared:
        raise NotCompilable("it raises at every trial point, so its compiled version could "
                            "not be checked against it")
    return CompiledKernel(kernel, layout.pack, name, layout)


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
