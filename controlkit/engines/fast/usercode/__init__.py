"""A user's ``(t, x, u, params)`` function as a kernel ``(t, x, u, p, out)``.

Run as Python, the engine calls the function as it is (:class:`UserKernel`, which names
the block in any error). Compiled (docs/fast-blocks.md, *Your own nlsys*), the function's
plan (:mod:`..source`) is written out for the *types and shapes* of its parameters: each
``params`` read becomes a read of the packed vector ``p`` (:class:`~.layout.ParamLayout`:
a float at one index, an int or bool cast back, an array as a slice reshaped, a complex
as two floats), the values read from outside become module-level constants, and the
module, kept in the store (:mod:`..store`), is compiled with the diagram that calls it. A
new parameter value is a new ``p``: nothing is written or compiled again.

The user's functions and helpers are pasted into the kernel, compiled with numba's numpy
error model: a division by zero gives ``inf`` or ``nan``, as it does in Python for the
numpy numbers ``x`` and ``u`` hold. (Where Python raises instead, for two Python floats,
the compiled piece whose state goes non-finite is run again as Python, which raises.)

The package's rooms: :mod:`.layout` (the packed vector ``p``), :mod:`.writer` (the kernel
module's text), :mod:`.compiling` (:class:`UserKernel`); what compiled code calls is in
:mod:`controlkit.kernels.user_calls`, re-exported here.
"""

from ....kernels.user_calls import clip, matmul, missing_parameter, store
from .compiling import UserKernel, block_layout

__all__ = ["UserKernel", "block_layout", "clip", "matmul", "missing_parameter", "store"]
