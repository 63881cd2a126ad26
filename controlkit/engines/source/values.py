"""Values a function reads from outside itself (its module, its closure, objects): which
ones the compiler can freeze, how each is read again to tell whether a plan is still
valid, and the markers of a value not known or not there.
"""

from __future__ import annotations

import cmath
import enum
import functools
import keyword
import math
import sys
import types
import unicodedata

import numpy as np

from ... import _jit

#: Modules whose functions numba compiles itself: calls into them are left as written.
NUMERIC_MODULES = ("numpy", "math", "cmath")

#: Packages whose plain Python functions are never compiled as helpers (their internals
#: are not numerical kernels: a python-control system's methods, numpy's Python layer).
_NOT_HELPERS = ("control", "numpy", "scipy", "controlkit", "numba", "functools", "builtins")


def _is_number(value):
    return isinstance(value, bool | int | float | complex | np.number | np.bool_)


#: Methods by which a class gives its numbers (or texts) arithmetic or comparisons of its own.
_OPERATORS = frozenset(f"__{name}__" for name in (
    "add radd sub rsub mul rmul truediv rtruediv floordiv rfloordiv mod rmod divmod rdivmod "
    "pow rpow matmul rmatmul neg pos abs invert and rand or ror xor rxor lshift rlshift "
    "rshift rrshift eq ne lt le gt ge int float index bool complex round trunc floor "
    "ceil").split())


def plain_values(value) -> bool:
    """Whether ``value`` computes as compiled code computes its numbers (or text): one of
    Python's number types or ``str`` itself, a numpy scalar of its own type, a numpy array
    (the class itself), an enumeration's member whose classes add no operator, or a list
    or tuple of these; not a subclass with arithmetic or comparisons of its own, which
    compiled code would not call (a ``float`` subclass's ``__mul__``).

    Examples
    --------
    >>> class Gain(float):
    ...     def __mul__(self, other):
    ...         return 10.0 * float(self) * other
    >>> plain_values([1.0, 2, np.float64(3.0)]), plain_values(Gain(2.0)), plain_values([Gain(2.0)])
    (True, False, False)
    """
    kind = type(value)
    if kind in (bool, int, float, complex, str, np.ndarray):
        return True
    if isinstance(value, np.generic):
        return kind is value.dtype.type
    if kind in (list, tuple):
        return all(plain_values(item) for item in value)
    return isinstance(value, enum.Enum) and not any(
        _OPERATORS & vars(cls).keys() for cls in kind.__mro__
        if cls.__module__ != "enum" and cls not in (int, float, complex, str, object))


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
    """Whether ``name`` is a dotted name of identifiers (what may be written after import)
    that Python reads as written: a name its parser would normalize (NFKC: a fullwidth
    letter, a ligature) would name another module or function in the text.

    Examples
    --------
    >>> _dotted("numpy.linalg"), _dotted("os; os.system('x')"), _dotted("\uff43k")
    (True, False, False)
    """
    return isinstance(name, str) and unicodedata.normalize("NFKC", name) == name and all(
        part.isidentifier() and not keyword.iskeyword(part) for part in name.split("."))


def imported(name: str) -> bool:
    """Whether the module ``name`` and each package above it are imported already: an
    import statement of it then finds them all in ``sys.modules``, where Python's
    ``import a.b`` would otherwise import ``a`` by name, searching ``sys.path``.

    Examples
    --------
    >>> imported("numpy.linalg"), imported("no_such_package.sub")
    (True, False)
    """
    parts = name.split(".")
    return all(".".join(parts[:i]) in sys.modules for i in range(1, len(parts) + 1))


def name_text(name) -> str:
    """``name``'s own text, "" for other than a ``str``: a subclass's ``__str__``,
    ``__format__`` or ``__repr__`` is never asked (a name is data, written as module text).

    Examples
    --------
    >>> name_text("numpy"), name_text(None)
    ('numpy', '')
    """
    return str.__str__(name) if isinstance(name, str) else ""


def _import_name(value):
    """``(module, name)`` that ``from module import name`` gives ``value`` itself by (a
    numpy, math or numba function), else None; checked before anything is imported."""
    fn = _jit.python_function(value)
    module = name_text(getattr(fn, "__module__", None))
    name = name_text(getattr(fn, "__name__", None))
    # (a module imported already: a name read from an attribute is data, never imported)
    found = _dotted(module) and _dotted(name) and "." not in name and imported(module) and getattr(
        sys.modules.get(module), name, None) is value
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


