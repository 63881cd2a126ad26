"""What compiled user code calls where numba's numbers are not numpy's: sums, means,
norms and traces in numpy's order, LU factorisations only as far as numba's LAPACK gives
numpy's bits, and the sign, larger, smaller and remainder of numbers with numpy's signed
zeros; each with its numba implementation (:mod:`.user_calls` has Python's).

The kernel modules written by :mod:`controlkit.engines.fast.usercode.writer` import them
from here.
"""

from __future__ import annotations

import numpy as np

from .. import _jit

#: What numpy's sum of floats starts from: 0.0 (a sum of negative zeros is 0.0), or -0.0
#: where this numpy keeps their sign.
SUM_START = 0.0 if not np.signbit(np.add.reduce(np.array([-0.0, -0.0]))) else -0.0


def numpy_sum(a):
    """``np.sum(a)`` and ``a.sum()``, which compiled user functions call instead: numba adds
    an array's values one after the other, numpy in numpy's pairwise order (eight running
    sums, then halves of 128 and more), whose last bits differ from eight values on (a
    third of the time for twenty).

    Examples
    --------
    >>> import numpy as np
    >>> float(numpy_sum(np.arange(10.0)))
    45.0
    """
    return np.sum(a)


def numpy_mean(a):
    """``np.mean(a)`` and ``a.mean()``: numpy's sum (:func:`numpy_sum`) over the count.

    Examples
    --------
    >>> import numpy as np
    >>> float(numpy_mean(np.arange(10.0)))
    4.5
    """
    return np.mean(a)


def numpy_norm(x):
    """``np.linalg.norm(x)``, which compiled user functions call instead: numpy's is the
    square root of ``x.dot(x)``, numba's LAPACK's scaled sum of squares (the last bit
    differs on a sixth of vectors of two).

    Examples
    --------
    >>> import numpy as np
    >>> float(numpy_norm(np.array([3.0, 4.0])))
    5.0
    """
    return np.linalg.norm(x)


def numpy_trace(a):
    """``np.trace(a)`` and ``a.trace()``: numpy's sum of the diagonal, in numpy's order
    (:func:`numpy_sum`), where numba adds one term after the other.

    Examples
    --------
    >>> import numpy as np
    >>> float(numpy_trace(np.eye(3)))
    3.0
    """
    return np.trace(a)


#: The most rows of a matrix whose LU factors numba (scipy's LAPACK) and numpy give with the
#: same last bits, measured: from 6x6 on 4-80 % of random matrices differ.
LU_SAME_UP_TO = 5


def numpy_solve(a, b):
    """``np.linalg.solve(a, b)``, compiled up to :data:`LU_SAME_UP_TO` rows: beyond, compiled
    code stops and the run goes on as Python (so do :func:`numpy_det`, :func:`numpy_slogdet`).

    Examples
    --------
    >>> import numpy as np
    >>> numpy_solve(2.0 * np.eye(2), np.array([1.0, 3.0])).tolist()
    [0.5, 1.5]
    """
    return np.linalg.solve(a, b)


def numpy_det(a):
    """``np.linalg.det(a)``, compiled up to :data:`LU_SAME_UP_TO` rows (:func:`numpy_solve`).

    Examples
    --------
    >>> import numpy as np
    >>> float(numpy_det(2.0 * np.eye(2)))
    4.0
    """
    return np.linalg.det(a)


def numpy_slogdet(a):
    """``np.linalg.slogdet(a)``, compiled up to :data:`LU_SAME_UP_TO` rows (:func:`numpy_solve`).

    Examples
    --------
    >>> import numpy as np
    >>> [float(v) for v in numpy_slogdet(np.eye(2))]
    [1.0, 0.0]
    """
    return np.linalg.slogdet(a)


def numpy_sign(x):
    """``np.sign(x)``, which compiled user functions call instead: numpy's sign of a zero
    is ``0.0`` whatever the zero's sign, numba's keeps ``-0.0`` (equal numbers, which a
    later ``1 / s``, ``atan2`` or ``copysign`` would tell apart).

    Examples
    --------
    >>> float(numpy_sign(-0.0)), float(numpy_sign(-2.5))
    (0.0, -1.0)
    """
    return np.sign(x)


def _second_of_equals(function) -> bool:
    """Whether numpy's ``function`` (maximum, minimum) gives the second of two equal
    numbers here, ``-0.0`` for ``(0.0, -0.0)`` and ``0.0`` for ``(-0.0, 0.0)``, on numbers
    and on arrays (as its SIMD code does on x86 CPUs; elsewhere it may not)."""
    pair = np.array([0.0, -0.0]), np.array([-0.0, 0.0])
    return (np.signbit(function(*pair)).tolist() == [True, False]
            and bool(np.signbit(function(0.0, -0.0))) and not np.signbit(function(-0.0, 0.0)))


