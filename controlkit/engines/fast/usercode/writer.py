"""Writing the module of a user function's kernel: every ``params`` read becomes a read
of ``p`` (:class:`~.layout.ParamLayout`), the values read from outside become
module-level constants, and ``kernel(t, x, u, p, out)`` calls the user's function.
"""

from __future__ import annotations

import ast
import sys as pysys
import types as pytypes

import numpy as np

from .... import _jit
from ...source import PARAM_READ, NotCompilable, Plan, as_written, copy_tree, function_def, walk
from ...source.runs import runs
from ...source.values import (
    _dotted,
    _import_name,
    imported,
    name_text,
    narrow,
    parts_from_c_library,
    plain_values,
    sequence_loses,
)
from ..codegen import CODING, numbers, quoted
from .calls import Calls
from .layout import ParamLayout


class _Reads(ast.NodeTransformer):
    """``__controlkit_param__(params, key, how, default)`` -> the read of ``p``."""

    def __init__(self, layout):
        self.layout = layout

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
        if e.kind == "float":
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
        elif e.kind == "array-i":
            text = f"{text}.astype(_np_.int64)"
        return text if len(e.shape) == 1 else f"{text}.reshape({e.shape!r})"


# --- the generated module -----------------------------------------------------------------

def _literal(name, value, lines, imports):
    """A module-level line freezing ``value`` as ``name`` (or NotCompilable)."""
    if isinstance(value, pytypes.ModuleType):
        module = name_text(value.__name__)
        if not (_dotted(module) and imported(module)) or pysys.modules.get(module) is not value:
            raise NotCompilable(f"it reads a module named {module!r}")
        imports.append(f"import {module} as {name}")
    elif isinstance(value, str | int | float | complex | np.generic | np.ndarray | list | tuple) \
            and not plain_values(value):  # (numbers, or text, with operators of their own)
        raise NotCompilable(f"it reads {as_written(name)!r}, of a {type(value).__name__} whose "
                            f"own operators compiled code would not call")
    elif value is None or isinstance(value, bool):
        lines.append(f"{name} = {value!r}")
    elif isinstance(value, str):  # (a str enumeration's member: its text)
        lines.append(f"{name} = {str.__str__(value)!r}")
    elif isinstance(value, np.bool_):
        lines.append(f"{name} = _np_.bool_({bool(value)!r})")
    elif isinstance(value, int):  # (an int enumeration's member: its number)
        lines.append(f"{name} = {int.__int__(value)!r}")
    elif type(value) is float:  # (a numpy float keeps its type)
        lines.append(f"{name} = {numbers(value, '_np_')}")
    elif isinstance(value, complex):  # (its own two floats, whatever its class says)
        lines.append(f"{name} = complex({numbers(complex.real.__get__(value), '_np_')}, "
                     f"{numbers(complex.imag.__get__(value), '_np_')})")
    elif isinstance(value, np.ndarray | np.generic | list | tuple):
        if why := sequence_loses(value):
            raise NotCompilable(f"it reads {as_written(name)!r}, which {why}")
        array = np.asarray(value)
        if array.dtype.kind not in "biufc":
            raise NotCompilable(f"it reads {as_written(name)!r}, which is not numeric")
        if array.dtype.kind != "b" and narrow(array.dtype):
            raise NotCompilable(f"it reads {as_written(name)!r}, of type "
                                f"{array.dtype.name}: numpy computes in it, compiled code in "
                                f"64 bits")
        if array.dtype.kind == "c":  # its floats in pairs, viewed as complex (inf, nan too)
            pairs = numbers(np.stack([array.real, array.imag], axis=-1).tolist(), "_np_")
            lines.append(f"{name} = _np_.array({pairs}).view(_np_.complex128)[..., 0].copy()")
            return
        text = numbers(array.tolist(), "_np_")
        if isinstance(value, np.ndarray | list | tuple):
            lines.append(f"{name} = _np_.array({text}, dtype=_np_.{array.dtype.name})")
        else:  # a numpy scalar keeps its type
            lines.append(f"{name} = _np_.{array.dtype.name}({text})")
    elif callable(value) and getattr(value, "__module__", None) and getattr(
            value, "__name__", None):
        found = _import_name(value)
        if found is None:
            attr = getattr(_jit.python_function(value), "__name__", "")
            raise NotCompilable(f"it calls {attr!r}, which cannot be imported by name")
        module, attr = found
        # what it runs, in the text: numba's cache knows the kernel by its own file only,
        # and would hand back code compiled with an older version of the imported function
        imports.append(f"from {module} import {attr} as {name}  # {runs(value)}")
    else:  # (named as the value names itself: scipy.special.erf, not its frozen name)
        shown = getattr(value, "__name__", None) or as_written(name)
        raise NotCompilable(f"it reads {shown!r}, a {type(value).__name__}, which numba "
                            f"cannot compile")



