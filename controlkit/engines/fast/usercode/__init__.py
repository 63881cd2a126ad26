"""Turning a user's ``(t, x, u, params)`` function into a kernel the fast engine can call.

python-control documents update and output functions as ``f(t, x, u, params)``
with ``params`` a dict. numba cannot compile a dict of mixed values, so the
function is compiled once for the *types and shapes* of its parameters, never
their values: :mod:`..source` plans the function (every read of ``params``, the
helpers it calls, the values it reads from outside), each read becomes a read of
the block contract's packed vector ``p`` (:class:`ParamLayout`: a float at one
index, an int or bool cast back where the code needs one, an array as a slice
reshaped, a complex as two floats), and :meth:`ParamLayout.pack` builds ``p`` from
the values in force for each run. The functions' globals and closure variables
(numbers, arrays, modules, compiled functions, attributes of objects) are frozen
as module-level constants, and the result is written as a small module in the
cache folder (:func:`.loader.cache_folder`), where numba compiles and caches it.
A new parameter value is a new ``p``: nothing is written or compiled again.

The user's functions and helpers are inlined into the kernel, and compiled with
numba's numpy error model: a division by zero gives ``inf`` or ``nan``, as it does in
Python for the numpy numbers that ``x`` and ``u`` hold, instead of a check per division
that made a kernel three times slower. (Python raises ``ZeroDivisionError`` when both
numbers are Python floats, such as two parameters; then the Python function raises at
every trial point below and the block runs as Python.)

Before a compiled function is trusted it is compared with the Python function at
several trial points (the run's initial state and inputs among them). A function
that cannot be planned, compiled or matched gets the reason instead; the engine
then calls it from Python inside its own loop.

The package's rooms: :mod:`.layout` (the packed vector ``p``), :mod:`.writer` (the kernel
module's text), :mod:`.compiling` (loading, checking, the Python fallback); what compiled
code calls is in :mod:`controlkit.kernels.user_calls`, re-exported here.
"""

from ....kernels.user_calls import clip, missing_parameter, store
from .compiling import UserKernel, block_layout, python_kernel
from .layout import ParamEntry, ParamLayout
from .writer import kernel_source

__all__ = ["ParamEntry", "ParamLayout", "UserKernel", "block_layout", "clip",
           "kernel_source", "missing_parameter", "python_kernel", "store"]
