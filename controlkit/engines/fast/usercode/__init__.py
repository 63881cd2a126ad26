"""A user's ``(t, x, u, params)`` function as a kernel ``(t, x, u, p, out)``.

Run as Python, the engine calls the function as it is (:class:`UserKernel`, which names
the block in any error). Compiled (docs/fast-blocks.md, *Your own nlsys*), the function's
plan (:mod:`..source`) is written out for the *types and shapes* of its parameters: each
``params`` read becomes a read of the packed vector ``p`` (:class:`~.layout.ParamLayout`),
the values read from outside become module-level constants, and the module, kept in the
store, is compiled on its own (:func:`~.compiling.compile_kernel`, timed for the engine's
estimates) before the diagram that calls it. A new parameter value is a new ``p``:
nothing is written or compiled again.

Compiled with numba's numpy error model, a division by zero gives ``inf`` or ``nan``, as in
Python for the numpy numbers ``x`` and ``u`` hold (where Python raises, for two Python
floats, the piece whose state goes non-finite is run again as Python, which raises).
"""

from .compiling import UserKernel, block_layout, compile_kernel, kernels_to_compile

__all__ = ["UserKernel", "block_layout", "compile_kernel", "kernels_to_compile"]