def numpy_maximum(a, b):
    """``np.maximum(a, b)``, which compiled user functions call instead: NaN wins, and of two
    equal numbers numpy gives the second (``maximum(0.0, -0.0)`` is ``-0.0``), numba the
    first. Compiled where numpy does so here (:func:`_second_of_equals`); elsewhere the
    block runs as Python. So does :func:`numpy_minimum`.

    Examples
    --------
    >>> float(numpy_maximum(-1.0, 2.0))
    2.0
    """
    return np.maximum(a, b)


def numpy_minimum(a, b):
    """``np.minimum(a, b)``: numpy's signed zeros as :func:`numpy_maximum`.

    Examples
    --------
    >>> float(numpy_minimum(-1.0, 2.0))
    -1.0
    """
    return np.minimum(a, b)


def numpy_mod(a, b):
    """``np.mod(a, b)`` (``np.remainder``), which compiled user functions call instead:
    Python's ``a % b``, whose rule numpy's follows (a zero remainder takes the divisor's
    sign: ``np.mod(2.0, -2.0)`` is ``-0.0``), where numba's ``np.mod`` gives ``0.0``.

    Examples
    --------
    >>> float(numpy_mod(-1.0, 3.0))
    2.0
    """
    return np.mod(a, b)


def numpy_floor_divide(a, b):
    """``np.floor_divide(a, b)``: Python's ``a // b``, as numpy's (numba's ``floor_divide``
    of ``5e-324`` by ``-2.0`` is ``-0.0``, numpy's and Python's ``-1.0``).

    Examples
    --------
    >>> float(numpy_floor_divide(7.0, -2.0))
    -4.0
    """
    return np.floor_divide(a, b)


def numpy_divmod(a, b):
    """``np.divmod(a, b)``: ``(a // b, a % b)``, as :func:`numpy_floor_divide` and
    :func:`numpy_mod`.

    Examples
    --------
    >>> [float(v) for v in numpy_divmod(7.0, -2.0)]
    [-4.0, -1.0]
    """
    return np.divmod(a, b)


