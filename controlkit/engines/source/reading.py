"""Reading a function's own source: the ``def`` or ``lambda`` its code object was compiled
from (never the function a decorator wraps); what calling a callable runs (a partial's
function, a bound method's, an object's ``__call__``); and how a call binds the function's
arguments: to a value known when the plan is made (:class:`Frozen`), to the run-time
``params`` (:data:`PARAMS`) or to a value known only when the function runs
(:data:`RUNTIME`).
"""

from __future__ import annotations

import ast
import functools
import inspect
import linecache
import re
import textwrap
import types
from dataclasses import dataclass

from ... import _jit
from .rewrites import copy_tree, function_def, walk
from .values import _is_numeric_function, _Marker


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


#: Definitions by code object: the def's tree, read once (or the NotCompilable).
_PARSED: dict = {}


def _definition(code, copy=True):
    """``(arguments, body)`` of the def or lambda whose code is ``code``, a fresh tree
    (``copy=False``: the tree kept, for a caller that only reads it).

    The source is found from the code object itself, never through ``__wrapped__``
    (``inspect.getsource`` of a decorated function gives the function it wraps). It is
    read and parsed once per code object, and each plan, which rewrites its tree, is
    handed a copy (:func:`.rewrites.copy_tree`, as fast as parsing the text again).
    """
    hit = _PARSED.get(code)
    if hit is None:
        try:
            hit = _parse_definition(code)
        except NotCompilable as why:
            hit = why
        _PARSED[code] = hit
    if isinstance(hit, NotCompilable):
        raise NotCompilable(str(hit))
    return (copy_tree(hit[0]), copy_tree(hit[1])) if copy else hit


def _parse_definition(code):
    if code.co_name == "<lambda>":
        if code.co_flags & (inspect.CO_VARARGS | inspect.CO_VARKEYWORDS) or code.co_kwonlyargcount:
            raise NotCompilable("it is a lambda taking *args or keyword-only arguments")
        body, names = _lambda_body(code), code.co_varnames[:code.co_argcount]
        if not _runs_this_text(f"_ = (lambda {', '.join(names)}: {ast.unparse(body)})\n",
                               code):  # (its file edited since, or names not its text's)
            raise NotCompilable("its source file was changed after it was imported: the "
                                "text is not the code that runs")
        node = function_def("f", names, [ast.Return(body)])
        return node.args, node.body
    text = "".join(_source_lines(code))
    if text[:1] in (" ", "\t"):  # a nested def: parse it inside a block, not dedented
        text = "if 1:\n" + text
    try:
        tree = ast.parse(text)
    except SyntaxError:
        raise NotCompilable("its source could not be parsed") from None
    for node in walk(tree):
        if isinstance(node, ast.FunctionDef) and node.name == code.co_name:
            if not _runs_this_text(text, code):
                raise NotCompilable("its source file was changed after it was imported: "
                                    "the text is not the code that runs")
            return node.args, node.body
    if any(isinstance(node, ast.AsyncFunctionDef) for node in walk(tree)):
        raise NotCompilable("it is a coroutine")
    raise NotCompilable("its definition was not found in its source")


def _runs_this_text(text, code) -> bool:
    """Whether compiling ``text`` (a def, its decorators first) gives the code ``code``
    runs: a module file edited after its import holds a text that is not what runs.

    The def is compiled inside a function that defines its free variables (as its own
    enclosing function did), and the two codes are compared by their instructions, names
    and constants (nested code too); line numbers do not count.
    """
    body = textwrap.dedent(text[len("if 1:\n"):] if text.startswith("if 1:\n") else text)
    # (without free variables, at a module's level: a def calling itself reads its own
    # name there as a global, where inside a function it would be a free variable)
    outer = body + "\n" if not code.co_freevars else (
        "def __controlkit_outer__():\n"
        + "".join(f"    {name} = None\n" for name in code.co_freevars)
        + textwrap.indent(body, "    ") + "\n")
    try:
        compiled = compile(outer, code.co_filename, "exec", dont_inherit=True)
    except SyntaxError:
        return False
    wanted = _fingerprint(code)
    stack = list(compiled.co_consts)
    while stack:
        item = stack.pop()
        if isinstance(item, types.CodeType):
            if item.co_name == code.co_name and _fingerprint(item) == wanted:
                return True
            stack.extend(item.co_consts)
    return False


def _fingerprint(code):
    """What ``code`` runs, for :func:`_runs_this_text`: its instructions with their names
    and constants, nested code too. What a compile of the same text may choose otherwise
    does not count: the lines a docstring is indented by, a method call made as an
    attribute load and a call (Python 3.13 calls ``np.clip(...)`` so, with a ``PUSH_NULL``,
    where it knows ``np`` is a module imported in the def's own module), and the byte
    offsets of jumps that follow from it."""
    import dis

    steps = []
    for step in dis.get_instructions(code):
        if step.opname == "PUSH_NULL":
            continue
        if step.opcode in dis.hasjrel or step.opcode in dis.hasjabs:
            steps.append(step.opname)
        elif isinstance(step.argval, types.CodeType):
            steps.append(_fingerprint(step.argval))
        elif isinstance(step.argval, str):
            name = "LOAD_ATTR" if step.opname == "LOAD_METHOD" else step.opname
            steps.append((name, re.sub(r"\n[ \t]*", "\n", step.argval)))
        else:
            steps.append((step.opname, repr(step.argval)))
    return tuple(steps), code.co_freevars


