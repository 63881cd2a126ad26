"""What compiled user code calls where numba's numbers are not Python's: the result stored
into ``out``, numbers clipped, products and powers, integers of floats, a missing
parameter raising ``KeyError`` and ``math``'s overflows raising ``OverflowError``; each
with its numba implementation (numpy's are in :mod:`.numpy_calls`).

The kernel modules written by :mod:`controlkit.engines.fast.usercode.writer` import them
from here.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from .. import _jit


def store(r, out):
    """Copy a user function's result (number, sequence or array) into ``out``.

    Examples
    --------
    >>> import numpy as np
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


def matmul(a, b):
    """``a @ b``, which compiled user functions call instead: numba's takes a one-row
    matrix times a vector to BLAS's matrix-vector product, numpy's to its dot product,
    whose last bits differ (a third of the time for two terms); a one-column matrix
    times a one-element vector is a product a row, summed from 0 as both sum it, without
    BLAS's call.

    Examples
    --------
    >>> import numpy as np
    >>> matmul(np.array([[1.0, 2.0]]), np.array([3.0, 4.0])).tolist()
    [11.0]
    """
    return a @ b


def power(a, b):
    """``a ** b``, which compiled user functions call instead, with Python's numbers: a
    number to a power is the C library's ``pow`` (numba multiplies for an integer power,
    ``x ** 3`` as ``x * x * x``, and LLVM turns ``pow(x, 2.0)`` into ``x * x``: the last bit
    differs from Python's on 0.1-25 % of values), raising where Python's float gives no
    float (a complex number, an error), so that the piece runs as Python; a float array to
    a number as numpy computes it (a square, a reciprocal or a square root for 2, -1 and
    0.5; else ``pow``).

    Examples
    --------
    >>> power(1.5, 3), power(2, -1)
    (3.375, 0.5)
    """
    return a ** b


def power_of_numbers(a, b):
    """:func:`power` where numpy raises an array to a power with code of its own (the CPU's
    wide registers) rather than the C library's ``pow``: compiled, a float array to a power
    other than 2, -1 and 0.5 is refused, and the block runs as Python.

    Examples
    --------
    >>> power_of_numbers(2.0, -1)
    0.5
    """
    return a ** b


def numpy_dot(a, b):
    """``np.dot(a, b)`` and ``a.dot(b)``, which compiled user functions call instead: a
    one-row matrix by a vector, and a vector by a one-column matrix, are numpy's dot
    products of two vectors (as :func:`matmul`), where numba's would take BLAS's
    matrix-vector product (a third of the time, other last bits).

    Examples
    --------
    >>> import numpy as np
    >>> numpy_dot(np.array([[1.0, 2.0]]), np.array([3.0, 4.0])).tolist()
    [11.0]
    """
    return np.dot(a, b)


#: The floats that convert to a 64-bit integer: ``-2**63 <= x < 2**63``.
INT64_RANGE = (-2.0 ** 63, 2.0 ** 63)


def within_int64(x):
    """``x``, which compiled user code converts to an integer (``int(x)``, ``round(x)``,
    ``math.floor``, ``ceil``, ``trunc``) after this call: numba turns a float outside
    :data:`INT64_RANGE`, or NaN, into ``-2**63`` without a word, where Python's integer
    holds any size (or raises for NaN and infinities). Compiled, such a float stops
    compiled code, and the run goes on as Python.

    Examples
    --------
    >>> within_int64(2.5), within_int64(7)
    (2.5, 7)
    """
    return x


def python_sum(iterable, start=0):
    """``sum(iterable, start)``, which compiled user functions call instead: from Python
    3.12 on, ``sum`` adds Python's own floats with a compensation of its rounding
    (Neumaier's), numpy's plainly, and compiled code cannot tell the two apart; there, a
    sum of a list or tuple that may hold floats stops the compiler, and the block runs as
    Python. An array's values (numpy's floats) and integers are added as numba adds them,
    as Python does.

    Examples
    --------
    >>> python_sum([0.1, 0.2, 0.3]) == sum([0.1, 0.2, 0.3])
    True
    """
    return sum(iterable, start)


