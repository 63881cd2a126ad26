"""Functions that run as Python until compiled code calls them.

Every kernel and every helper the simulation loops call is decorated with :func:`jit`.
The decorated function is a :class:`Jitted`: called from Python it runs its own Python
code (importing nothing), and when numba compiles a function that calls it, numba sees a
numba function (:attr:`Jitted.dispatcher`, made on first need). So a diagram run as
Python never imports numba, and the same source is what compiled code runs.

numba is imported on first need, and only if it is installed (``pip install
".[fast]"``) and not switched off by ``CONTROLKIT_DISABLE_NUMBA=1`` (then everything
runs as Python: :func:`available` says False).
"""

from __future__ import annotations

import functools
import os
import threading

import numpy as np

#: numba's module once imported (see :func:`numba_module`).
_NUMBA: list = []
#: Functions to call with numba's module when it is first imported (overloads, typing).
_ON_IMPORT: list = []
#: Held while numba is imported and controlkit's additions registered (re-entrant: they
#: ask for numba's module themselves); ``_READY`` once they all are.
_STARTING = threading.RLock()
_READY: list = []


def available() -> bool:
    """Whether numba can compile here (installed and not switched off).

    Examples
    --------
    >>> isinstance(available(), bool)
    True
    """
    if os.environ.get("CONTROLKIT_DISABLE_NUMBA", "") not in ("", "0"):
        return False
    if _NUMBA:
        return True
    import importlib.util

    return importlib.util.find_spec("numba") is not None


def numba_module():
    """numba, imported now if it was not, with controlkit's additions to it registered.

    Raises
    ------
    ImportError
        When numba is not installed or switched off (see :func:`available`).

    Examples
    --------
    >>> available() == (numba_module() is not None) if available() else True
    True
    """
    if not _READY:
        with _STARTING:  # (another thread waits until every addition is registered)
            if not _NUMBA:
                if not available():
                    raise ImportError("numba is not installed (pip install \".[fast]\") or "
                                      "is switched off by CONTROLKIT_DISABLE_NUMBA")
                import numba
                from numba.extending import typeof_impl

                from . import compat

                compat.unique_function_ids(numba)

                @typeof_impl.register(Jitted)
                def _typeof_jitted(value, context):  # compiled code calling it calls numba's
                    return typeof_impl(value.dispatcher, context)

                _NUMBA.append(numba)
                _compiled_only(numba)
                for register in _ON_IMPORT:
                    register(numba)
                _READY.append(True)
    return _NUMBA[0]


def on_numba_import(register):
    """Call ``register(numba)`` when numba is first imported (now if it is): for overloads
    of functions compiled code calls. Returns ``register``.

    Examples
    --------
    >>> seen = []
    >>> _ = on_numba_import(seen.append)
    >>> len(seen) == (1 if _NUMBA else 0)
    True
    """
    with _STARTING:
        _ON_IMPORT.append(register)
        if _NUMBA:
            register(_NUMBA[0])
    return register


class Jitted:
    """A function that runs its Python code when Python calls it, and numba's compiled
    version when compiled code calls it (see the module's description).

    Attributes
    ----------
    py_func : callable
        The function itself (the name numba's dispatchers use too).
    options : dict
        Options for :func:`numba.njit` (``inline="always"`` for a helper that takes a
        function as an argument, which numba must paste into its caller).
    python : callable
        What Python calls run: ``py_func``, or a Python version given to :func:`jit`
        for a function whose compiled form uses what only compiled code can (addresses).
    """

    def __init__(self, py_func, options, python=None):
        self.py_func = py_func
        self.options = options
        self.python = python or py_func
        self._dispatcher = None
        functools.update_wrapper(self, py_func)

    def __call__(self, *args, **kwargs):
        return self.python(*args, **kwargs)

    @property
    def targetoptions(self) -> dict:
        """The options numba's inliner reads of a function it meets in compiled code (the
        name numba's dispatchers give them): an ``inline="always"`` one is pasted into
        its caller before typing, as a numba function would be."""
        return self.options

    def __repr__(self):
        return f"<jit function {self.__module__}.{self.__qualname__}>"

    def __copy__(self):
        return self

    def __deepcopy__(self, memo):  # a function: numba's inliner copies the code that
        return self                # names it, which must not copy the function itself

    @property
    def dispatcher(self):
        """The numba function compiled code calls (made, not compiled, on first access)."""
        if self._dispatcher is None:
            self._dispatcher = numba_module().njit(**self.options)(self.py_func)
        return self._dispatcher


def jit(function=None, *, inline=False, python=None):
    """Mark ``function`` for compiled code (see :class:`Jitted`); Python calls run it as is.

    ``inline=True`` asks numba to paste the function into each compiled caller (a
    helper that takes a kernel as an argument, such as
    :func:`controlkit.kernels.common.rk4_step`: the kernel is then a constant there).
    ``python`` is the function Python calls run, when the compiled form cannot run as
    Python.

    Examples
    --------
    >>> import numpy as np
    >>> from controlkit.kernels.common import constant_output  # decorated with @jit
    >>> constant_output(0.0, np.zeros(0), np.zeros(0), np.array([1.5]), np.zeros(1)).tolist()
    [1.5]
    """
    if function is None:
        return lambda f: jit(f, inline=inline, python=python)
    return Jitted(function, {"inline": "always"} if inline else {}, python)


def python_function(function):
    """The plain Python function behind a :func:`jit` one (or a numba dispatcher).

    Examples
    --------
    >>> from controlkit.kernels.common import rk4_step
    >>> python_function(rk4_step).__name__
    'rk4_step'
    """
    if isinstance(function, Jitted):
        return function.python
    return getattr(function, "py_func", function)


def dispatcher(function):
    """The numba function of a :func:`jit` one (a numba dispatcher is returned as is).

    Examples
    --------
    >>> from controlkit.kernels.common import state_output
    >>> hasattr(dispatcher(state_output), "py_func") if available() else True
    True
    """
    return function.dispatcher if isinstance(function, Jitted) else function


# ----------------------------------------------------------------------------------------
# Arrays viewed by address, in compiled code only (the integrator's step machine)
# ----------------------------------------------------------------------------------------

#: numba's module and an integer-to-pointer cast, set when numba is imported: the views
#: below are compiled, never run as Python.
numba = None
pointer = None


def _compiled_only(module):
    """Make :data:`pointer`, numba's documented ``inttoptr`` intrinsic (the example of
    the "high-level extension API" page)."""
    global numba, pointer
    from numba import types
    from numba.extending import intrinsic

    @intrinsic
    def address_as_pointer(typingctx, address):
        if not isinstance(address, types.Integer):
            return None

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(types.voidptr))

        return types.voidptr(address), codegen

    numba, pointer = module, address_as_pointer


@jit(inline=True)
def floats_at(address, size):
    """The ``size`` floats at ``address`` as an array that owns nothing: numba counts no
    references for it (compiled code only; the caller keeps the memory alive)."""
    return numba.carray(pointer(address), (size,), np.float64)


@jit(inline=True)
def matrix_at(address, rows, columns):
    """The ``rows`` x ``columns`` floats at ``address`` (as :func:`floats_at`)."""
    return numba.carray(pointer(address), (rows, columns), np.float64)


@jit(inline=True)
def ints_at(address, size):
    """The ``size`` 64-bit integers at ``address`` (as :func:`floats_at`)."""
    return numba.carray(pointer(address), (size,), np.int64)