def _source_lines(code):
    """The lines of the def whose code is ``code`` (its decorators first), from its file.

    What :func:`inspect.getsourcelines` gives, read straight from :mod:`linecache` (a def's
    ``co_firstlineno`` is its first decorator's or its ``def`` line): ``inspect`` first looks
    the code's module up among all of ``sys.modules``, 70 ms of a first call of the fast
    engine. A file :mod:`linecache` cannot read (a module in a zip) goes through ``inspect``.
    """
    linecache.checkcache(code.co_filename)  # a file edited since: read again, as inspect does
    lines = linecache.getlines(code.co_filename)
    first = code.co_firstlineno
    if 0 < first <= len(lines) and _DEF_LINE.match(lines[first - 1]):
        return inspect.getblock(lines[first - 1:])
    try:
        return inspect.getsourcelines(code)[0]
    except (OSError, TypeError) as error:
        raise NotCompilable(f"its source is not available ({error})") from None


#: A line where a def (or its first decorator) starts, as :func:`inspect.findsource` knows it.
_DEF_LINE = re.compile(r"^(\s*def\s)|(\s*async\s+def\s)|^(\s*@)")


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
    frozen = _frozen_by_numba(fn)
    if frozen:
        raise NotCompilable(
            f"it calls {fn.__name__!r}, a numba function compiled already in this process: "
            f"numba froze then what it reads ({', '.join(frozen)}), whose values now may "
            "differ")
    fn = _jit.python_function(fn)
    if isinstance(fn, types.FunctionType):
        return fn, [], {}
    if isinstance(fn, functools.partial):
        target, bound, keywords = call_target(fn.func)
        return target, bound + list(fn.args), {**keywords, **fn.keywords}
    if isinstance(fn, types.MethodType):
        target, bound, keywords = call_target(fn.__func__)
        return target, bound + [fn.__self__], keywords
    # as Python finds it; an instance that is not callable may still find its metaclass's
    call = inspect.getattr_static(type(fn), "__call__", None) if callable(fn) else None
    if isinstance(call, types.FunctionType):
        return call, [fn], {}
    raise NotCompilable(f"it is a {type(fn).__name__}, not a Python function")


def _frozen_by_numba(fn) -> list[str]:
    """The names a numba function ``fn`` already compiled reads from outside itself (its
    module's values, its closure), which numba froze at that compile
    (:meth:`numba.core.dispatcher.Dispatcher.recompile` says so): its source, compiled
    again, would read them as they are now. Empty for anything else."""
    if not (hasattr(fn, "py_func") and getattr(fn, "signatures", None)):
        return []
    code, module = fn.py_func.__code__, fn.py_func.__globals__
    return [name for name in code.co_names if name in module and not (
        isinstance(module[name], types.ModuleType) or _is_numeric_function(module[name]))
    ] + list(code.co_freevars)


# --- how a call binds the arguments ------------------------------------------------------

#: A function argument given a value at run time (kept in the compiled signature).
RUNTIME = _Marker("runtime")
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


def _called_as_python_control(target, bound, keywords):
    """The bindings of ``target`` called as ``fn(t, x, u, params)`` with the values
    :func:`call_target` found bound, or the reason it cannot be bound."""
    call = [Frozen(v) for v in bound] + [RUNTIME, RUNTIME, RUNTIME, PARAMS]
    return _bind(target, call, {k: Frozen(v) for k, v in keywords.items()})


def _input_name(bindings):
    """The argument that receives ``u`` (the third of t, x, u, params)."""
    runtime = [name for name, b in bindings.items() if b is RUNTIME or b == PARAMS]
    return runtime[2] if len(runtime) == 4 else None


def _bind(fn, positional, keywords):
    """Each argument name of ``fn`` -> its binding, as Python would bind the call, or
    the reason it cannot be bound."""
    try:
        arguments, _ = _definition(fn.__code__, copy=False)
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


# --- what compiled code cannot do as Python -----------------------------------------------

#: Builtins with effects outside the function (what compiled code cannot do as Python).
SIDE_EFFECTS = {"print": "which prints", "open": "which reads or writes files",
                 "input": "which reads the keyboard", "exec": "which runs code",
                 "eval": "which runs code", "breakpoint": "which stops in the debugger"}
#: Methods that change the object they are called on.
MUTATORS = {"append", "extend", "insert", "pop", "remove", "clear", "update", "add",
             "discard", "setdefault", "popitem", "write", "writelines", "sort", "reverse",
             "fill", "put", "resize", "itemset"}


def _outside_effect(call, local, is_module):
    """``(what, why compiled code differs)`` of a call with an effect outside the function
    (a builtin such as ``print``, a method changing an object from outside), else None;
    ``local`` holds the function's own names, ``is_module(name)`` says whether a name it
    reads from outside is a module's (``np.sort(x)``, ``np.append(x, v)`` return new
    arrays)."""
    f = call.func
    if isinstance(f, ast.Name) and f.id in SIDE_EFFECTS and f.id not in local:
        return (f"it calls {f.id}()", f", {SIDE_EFFECTS[f.id]} (compiled code would do it "
                                      f"at other moments, or not at all)")
    if isinstance(f, ast.Attribute) and f.attr in MUTATORS and isinstance(f.value, ast.Name) \
            and f.value.id not in local and not is_module(f.value.id):
        return (f"it changes an object from outside ({f.value.id}.{f.attr})",
                ": a side effect compiled code would not have")
    return None