def kernel_source(plan: Plan, layout: ParamLayout) -> str:
    """The module source of the kernel compiled from ``plan`` for the parameter ``layout``.

    Raises
    ------
    NotCompilable
        Saying why the plan's function cannot be turned into a kernel.

    Examples
    --------
    >>> from controlkit.engines.source import plan_function
    >>> plan = plan_function(lambda t, x, u, params: params["k"] * x)
    >>> src = kernel_source(plan, ParamLayout(["k"], {"k": 2.0}))
    >>> "return params[0] * x" in src, "2.0" in src
    (True, False)
    """
    why = plan.why_not()
    if why is not None:
        raise NotCompilable(why)
    written = plan.written  # the functions' text, per layout
    if layout.entries not in written:
        text = _functions(plan, layout)
        try:  # (Python 3.11 writes some strings inside an f-string as text it cannot read)
            ast.parse(text)
        except SyntaxError:
            raise NotCompilable("its text, written out, is not Python it can read (a "
                                "string inside an f-string)") from None
        written[layout.entries] = text
    imports = ["import numpy as _np_",
               *(f"from controlkit.kernels.numpy_calls import numpy_{name} as _ck_{name}"
                 for name in Calls.NUMPY_CALLS),
               *(f"from controlkit.kernels.user_calls import {function} as {name}"
                 for name, function in Calls.USER_CALLS.items()),
               # where numpy raises arrays to powers with its own code, compiled code
               # cannot give its numbers: a float array's power is then Python's to run
               "from controlkit.kernels.user_calls import "
               f"{'power_of_numbers' if parts_from_c_library('power') else 'power'} "
               "as _ck_power"]
    lines = []
    for each in plan.tree():  # read now: an array may have been changed in place
        for name, value in each.frozen.items():
            _literal(name, value, lines, imports)
    text = "\n".join([
        CODING,
        # (not its file: a notebook's cell is a file named by its kernel's process, and a
        # name that changes would compile the same code again in every session)
        f"# generated by controlkit from {quoted(plan.function.__qualname__)}: do not edit",
        *dict.fromkeys(imports), *lines, "", "", written[layout.entries], "", "",
        "def kernel(t, x, u, p, out):",
        "    return store(user(t, x, u, p), out)",
        "",
    ])
    return text


def _names(tree):
    """``(stores, uses, parents)`` of ``tree``: how often each name is bound, the nodes
    that read each name, and each node's parent."""
    stores, uses = {}, {}
    for node in walk(tree):
        if isinstance(node, ast.Name):
            if isinstance(node.ctx, ast.Store):
                stores[node.id] = stores.get(node.id, 0) + 1
            else:
                uses.setdefault(node.id, []).append(node)
    parents = {child: parent for parent in walk(tree) for child in ast.iter_child_nodes(parent)}
    return stores, uses, parents


