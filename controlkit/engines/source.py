"""Reading a user's ``(t, x, u, params)`` function from its source.

What a function reads can only be known from its source: which ``params`` keys
(for the ``params`` check every backend makes), whether it reads ``u`` (its
feedthrough, for the fast engine's evaluation order), and the statements the fast
engine compiles. A lambda is cut from its file by the positions of its code.
"""

from __future__ import annotations

import ast
import inspect
import linecache
import textwrap

from .. import _jit


class NotCompilable(Exception):
    """Why a user function cannot be compiled (the message is shown by ``explain``).

    Examples
    --------
    >>> str(NotCompilable("no source"))
    'no source'
    """


def _lambda_body(fn):
    """The expression of a lambda, cut from its file by the positions of its code."""
    code = fn.__code__
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


def function_node(fn):
    """The body statements of ``fn`` (a def or a lambda) and its argument names.

    Examples
    --------
    >>> names, body = function_node(lambda t, x, u, params: -x)
    >>> names, type(body[0]).__name__
    (['t', 'x', 'u', 'params'], 'Return')
    """
    code = fn.__code__
    names = list(code.co_varnames[:code.co_argcount])
    if code.co_flags & (inspect.CO_VARARGS | inspect.CO_VARKEYWORDS) or code.co_kwonlyargcount \
            or len(names) != 4:
        raise NotCompilable("it does not take exactly (t, x, u, params)")
    if fn.__name__ == "<lambda>":
        return names, [ast.Return(_lambda_body(fn))]
    try:
        lines, _ = inspect.getsourcelines(fn)
    except (OSError, TypeError) as error:
        raise NotCompilable(f"its source is not available ({error})") from None
    try:
        tree = ast.parse(textwrap.dedent("".join(lines)))
    except SyntaxError:
        raise NotCompilable("its source could not be parsed") from None
    defs = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)
            and n.name == fn.__name__]
    if not defs:
        raise NotCompilable("its definition was not found in its source")
    return names, defs[0].body


def used_params(fn):
    """The ``params`` keys a ``(t, x, u, params)`` function reads, or None if unknown.

    Examples
    --------
    >>> sorted(used_params(lambda t, x, u, params: params["k"] * x + params.get("b", 0.0)))
    ['b', 'k']
    """
    fn = _jit.python_function(fn)
    try:
        names, body = function_node(fn)
    except NotCompilable:
        return None
    keys, opaque = set(), False
    for node in ast.walk(ast.Module(body, [])):
        if isinstance(node, ast.Subscript) and isinstance(node.value, ast.Name) \
                and node.value.id == names[3] and isinstance(node.slice, ast.Constant):
            keys.add(node.slice.value)
        elif isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) \
                and node.func.attr == "get" and isinstance(node.func.value, ast.Name) \
                and node.func.value.id == names[3] and node.args \
                and isinstance(node.args[0], ast.Constant):
            keys.add(node.args[0].value)
    for node in ast.walk(ast.Module(body, [])):  # params passed on whole: keys unknown
        if isinstance(node, ast.Call):
            for a in node.args:
                if isinstance(a, ast.Name) and a.id == names[3]:
                    opaque = True
    return None if opaque else keys


def reads_input(fn):
    """Whether a ``(t, x, u, params)`` function reads ``u`` (None when its source is unknown).

    Examples
    --------
    >>> reads_input(lambda t, x, u, params: 2 * x)
    False
    """
    fn = _jit.python_function(fn)
    try:
        names, body = function_node(fn)
    except NotCompilable:
        return None
    return any(isinstance(n, ast.Name) and n.id == names[2]
               for n in ast.walk(ast.Module(body, [])))