def invert(x):
    """``~x``, which compiled user functions call instead: Python's ``~True`` is ``-2`` (a
    bool is an integer) and numpy's ``~np.True_`` is ``False``, and compiled code holds
    both as one boolean; there, the compiler stops and the block runs as Python. An
    integer's bits and a boolean array's values are inverted as numba inverts them.

    Examples
    --------
    >>> invert(True), invert(np.True_), invert(5)
    (-2, np.False_, -6)
    """
    return ~x


@_jit.on_numba_import
def _overloads(numba):
    """numba's implementations of the functions above (made when numba loads)."""
    from llvmlite import ir
    from numba import types as _nbtypes
    from numba.core.errors import TypingError
    from numba.extending import intrinsic, overload

    @overload(store, inline="always")
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
        elif isinstance(r, _nbtypes.BaseTuple):
            if not all(isinstance(e, _nbtypes.Number | _nbtypes.Boolean) for e in r):
                return None
            impl = _tuple_store(len(r))
        elif isinstance(r, _nbtypes.List):
            def impl(r, out):
                for i in range(len(r)):
                    out[i] = r[i]
                return out
        else:
            return None
        return impl

    def _tuple_store(n):
        """``store`` of a tuple of ``n`` numbers (of one type or several: indexed by
        constants), which must fill ``out`` (else the compiled run stops, and Python
        says what is wrong)."""
        lines = ["def impl(r, out):",
                 f"    if out.size != {n}:",
                 "        raise IndexError('a result of another size than the block declares')",
                 *(f"    out[{i}] = r[{i}]" for i in range(n)),
                 "    return out"]
        scope = {}
        exec("\n".join(lines), scope)  # noqa: S102 - the text above, n an int
        return scope["impl"]

    @overload(matmul, inline="always")
    def _matmul_overload(a, b):
        if (isinstance(a, _nbtypes.Array) and isinstance(b, _nbtypes.Array)
                and a.ndim == 2 and b.ndim == 1
                and a.dtype == b.dtype == _nbtypes.float64):
            def impl(a, b):  # numpy's matmul: one row by a vector is a dot product
                if a.shape[0] == 1 and a.shape[1] == b.shape[0] and b.shape[0] > 0:
                    out = np.empty(1)
                    out[0] = np.dot(np.ascontiguousarray(a[0]), np.ascontiguousarray(b))
                    return out
                if a.shape[1] == 1 and b.shape[0] == 1:  # one term a row: 0 + a b, as
                    out = np.empty(a.shape[0])       # numpy's (and BLAS's gemv) sum it
                    for i in range(a.shape[0]):
                        out[i] = 0.0 + a[i, 0] * b[0]
                    return out
                return a @ b
            return impl

        if _vector_by_column(a, b):
            return _vector_by_column_impl

        def impl(a, b):
            return a @ b
        return impl

    def _vector_by_column(a, b):
        return (isinstance(a, _nbtypes.Array) and isinstance(b, _nbtypes.Array)
                and a.ndim == 1 and b.ndim == 2
                and a.dtype == b.dtype == _nbtypes.float64)

    def _vector_by_column_impl(a, b):  # numpy's: a dot product of two vectors
        if b.shape[1] == 1 and a.shape[0] == b.shape[0] and a.shape[0] > 0:
            out = np.empty(1)
            out[0] = np.dot(np.ascontiguousarray(a), np.ascontiguousarray(b[:, 0]))
            return out
        return np.dot(a, b)

    @overload(numpy_dot, inline="always")
    def _dot_overload(a, b):
        if isinstance(a, _nbtypes.Array) and isinstance(b, _nbtypes.Array) \
                and a.ndim == 2 and b.ndim == 1:
            def impl(a, b):
                return matmul(a, b)
            return impl
        if _vector_by_column(a, b):
            return _vector_by_column_impl

        def impl(a, b):
            return np.dot(a, b)
        return impl

    @intrinsic
    def _c_pow(typingctx, a, b):
        """The C library's ``pow``, as Python calls it: a call LLVM may not replace by
        other arithmetic (``nobuiltin``)."""
        def codegen(context, builder, signature, args):
            double = ir.DoubleType()
            function = builder.module.globals.get("pow") or ir.Function(
                builder.module, ir.FunctionType(double, [double, double]), "pow")
            function.attributes.add("nobuiltin")
            return builder.call(function, args)
        return _nbtypes.float64(_nbtypes.float64, _nbtypes.float64), codegen

    @numba.njit(nogil=True)  # (called, not pasted: a raise at every power site slowed
    def _finite_pow(x, y):  # a kernel's compile by 10 %)
        result = _c_pow(x, y)
        # finite numbers, no finite power: Python's float gives a complex number (a
        # negative to a fractional power) or raises (0.0 to a negative power, an overflow),
        # numpy's NaN or inf: the piece runs as Python
        if not math.isfinite(result) and math.isfinite(x) and math.isfinite(y):
            raise ArithmeticError("a power of finite numbers with no finite value: complex "
                                  "or an error for Python's float, NaN or inf for numpy's, "
                                  "which compiled code cannot tell apart")
        return result

    def _power_overload(refuse_arrays):
        def typer(a, b):
            if isinstance(a, _nbtypes.Float | _nbtypes.Integer) and isinstance(
                    b, _nbtypes.Float | _nbtypes.Integer) and not (
                    isinstance(a, _nbtypes.Integer) and isinstance(b, _nbtypes.Integer)):
                def impl(a, b):
                    return _finite_pow(float(a), float(b))
                return impl
            if isinstance(a, _nbtypes.Array) and a.dtype == _nbtypes.float64 \
                    and isinstance(b, _nbtypes.Float | _nbtypes.Integer):
                if refuse_arrays and not (isinstance(b, _nbtypes.Literal)
                                          and b.literal_value in (2, -1)):
                    # (numba types a literal exponent again as one: 2 and -1 then pass)
                    raise TypingError(
                        "numpy raises a float array to a power other than 2 and -1 with "
                        "code of its own on this CPU, whose last bits compiled code does "
                        "not give (a number's power, or a product, compiles)")

                def impl(a, b):  # numpy's power: its three shortcuts, else pow
                    if b == 2:
                        return a * a
                    if b == -1:
                        return 1.0 / a
                    if b == 0.5:
                        return np.sqrt(a)
                    out = np.empty(a.shape)
                    values, results = a.ravel(), out.reshape(-1)
                    for i in range(values.size):
                        results[i] = _c_pow(values[i], float(b))
                    return out
                return impl

            def impl(a, b):
                return a ** b
            return impl
        return typer

    @overload(within_int64, inline="always")
    def _within_int64_overload(x):
        if not isinstance(x, _nbtypes.Float):
            return lambda x: x

        def impl(x):
            if not INT64_RANGE[0] <= x < INT64_RANGE[1]:  # (NaN too)
                raise OverflowError("a float made an integer beyond 64 bits (or NaN), "
                                    "which Python's int holds and compiled code does not")
            return x
        return impl

    def _whole(kind):
        return isinstance(kind, _nbtypes.Integer | _nbtypes.Boolean)

    @overload(python_sum, inline="always")
    def _python_sum_overload(iterable, start=0):
        if isinstance(iterable, _nbtypes.BaseTuple):
            whole = all(_whole(kind) for kind in iterable)
        else:
            whole = isinstance(iterable, _nbtypes.Array | _nbtypes.RangeType) or _whole(
                getattr(iterable, "dtype", None))
        if sys.version_info >= (3, 12) and not (whole and not isinstance(
                start, _nbtypes.Float)):
            raise TypingError("Python's sum() of floats (3.12 and later) compensates its "
                              "rounding for Python's floats and not for numpy's, which "
                              "compiled code cannot tell apart (a + b + c compiles)")

        def impl(iterable, start=0):
            return sum(iterable, start)
        return impl

    @overload(invert, inline="always")
    def _invert_overload(x):
        if isinstance(x, _nbtypes.Boolean):
            raise TypingError("it inverts a bool (~): Python's ~True is -2, numpy's "
                              "~np.True_ is False, and compiled code cannot tell the two "
                              "apart ('not' compiles)")
        return lambda x: ~x

    overload(power, inline="always")(_power_overload(refuse_arrays=False))
    overload(power_of_numbers, inline="always")(_power_overload(refuse_arrays=True))

    def _none(bound):
        return bound is None or isinstance(bound, _nbtypes.NoneType | _nbtypes.Omitted)

    @overload(clip, inline="always")
    def _clip_overload(a, a_min, a_max):
        if isinstance(a, _nbtypes.Array):
            def impl(a, a_min, a_max):
                return np.clip(a, a_min, a_max)
            return impl
        if not isinstance(a, _nbtypes.Number):
            return None
        # numpy's own definition, maximum with a_min then minimum with a_max (NaN anywhere
        # wins), as ufuncs on numbers: no branch, which numba's SSA pass warned about
        # (NumbaIRAssumptionWarning) once the overload was inlined several times
        if _none(a_min) and _none(a_max):
            return None
        if _none(a_min):
            def impl(a, a_min, a_max):
                return np.minimum(a, a_max)
        elif _none(a_max):
            def impl(a, a_min, a_max):
                return np.maximum(a, a_min)
        else:
            def impl(a, a_min, a_max):
                return np.minimum(np.maximum(a, a_min), a_max)
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