#: numpy's functions of numbers that compiled code computes with the C library's function
#: (numba calls it, as Python's math module does), by the math module's name for it.
C_LIBRARY = {"exp": "exp", "exp2": "exp2", "expm1": "expm1", "log": "log", "log2": "log2",
             "log10": "log10", "log1p": "log1p", "sin": "sin", "cos": "cos", "tan": "tan",
             "arcsin": "asin", "arccos": "acos", "arctan": "atan", "sinh": "sinh",
             "cosh": "cosh", "tanh": "tanh", "arcsinh": "asinh", "arccosh": "acosh",
             "arctanh": "atanh", "cbrt": "cbrt", "arctan2": "atan2", "power": "pow"}
# (not hypot: numpy's is the C library's, and math.hypot, to compare with, is not)


def _sample_points(name):
    """The points :func:`parts_from_c_library` compares ``name`` at: 20 000 in its domain,
    most where a model's numbers are (within a few units), seeded (the same every time)."""
    rng = np.random.default_rng(20261128)
    if name in ("arcsin", "arccos", "arctanh"):
        return (rng.uniform(-1.0, 1.0, 20000),)
    if name == "arctan2":
        return rng.uniform(-4.0, 4.0, 20000), rng.uniform(-4.0, 4.0, 20000)
    if name == "power":  # (numpy's shortcuts for 2, -1 and 0.5 are the same everywhere)
        return rng.uniform(1e-3, 4.0, 20000), rng.uniform(-4.0, 4.0, 20000)
    low, wide = {"log": (1e-3, 1e-6), "log2": (1e-3, 1e-6), "log10": (1e-3, 1e-6),
                 "log1p": (-0.99, 1e-6), "arccosh": (1.0, 1.0)}.get(name, (-4.0, None))
    spread = (np.geomspace(wide, 1e6, 5000) if wide is not None
              else np.linspace(-19.0, 19.0, 5000))
    return (np.concatenate([rng.uniform(low, 4.0, 15000), spread]),)


@functools.cache
def parts_from_c_library(name: str) -> float:
    """The share of sample points at which numpy's function ``name`` (a key of
    :data:`C_LIBRARY`) gives other numbers than the C library's, called on numbers and on
    an array: 0 where numpy calls the C library, more where it has code of its own for
    this machine (vectorised with the CPU's wide registers: exp, tanh, ... on AVX-512),
    whose last bits compiled code would not reproduce.

    Examples
    --------
    >>> parts_from_c_library("sin") >= 0.0
    True
    """
    function, c_function = getattr(np, name), getattr(math, C_LIBRARY[name])
    points = [p.ravel() for p in _sample_points(name)]
    expected = np.array([c_function(*map(float, p)) for p in zip(*points, strict=True)])
    on_numbers = np.array([function(*p) for p in zip(*points, strict=True)])
    on_array = function(*points)
    differ = ~((on_numbers == expected) & (on_array == expected))
    return float(np.mean(differ))


#: Functions numba computes by another method than numpy's (or Python's), with other last
#: bits, or answers in another form; a block calling one runs as Python. (Shares of
#: differing results, compiled against Python, on 3 000 seeded arguments on the
#: benchmarks' machine.)
COMPUTED_OTHERWISE = {
    np.linalg.inv: "numba inverts with LAPACK's LU inverse, numpy solves against the "
                   "identity (61-100 % of 2x2 to 4x4 matrices differ); np.linalg.solve "
                   "(numpy's method in both) compiles up to 5x5",
    **{f: f"numpy's {f.__name__} of a real matrix answers complex numbers where the "
          "eigenvalues are complex, numba's refuses them (ValueError), after a compile of "
          "seconds; of a symmetric matrix, np.linalg.eigvalsh and eigh give numpy's numbers "
          "compiled"
       for f in (np.linalg.eig, np.linalg.eigvals)},
    np.var: "numba's variance sums in another order than numpy's (22 % of 12 values differ)",
    np.std: "numba's standard deviation sums in another order than numpy's (14 % of 12 "
            "values differ)",
    **{f: f"numba's {f.__name__} sums in another order than numpy's (average, nansum: 8-11 "
          "% of 10 values differ)"
       for f in (np.average, np.nansum, np.nanmean, np.nanvar, np.nanstd)},
    **{f: f"numba's {f.__name__} takes another method than numpy's (found differing on "
          "7-100 % of sample arguments)"
       for f in (np.linalg.cholesky, np.linalg.pinv, np.angle, np.convolve, np.correlate,
                 np.percentile, np.quantile)},
    **{f: f"numba's {f.__name__} is not the one Python calls (73-77 % differ)"
       for f in (math.gamma, math.lgamma)},
    cmath.log: "numba's complex logarithm is not Python's (18 % differ)",
    np.spacing: "numba's spacing of -0.0 is -5e-324, numpy's 5e-324",
    math.hypot: "Python's math.hypot has a method of its own, not the C library's hypot "
                "that compiled code calls (0.5 % differ); np.hypot is the C library's in both",
    **({np.trapezoid: "numba's trapezoid rule sums in another order than numpy's (33 % of "
                      "10 values differ)"} if hasattr(np, "trapezoid") else {}),
}