def _read_only_lists(body):
    """``name = [1, 2, 3]`` -> ``name = (1, 2, 3)`` where ``name`` is only ever indexed.

    Compiled, a list literal is a new list at every call (python-control's cruise-control
    example reads its gear ratios so: ``alpha = params.get("alpha", [40, 25, 16, 12,
    10])``, which cost the vehicle's kernel three quarters of its time); a tuple of numbers
    is a constant. Only a name assigned once, from numbers, and read only as ``name[i]``
    or ``len(name)`` is changed: Python reads the two alike.
    """
    tree = ast.Module(body, [])
    stores, uses, parents = _names(tree)

    def read_only(name):
        for node in uses.get(name, []):
            parent = parents.get(node)
            indexed = (isinstance(parent, ast.Subscript) and parent.value is node
                       and isinstance(parent.ctx, ast.Load))
            measured = (isinstance(parent, ast.Call) and isinstance(parent.func, ast.Name)
                        and parent.func.id == "len" and parent.args == [node])
            if not (indexed or measured):
                return False
        return True

    for node in walk(tree):
        if (isinstance(node, ast.Assign) and len(node.targets) == 1
                and isinstance(node.targets[0], ast.Name) and isinstance(node.value, ast.List)
                and node.value.elts and all(isinstance(e, ast.Constant) and isinstance(
                    e.value, int | float) and not isinstance(e.value, bool)
                    for e in node.value.elts)
                and stores.get(node.targets[0].id) == 1 and read_only(node.targets[0].id)):
            node.value = ast.copy_location(ast.Tuple(node.value.elts, ast.Load()), node.value)
    return body


def _appended_lists(body):
    """``name = []`` then ``name.append(a)``, ``name.append(b)`` -> ``name = (a, b)``
    where ``name`` is bound there only and otherwise only unpacked whole, indexed by a
    constant or measured by ``len``.

    Compiled, a list is built at every call (a new list, grown as it is appended to):
    what a loop over literal ``params`` keys, written out one copy per key
    (:mod:`...source.rewrites`), leaves of ``values = []; for key in (..): values.append(
    params[key])``. A tuple holds the same values, each of its own type as in Python.
    """
    tree = ast.Module(body, [])
    stores, uses, parents = _names(tree)

    def appended(stmt, name):
        call = stmt.value if isinstance(stmt, ast.Expr) else None
        return (isinstance(call, ast.Call) and isinstance(call.func, ast.Attribute)
                and call.func.attr == "append" and isinstance(call.func.value, ast.Name)
                and call.func.value.id == name and len(call.args) == 1
                and not call.keywords and not isinstance(call.args[0], ast.Starred)
                and not any(isinstance(n, ast.Name) and n.id == name
                            for n in walk(call.args[0])))

    def read_whole(node, count, receivers):
        parent = parents.get(node)
        if node in receivers:
            return True
        if isinstance(parent, ast.Assign) and parent.value is node:
            return all(isinstance(t, ast.Tuple | ast.List) and len(t.elts) == count
                       and not any(isinstance(e, ast.Starred) for e in t.elts)
                       for t in parent.targets)
        if isinstance(parent, ast.Subscript) and parent.value is node:
            index = parent.slice  # (read: a tuple's items cannot be set)
            return (isinstance(parent.ctx, ast.Load) and isinstance(index, ast.Constant)
                    and type(index.value) is int and -count <= index.value < count)
        return (isinstance(parent, ast.Call) and isinstance(parent.func, ast.Name)
                and parent.func.id == "len" and parent.args == [node])

    for block in [body] + [getattr(n, f) for n in walk(tree)
                           for f in ("body", "orelse", "finalbody")
                           if n is not tree and isinstance(getattr(n, f, None), list)]:
        i = 0
        while i < len(block):
            stmt = block[i]
            name = (stmt.targets[0].id if isinstance(stmt, ast.Assign)
                    and len(stmt.targets) == 1 and isinstance(stmt.targets[0], ast.Name)
                    and isinstance(stmt.value, ast.List) and not stmt.value.elts else None)
            j = i + 1
            while name is not None and j < len(block) and appended(block[j], name):
                j += 1
            if name is None or j == i + 1 or stores.get(name) != 1:
                i += 1
                continue
            receivers = {block[k].value.func.value for k in range(i + 1, j)}
            if all(read_whole(n, j - i - 1, receivers) for n in uses.get(name, [])):
                items = [block[k].value.args[0] for k in range(i + 1, j)]
                stmt.value = ast.copy_location(ast.Tuple(items, ast.Load()), stmt.value)
                del block[i + 1:j]
            i += 1
    return body


