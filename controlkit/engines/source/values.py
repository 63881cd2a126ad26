"""Values a function reads from outside itself (its module, its closure, objects): which
ones the compiler can freeze, how each is read again to tell whether a plan is still
valid, and the markers of a value not known or not there.
"""

from __future__ import annotations

import importlib
import keyword
import types

import numpy as np

from ... import _jit

#: Modules whose functions numba compiles itself: calls into them are left as written.
NUMERIC_MODULES = ("numpy", "math", "cmath")

#: Packages whose plain Python functions are never compiled as helpers (their internals
#: are not numerical kernels: a python-control system's methods, numpy's Python layer).
_NOT_HELPERS = ("control", "numpy", "scipy", "controlkit", "numba", "functools", "builtins")


def _is_number(value):
    return isinstance(value, bool | int | float | complex | np.number | np.bool_)


def _is_array_like(value):
    """A numpy array, or a list or tuple of numbers (nested lists: a matrix)."""
    if isinstance(value, np.ndarray):
        return True
    if isinstance(value, list | tuple) and value:
        try:
            return np.asarray(value).dtype.kind in "biufc"
        except (ValueError, TypeError):
            return False
    return False


def _is_numeric_function(value):
    """A function numba compiles itself: numpy's, math's, a ufunc."""
    module = getattr(value, "__module__", None) or ""
    return callable(value) and not isinstance(value, type) and (
        isinstance(value, np.ufunc) or module.split(".")[0] in NUMERIC_MODULES)


def _is_numba_function(value):
    return hasattr(value, "py_func") and hasattr(value, "targetoptions")


def _is_plain(value):
    """A value the compiler can freeze as it is (not an object to read attributes of)."""
    return (value is None or isinstance(value, str) or _is_number(value)
            or _is_array_like(value) or isinstance(value, types.ModuleType)
            or _is_numeric_function(value) or _is_numba_function(value)
            or isinstance(value, types.FunctionType))


def _dotted(name) -> bool:
    """Whether ``name`` is a dotted name of identifiers (what may be written after import).

    Examples
    --------
    >>> _dotted("numpy.linalg"), _dotted("os; os.system('x')")
    (True, False)
    """
    return isinstance(name, str) and all(part.isidentifier() and not keyword.iskeyword(part)
                                         for part in name.split("."))


def _import_name(value):
    """``(module, name)`` that ``from module import name`` gives ``value`` itself by (a
    numpy, math or numba function), else None; checked before anything is imported."""
    fn = _jit.python_function(value)
    module, name = getattr(fn, "__module__", None), getattr(fn, "__name__", "")
    try:
        found = _dotted(module) and name.isidentifier() and getattr(
            importlib.import_module(module), name, None) is value
    except ImportError:
        return None
    return (module, name) if found else None


def _helper_allowed(fn):
    module = (getattr(fn, "__module__", None) or "").split(".")[0]
    return module not in _NOT_HELPERS


class _Marker:
    """A value standing for something that is not a value (its repr says what)."""

    def __init__(self, name):
        self.name = name

    def __repr__(self):
        return self.name


#: A key or a value not known when the plan is made.
_UNKNOWN = _Marker("<unknown>")
#: A name or a key that is not there.
_MISSING = _Marker("<missing>")


def _cell(cell):
    try:
        return cell.cell_contents
    except ValueError:  # an empty cell: a name defined later in the enclosing function
        return None


def _evaluate(value, steps):
    """``value.a[b]...`` for ``steps`` ``[("attr", "a"), ("item", b), ...]``."""
    for kind, step in steps:
        value = getattr(value, step) if kind == "attr" else value[step]
    return value


def _reevaluate(root, steps):
    try:
        return _evaluate(root(), steps)
    except Exception:  # noqa: BLE001 - not readable now: the plan is out of date
        return _MISSING


def _same(a, b) -> bool:
    """Whether a value read now is the one a plan was made with."""
    if a is b:
        return True
    if type(a) is not type(b):
        return False
    if isinstance(a, str):
        return a == b
    if _is_number(a):  # by their bits: 0.0 and -0.0 are equal, yet divide differently
        return np.asarray(a).tobytes() == np.asarray(b).tobytes() or bool(a != a and b != b)
    if isinstance(a, types.MethodType):  # a new bound method object at each read
        return a.__func__ is b.__func__ and a.__self__ is b.__self__
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    return False


def _same_items(now, then) -> bool:
    """Whether keyword defaults (or a partial's keywords) read now are the ones of then."""
    if now is None or then is None:
        return now is None and then is None
    return now.keys() == then.keys() and all(_same(now[k], then[k]) for k in now)