@_jit.on_numba_import
def _overloads(numba):
    """numba's implementations of the functions above (made when numba loads). None is
    pasted into its caller (``inline="always"``): a helper calling one, called twice in a
    function, broke numba's inliner ("key already in dictionary"); LLVM inlines them
    anyway (the same time a step, measured)."""
    from numba import types as _nbtypes
    from numba.core.errors import TypingError
    from numba.extending import overload

    @numba.njit
    def _block_sum(a, start, n):
        """numpy's sum of at most 128 values ``a[start:start + n]``: in order below eight,
        else in eight running sums."""
        if n < 8:
            total = -0.0
            for i in range(start, start + n):
                total += a[i]
            return total
        r0, r1, r2, r3 = a[start], a[start + 1], a[start + 2], a[start + 3]
        r4, r5, r6, r7 = a[start + 4], a[start + 5], a[start + 6], a[start + 7]
        i = 8
        while i < n - n % 8:
            at = start + i
            r0 += a[at]
            r1 += a[at + 1]
            r2 += a[at + 2]
            r3 += a[at + 3]
            r4 += a[at + 4]
            r5 += a[at + 5]
            r6 += a[at + 6]
            r7 += a[at + 7]
            i += 8
        total = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
        for k in range(i, n):
            total += a[start + k]
        return total

    @numba.njit
    def _left_half(n):  # numpy's: half of n values, rounded down to eight
        return n // 2 - (n // 2) % 8

    @numba.njit
    def _pairwise_sum(a, start, n):
        """numpy's order of adding ``a[start:start + n]`` (its ``pairwise_sum``): blocks of
        at most 128 values (:func:`_block_sum`), halves (rounded down to eight values) added
        left + right. numpy's recursion is run on a stack of halves here: a recursive jitted
        function crashed the process that loaded a module calling it from the store."""
        if n <= 128:
            return _block_sum(a, start, n)
        starts, sizes = np.empty(64, np.int64), np.empty(64, np.int64)
        lefts, left_done = np.empty(64), np.zeros(64, np.bool_)
        depth, starts[0], sizes[0] = 0, start, n
        while True:
            if sizes[depth] > 128:  # split: its left half first
                left_done[depth] = False
                starts[depth + 1], sizes[depth + 1] = starts[depth], _left_half(sizes[depth])
                depth += 1
                continue
            value, right_next = _block_sum(a, starts[depth], sizes[depth]), False
            while depth > 0 and not right_next:  # a left half waits for its right one,
                depth -= 1                       # a right half ends its pair
                if left_done[depth]:
                    value = lefts[depth] + value
                    continue
                lefts[depth], left_done[depth], right_next = value, True, True
                half = _left_half(sizes[depth])
                starts[depth + 1] = starts[depth] + half
                sizes[depth + 1] = sizes[depth] - half
                depth += 1
            if not right_next:
                return value

    def _flat_floats(a):
        """Whether numpy sums ``a`` as one row of floats: one dimension, or C order."""
        return isinstance(a, _nbtypes.Array) and a.dtype == _nbtypes.float64 and (
            a.ndim == 1 or a.layout == "C")

    def _refused(what):
        raise TypingError(f"{what}: numba's order of sums is not numpy's, whose last bits "
                          "compiled code gives for a float array alone, all its values")

    @overload(numpy_sum)
    def _sum_overload(a):
        if not _flat_floats(a):
            _refused("a sum of other than a float array")

        def impl(a):  # (numpy adds the sum to its add's identity: a sum of -0.0 is 0.0)
            return SUM_START + _pairwise_sum(a.ravel(), 0, a.size) if a.size else SUM_START
        return impl

    @overload(numpy_mean)
    def _mean_overload(a):
        if not _flat_floats(a):
            _refused("a mean of other than a float array")

        def impl(a):  # numpy's: its sum over the count
            return numpy_sum(a) / a.size
        return impl

    @overload(numpy_norm)
    def _norm_overload(x):
        if not _flat_floats(x):
            _refused("the norm of other than a float array")

        def impl(x):
            flat = x.ravel()
            return np.sqrt(np.dot(flat, flat))
        return impl

    @overload(numpy_trace)
    def _trace_overload(a):
        if not (isinstance(a, _nbtypes.Array) and a.ndim == 2
                and a.dtype == _nbtypes.float64):
            _refused("the trace of other than a float matrix")

        def impl(a):  # numpy's: the sum of the diagonal (a copy)
            return numpy_sum(np.diag(a))
        return impl

    too_large = (f"a matrix of more than {LU_SAME_UP_TO} rows factored by LU (solve, det, "
                 "slogdet): compiled code's LAPACK gives other last bits than numpy's there, "
                 "and the run goes on as Python")

    @numba.njit
    def _lu_same(a):
        if a.shape[-1] > LU_SAME_UP_TO:
            raise ValueError(too_large)

    @overload(numpy_solve)
    def _solve_overload(a, b):
        def impl(a, b):
            _lu_same(a)
            return np.linalg.solve(a, b)
        return impl

    def _of_one_matrix(numpy_function):
        def typer(a):
            def impl(a):
                _lu_same(a)
                return numpy_function(a)
            return impl
        return typer

    overload(numpy_det)(_of_one_matrix(np.linalg.det))
    overload(numpy_slogdet)(_of_one_matrix(np.linalg.slogdet))

    @overload(numpy_sign)
    def _sign_overload(x):
        if x == _nbtypes.float64:
            return lambda x: _sign(x)
        if isinstance(x, _nbtypes.Array) and x.dtype == _nbtypes.float64:
            def impl(x):
                out = np.empty(x.shape)
                values, results = x.ravel(), out.reshape(-1)
                for i in range(values.size):
                    results[i] = _sign(values[i])
                return out
            return impl
        return lambda x: np.sign(x)  # integers: no signed zero (float32: numba's)

    @numba.njit
    def _sign(x):  # numpy's: 1, -1, 0 for either zero, NaN stays (not inlined: a branch)
        if x > 0.0:
            return 1.0
        if x < 0.0:
            return -1.0
        return 0.0 if x == 0.0 else x

    def _extreme(function, pick):
        def typer(a, b):
            if not _second_of_equals(function):
                raise TypingError(f"numpy's {function.__name__} of two equal zeros is not "
                                  "the second here, as compiled code's is")
            numbers = _nbtypes.Float | _nbtypes.Integer
            kinds = [v.dtype if isinstance(v, _nbtypes.Array) else v for v in (a, b)]
            if not all(isinstance(kind, numbers) for kind in kinds):
                return None
            floats = [kind for kind in kinds if isinstance(kind, _nbtypes.Float)]
            if not floats or any(kind != _nbtypes.float64 for kind in floats):
                return lambda a, b: function(a, b)  # integers, float32: numba's own
            if isinstance(a, numbers) and isinstance(b, numbers):
                return lambda a, b: pick(a, b)

            def impl(a, b):
                a2, b2 = np.broadcast_arrays(np.asarray(a), np.asarray(b))
                out = np.empty(a2.shape)
                for at in np.ndindex(a2.shape):
                    out[at] = pick(a2[at], b2[at])
                return out
            return impl
        return typer

    @numba.njit
    def _larger(a, b):  # numpy's maximum here: NaN wins, else the second of equals
        if a != a:
            return 1.0 * a
        return 1.0 * a if a > b else 1.0 * b

    @numba.njit
    def _smaller(a, b):
        if a != a:
            return 1.0 * a
        return 1.0 * a if a < b else 1.0 * b

    overload(numpy_maximum)(_extreme(np.maximum, _larger))
    overload(numpy_minimum)(_extreme(np.minimum, _smaller))

    # numba's own % and // are Python's, which numpy's mod and floor_divide follow
    overload(numpy_mod)(lambda a, b: lambda a, b: a % b)
    overload(numpy_floor_divide)(lambda a, b: lambda a, b: a // b)
    overload(numpy_divmod)(lambda a, b: lambda a, b: (a // b, a % b))