def _stored_returns(body, frozen, name):
    """``return np.array([a, b])`` or ``return [a, b]`` -> ``return (a, b)`` in the
    function ``name`` whose result ``kernel`` stores, when every return of it is written
    so.

    Compiled, the array (or list) is a new one at every call, only to be copied into
    ``out``; the tuple is stored element by element (:func:`..user_calls.store`), each
    number converted to a float as ``np.array`` converts it and storing it does (an
    element that is an array is refused by both). Only a flat display (no nested list,
    no ``*``) of a call without other arguments is changed.
    """
    returns, nested = [], False
    todo = list(body)
    while todo:
        node = todo.pop()
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda | ast.ClassDef):
            continue  # (a return in there is another function's)
        if isinstance(node, ast.Return):
            returns.append(node)
        if isinstance(node, ast.Name) and node.id == name:
            nested = True  # it calls itself: its result is used as a value
        todo.extend(ast.iter_child_nodes(node))

    def display(value):
        if (isinstance(value, ast.Call) and len(value.args) == 1 and not value.keywords
                and _numpy_array(value.func, frozen)):
            value = value.args[0]
        if isinstance(value, ast.List) and value.elts and not any(
                isinstance(e, ast.List | ast.Tuple | ast.Set | ast.Starred
                           | ast.ListComp | ast.GeneratorExp) for e in value.elts):
            return value.elts
        return None

    elements = [display(node.value) for node in returns]
    if nested or not returns or any(e is None for e in elements):
        return body
    for node, elts in zip(returns, elements, strict=True):
        node.value = ast.copy_location(ast.Tuple(elts, ast.Load()), node.value)
    return body


def _numpy_array(func, frozen) -> bool:
    """Whether ``func`` names ``numpy.array`` (or ``asarray``) in the kernel's module."""
    if isinstance(func, ast.Attribute) and func.attr in ("array", "asarray") \
            and isinstance(func.value, ast.Name):
        module = np if func.value.id == "_np_" else frozen.get(func.value.id)
        return module is np
    if isinstance(func, ast.Name):
        return frozen.get(func.id) in (np.array, np.asarray)
    return False


def _functions(plan, layout):
    """The text of the plan's functions, params read from ``p``."""
    reads = _Reads(layout)
    texts = []
    for each in plan.tree():
        body = _appended_lists(_read_only_lists(
            [Calls(each.frozen).visit(reads.visit(stmt)) for stmt in copy_tree(each.body)]))
        if each is plan:
            body = _stored_returns(body, each.frozen, each.name)
        try:
            texts.append(ast.unparse(_plain(function_def(each.name, each.arguments, body))))
        except ValueError as why:  # ("Unable to avoid backslash in f-string expression")
            raise NotCompilable(f"its text cannot be written out ({why})") from None
    return "\n\n\n".join(texts)


#: The constants a kernel's text may hold: their ``repr`` is Python's own literal.
PLAIN = (str, int, float, complex, bool, bytes, type(None), type(Ellipsis))


def _plain(tree):
    """``tree``, whose constants (values read from outside, frozen in) are all of the
    :data:`PLAIN` types themselves, and whose names are identifiers: the text writes them
    as they are, which another class, or a name read from a code object, may make any code
    (NotCompilable: the function runs as Python)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and type(node.value) not in PLAIN:
            raise NotCompilable(f"it reads a value of type {type(node.value).__name__!r} "
                                "(a subclass of a number or a string), which compiled code "
                                "would write as its class's repr")
        for name in (getattr(node, field, "") for field in ("id", "arg", "attr", "name")):
            if name and not (type(name) is str and _dotted(name)
                             and ("." not in name or isinstance(node, ast.alias))):
                raise NotCompilable("it has a name that is not an identifier")
    return tree
