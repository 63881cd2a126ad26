"""What a function runs, as a digest: its code, its defaults, numba's options for it and
the values it reads from outside (numba freezes them into compiled code), followed into
the functions it calls. Compiled code kept in the store is named by it, so that a value
or a helper changed since is a new module, never an old one loaded again.
"""

from __future__ import annotations

import hashlib
import inspect
import types as pytypes

import numpy as np

from ... import _jit
from .values import NUMERIC_MODULES, _cell


def code_digest(code, digest) -> None:
    """Feed what ``code`` runs into ``digest`` (a :mod:`hashlib` object): its bytecode,
    flags, argument counts, names and constants (nested code too), none of which depend
    on the process (unlike ``marshal``'s bytes, or a frozenset's order).

    Examples
    --------
    >>> import hashlib
    >>> def digest(f):
    ...     d = hashlib.sha256()
    ...     code_digest(f.__code__, d)
    ...     return d.hexdigest()
    >>> two, three = digest(lambda x: 2 * x), digest(lambda x: 3 * x)
    >>> two == digest(lambda x: 2 * x), three == two
    (True, False)
    """
    digest.update(code.co_code)
    digest.update(code.co_exceptiontable)
    digest.update(repr((code.co_flags, code.co_argcount, code.co_posonlyargcount,
                        code.co_kwonlyargcount, code.co_names, code.co_varnames,
                        code.co_freevars, code.co_cellvars)).encode())
    for const in code.co_consts:
        if isinstance(const, pytypes.CodeType):
            code_digest(const, digest)
        elif isinstance(const, frozenset):
            digest.update(repr(sorted(map(repr, const))).encode())
        else:
            digest.update(repr(const).encode())


def runs(function) -> str:
    """A digest of what ``function`` (imported by a kernel) runs: its code, its defaults,
    numba's options for it, and the values of what it reads by global name (numba freezes
    them into the compiled code: numbers, strings, arrays, tuples, a module's or a class's
    attributes such as an enumeration's members), followed into the functions it calls
    that way.

    Examples
    --------
    >>> def make(k):
    ...     return lambda v: k * v
    >>> runs(make(2.0)) == runs(make(2.0)), runs(make(2.0)) == runs(make(3.0))
    (True, False)
    """
    digest = hashlib.sha256()
    todo, seen = [function], set()
    while todo:
        called = todo.pop()
        fn = _jit.python_function(called)
        code = getattr(fn, "__code__", None)
        if code is None or id(fn) in seen:
            continue
        seen.add(id(fn))
        code_digest(code, digest)
        options = getattr(_jit.dispatcher(called), "targetoptions", None) or {}
        digest.update(repr(sorted((key, sorted(map(repr, value)) if isinstance(
            value, set | frozenset) else repr(value)) for key, value in options.items())).encode())
        namespace = getattr(fn, "__globals__", {})
        names = _global_names(code)
        cells = zip(code.co_freevars, fn.__closure__ or (), strict=False)
        reads = [(name, namespace.get(name)) for name in names]
        reads += [(name, _cell(cell)) for name, cell in cells]  # (an empty one: None)
        reads += [("(defaults)", getattr(fn, "__defaults__", None) or ()),
                  ("(keyword defaults)", tuple(sorted((getattr(fn, "__kwdefaults__", None)
                                                       or {}).items())))]
        for name, value in reads:
            _feed(digest, name, value, names, todo, seen)
    return digest.hexdigest()[:16]


def _feed(digest, name, value, names, todo, seen) -> None:
    """Feed the value ``name`` reads into ``digest``; a function it may call into ``todo``.
    A module's or a class's attributes are fed by the names the code reads (``consts.G``,
    ``Mode.BOOST``), but not numpy's, math's, numba's or Python's own (numba compiles
    those itself)."""
    if isinstance(value, bool | int | float | complex | str | bytes) or value is None:
        digest.update(repr((name, value)).encode())
    elif isinstance(value, np.ndarray | np.generic):
        digest.update(repr((name, value.dtype.str, np.shape(value))).encode())
        digest.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, tuple):
        digest.update(repr((name, "tuple", len(value))).encode())
        for i, item in enumerate(value):
            _feed(digest, f"{name}[{i}]", item, names, todo, seen)
    elif isinstance(value, pytypes.ModuleType | type):
        owner = value.__name__ if isinstance(value, pytypes.ModuleType) else value.__module__
        if id(value) not in seen and str(owner).split(".")[0] not in (
                *NUMERIC_MODULES, "numba", "builtins"):
            seen.add(id(value))
            for attr in names:
                found = inspect.getattr_static(value, attr, _ABSENT)
                if found is not _ABSENT:
                    _feed(digest, f"{name}.{attr}", found, names, todo, seen)
    elif callable(value):
        todo.append(value)


#: What :func:`inspect.getattr_static` answers for an attribute that is not there.
_ABSENT = object()


def _global_names(code):
    """The global names ``code`` (and the code nested in it) reads."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, pytypes.CodeType):
            names |= set(_global_names(const))
    return sorted(names)