def _raising_as_python(function, domain=False):
    """``function`` of the math module as Python runs it: its ``OverflowError`` where a
    finite argument gives an infinite result, or with ``domain`` its ``ValueError`` where
    the argument is outside its domain (NaN from a number, an infinity at a pole). numba's
    returns those without a word, and a later ``1 / (1 + inf)``, a comparison or a result
    left unused makes a number again; Python's own run of the piece then says what it is.
    """
    if domain:
        def checked(x):
            y = function(x)
            if math.isnan(y) and not math.isnan(x) or math.isinf(y) and not math.isinf(x):
                raise ValueError("math domain error")
            return y
    else:
        def checked(x):
            y = function(x)
            if math.isinf(y) and not math.isinf(x):
                raise OverflowError("math range error")
            return y

    checked.__name__ = checked.__qualname__ = f"math_{function.__name__}"
    checked.__doc__ = (f"``math.{function.__name__}``, raising Python's "
                       f"``{'ValueError' if domain else 'OverflowError'}``.")
    return _jit.jit(checked)


#: What compiled user code calls instead of ``math.exp``, ``expm1``, ``sinh``, ``cosh``.
math_exp, math_expm1, math_sinh, math_cosh = map(
    _raising_as_python, (math.exp, math.expm1, math.sinh, math.cosh))
#: What compiled user code calls instead of ``math.sqrt``, ``log``, ``log10``, ``log2``,
#: ``log1p``, ``acos``, ``asin``, ``acosh``, ``atanh`` (of one argument: numba has no
#: ``log(x, base)``, whose function runs as Python).
(math_sqrt, math_log, math_log10, math_log2, math_log1p, math_acos, math_asin, math_acosh,
 math_atanh) = (_raising_as_python(f, domain=True) for f in (
    math.sqrt, math.log, math.log10, math.log2, math.log1p, math.acos, math.asin,
    math.acosh, math.atanh))
