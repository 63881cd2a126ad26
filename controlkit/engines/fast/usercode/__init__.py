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

from ....kernels.numpy_calls import (
    numpy_det,
    numpy_divmod,
    numpy_floor_divide,
    numpy_maximum,
    numpy_mean,
    numpy_minimum,
    numpy_mod,
    numpy_norm,
    numpy_sign,
    numpy_slogdet,
    numpy_solve,
    numpy_sum,
    numpy_trace,
)
from ....kernels.user_calls import (
    clip,
    matmul,
    missing_parameter,
    numpy_dot,
    power,
    power_of_numbers,
    python_sum,
    store,
    within_int64,
)
from .compiling import UserKernel, block_layout, compile_kernel, kernels_to_compile

__all__ = ["UserKernel", "block_layout", "clip", "compile_kernel", "kernels_to_compile",
           "matmul", "missing_parameter", "numpy_det", "numpy_divmod", "numpy_dot",
           "numpy_floor_divide", "numpy_maximum", "numpy_mean", "numpy_minimum", "numpy_mod",
           "numpy_norm", "numpy_sign", "numpy_slogdet", "numpy_solve", "numpy_sum",
           "numpy_trace", "power", "power_of_numbers", "python_sum", "store", "within_int64"]
