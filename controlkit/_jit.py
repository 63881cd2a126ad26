"""Optional numba compilation of the kernels.

With numba installed (``pip install controlkit[fast]``) every kernel is
compiled once and cached on disk; without it, or with the environment
variable ``CONTROLKIT_DISABLE_NUMBA=1``, the same functions run as plain
Python. Both the python-control path and the fast engine call the kernels
through this module, so both compute with the same code.
"""

from __future__ import annotations

import os
import uuid

try:
    if os.environ.get("CONTROLKIT_DISABLE_NUMBA", "") not in ("", "0"):
        raise ImportError("disabled by CONTROLKIT_DISABLE_NUMBA")
    import numba
except ImportError:
    numba = None

#: True when kernels are compiled with numba.
HAVE_NUMBA = numba is not None


class _RandomIds:
    """Unique ids for the functions numba compiles: random 128-bit numbers, not 1, 2, 3.

    numba names the compiled code of a function (and the global that holds its
    environment) after the function and a per-process counter. Two processes
    compiling the same kernel, e.g. the test suite and a ``controlkit reproduce`` it
    starts, or two figure workers, give it the same number; when one process's
    compiled loop (which carries a copy of each kernel it calls) and the other's
    cached kernel are later loaded into one process, the second copy is bound to the
    first's environment. We saw a kernel then fail on return with numba's "In
    'NRT_adapt_ndarray_to_python', 'descr' is NULL" (numba issue 10486; PyTensor draws
    random ids for the same reason). numba only calls ``next()`` on this iterator.
    """

    def __iter__(self):
        return self

    def __next__(self) -> int:
        return uuid.uuid4().int


if numba is not None:
    from numba.core.bytecode import FunctionIdentity

    if hasattr(FunctionIdentity, "_unique_ids"):  # numba's counter (0.59-0.68)
        FunctionIdentity._unique_ids = _RandomIds()

#: Part of the name of every compiled loop and user kernel in the disk cache: changed
#: when code cached by earlier versions must not be loaded again (2: cached before the
#: random ids above, whose copies of a kernel could share a name with another's).
CACHE_FORMAT = 2


def jit(function=None, *, inline=False):
    """Compile ``function`` with numba (cached) when available; else return it unchanged.

    Every kernel and every helper a kernel calls is decorated with ``@jit``.
    ``@jit(inline=True)`` marks a helper that takes a kernel as an argument
    (:func:`controlkit.kernels.common.rk4_step`): numba inlines it into its caller
    before typing, so the kernel it is handed is a constant there and the caller's
    compiled loop can still be cached on disk.

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.kernels.common import constant_output  # decorated with @jit
    >>> constant_output(0.0, np.zeros(0), np.zeros(0), np.array([1.5]), np.zeros(1)).tolist()
    [1.5]
    """
    if function is None:
        return lambda f: jit(f, inline=inline)
    if numba is None:
        return function
    if inline:
        return numba.njit(cache=True, inline="always")(function)
    return numba.njit(cache=True)(function)


if numba is not None:
    from numba.core import cgutils
    from numba.extending import intrinsic

    @intrinsic
    def void_pointer(typingctx, address):
        """An integer address as a ``void*``, for ``numba.carray`` (compiled code only).

        A compiled function that receives arrays by address (``array.ctypes.data``)
        views them with ``numba.carray(void_pointer(address), shape, dtype)``: views
        that own nothing, so numba does not update any reference count when they are
        passed around (:mod:`controlkit.engines.fast.rk` relies on it). The caller keeps
        the arrays alive. Defined only when numba is.

        Examples
        --------
        >>> import numba
        >>> import numpy as np
        >>> @numba.njit
        ... def second(address, size):
        ...     return numba.carray(void_pointer(address), (size,), np.float64)[1]
        >>> values = np.array([1.0, 2.5, 4.0])
        >>> float(second(values.ctypes.data, values.size))
        2.5
        """
        if not isinstance(address, numba.types.Integer):
            return None

        def codegen(context, builder, signature, arguments):
            return builder.inttoptr(arguments[0], cgutils.voidptr_t)

        return numba.types.voidptr(address), codegen


def python_function(function):
    """The plain Python function behind a :func:`jit`-decorated one.

    Examples
    --------
    >>> from controlkit.kernels.common import rk4_step
    >>> python_function(rk4_step).__name__
    'rk4_step'
    """
    return getattr(function, "py_func", function)


def from_cache(dispatcher, args) -> bool:
    """Give the numba ``dispatcher`` its compiled code for the types of ``args`` from
    numba's disk cache, if it is there; never compile. True if it has that code now.

    What :meth:`numba.core.dispatcher.Dispatcher.compile` does on a cache hit (numba's
    own steps, under its compiler lock); any difference in numba's internals makes it
    answer False, and the first call then compiles or loads as ever.

    Examples
    --------
    >>> from_cache(lambda x: x, (1.0,))  # not a numba function
    False
    """
    try:
        from numba.core.compiler_lock import global_compiler_lock

        signature = tuple(dispatcher.typeof_pyval(a) for a in args)
        with global_compiler_lock:
            if dispatcher.overloads.get(signature) is not None:
                return True
            cres = dispatcher._cache.load_overload(signature, dispatcher.targetctx)
            if cres is None:
                return False
            dispatcher._cache_hits[signature] += 1
            if not cres.objectmode:
                dispatcher.targetctx.insert_user_function(cres.entry_point, cres.fndesc,
                                                          [cres.library])
            dispatcher.add_overload(cres)
            return True
    except Exception:  # noqa: BLE001 - not a numba dispatcher, or numba changed
        return False