def narrow(dtype) -> bool:
    """Whether numpy computes in ``dtype`` (a number type) otherwise than compiled code,
    which computes in 64 bits: an ``int32`` product wraps, a ``float32`` rounds to 24
    bits, and the numbers part ways, maybe late in a run.

    Examples
    --------
    >>> narrow(np.int16), narrow(np.float32), narrow(np.float64), narrow(np.complex128)
    (True, True, False, False)
    """
    return np.dtype(dtype).str[1:] not in ("i8", "f8", "c16")


def _items(value):
    for item in value:
        if type(item) in (list, tuple):
            yield from _items(item)
        else:
            yield item


def sequence_loses(value) -> str | None:
    """Why the one array compiled code makes of a list or tuple ``value`` would not compute
    as its items do in Python (a numpy scalar narrower than 64 bits among them, an integer
    past 2**53 made a float among floats), said after its name; else None.

    Examples
    --------
    >>> sequence_loses([0.5, np.float32(0.1)]).split(":")[0], sequence_loses([0.5, 2])
    ('holds an item of type float32', None)
    """
    if type(value) not in (list, tuple):
        return None
    items = list(_items(value))
    kinds = [np.dtype(type(item)) for item in items if isinstance(item, np.generic)]
    if any(kind.kind in "iufc" and narrow(kind) for kind in kinds):
        kind = next(kind for kind in kinds if kind.kind in "iufc" and narrow(kind))
        return f"holds an item of type {kind.name}: numpy computes in it, compiled code in 64 bits"
    if any(isinstance(item, float | complex | np.floating) for item in items):
        big = [i for i in items if isinstance(i, int | np.integer) and abs(int(i)) > 2 ** 53]
        if big:
            return (f"holds the integer {big[0]} among floats: compiled code holds it as a "
                    f"float, rounded")
    return None


def numpy_last_bits(value) -> str | None:
    """Why compiled code would not give ``value``'s numbers, when it is a function that
    numba computes by another method (:data:`COMPUTED_OTHERWISE`), a numpy scalar type
    other than the 64-bit ones (``np.float32``, ``np.int16``: numpy computes in its width,
    numba in 64 bits), or a numpy function
    whose own implementation here differs from the C library's in the last bits (see
    :func:`parts_from_c_library`); else None.

    Examples
    --------
    >>> numpy_last_bits(np.clip) is None
    True
    >>> numpy_last_bits(np.random.randn).split(" (")[0]
    "it draws numpy's random numbers"
    >>> numpy_last_bits(np.linalg.inv).split(":")[0]
    'it calls numpy.linalg.inv'
    >>> numpy_last_bits(np.float32).split(":")[0], numpy_last_bits(np.float64)
    ('it uses numpy.float32', None)
    """
    try:
        otherwise = COMPUTED_OTHERWISE.get(value)
    except TypeError:  # (an unhashable value: not a function)
        otherwise = None
    if otherwise is not None:
        return f"it calls {value.__module__}.{value.__name__}: {otherwise}"
    if isinstance(value, type) and issubclass(value, np.number) and narrow(value):
        return (f"it uses numpy.{value.__name__}: numpy computes in its "
                f"{np.dtype(value).itemsize * 8} bits, compiled code in 64 (the numbers "
                f"part ways, maybe late in a run)")
    if isinstance(getattr(value, "__self__", None), np.random.RandomState | np.random.Generator):
        return (f"it draws numpy's random numbers ({getattr(value, '__name__', value)}), "
                f"whose state compiled code does not share: numba draws from its own")
    name = getattr(value, "__name__", None)
    if not isinstance(value, np.ufunc) or name not in C_LIBRARY or getattr(np, name) is not value:
        return None
    share = parts_from_c_library(name)
    if not share:
        return None
    return (f"it calls numpy.{name}, which numpy computes here with code of its own "
            f"({share:.1%} of sample values differ in the last bits from the C library's "
            f"{name}, which compiled code calls); math.{C_LIBRARY[name]} on numbers is the "
            f"C library's in Python too, and compiles")
