"""Borrowed array views: the slices the engine hands its kernels, without reference counts.

``a[i:j]`` in compiled code is a new array that holds a reference to ``a``'s memory:
numba increments and decrements an atomic counter when the view is made and dropped,
and again when a function returns it. A kernel call passes four views and returns one,
some ten atomic operations (about 50 ns, measured) for a kernel that may compute in 2 ns.
:func:`borrow` builds the same view with no owner (a null ``meminfo``), on which numba's
reference counting returns at once: the call then costs a plain call. It is safe as long
as the view does not outlive ``a``, which holds for the views a loop hands to its kernels.
Without numba it is an ordinary slice.
"""

from __future__ import annotations

from ..._jit import HAVE_NUMBA


def borrow(array, start, length):
    """``array[start:start + length]`` (compiled: a view without an owner).

    Examples
    --------
    >>> import numpy as np
    >>> borrow(np.arange(5.0), 1, 3).tolist()
    [1.0, 2.0, 3.0]
    """
    return array[start:start + length]


def unowned(array):
    """``array`` itself (compiled: the same array without an owner, as :func:`borrow`).

    For the arrays a loop hands its right-hand side in a tuple at every stage: unpacked
    from the tuple, each was counted up and down again per call, atomically (over half the
    time of a sampled-data loop's intervals). Safe while ``array`` outlives the result.

    Examples
    --------
    >>> import numpy as np
    >>> unowned(np.ones((2, 3))).shape
    (2, 3)
    """
    return array


if HAVE_NUMBA:
    from numba import types
    from numba.core import cgutils
    from numba.extending import intrinsic, overload
    from numba.np.arrayobj import make_array, populate_array

    @intrinsic
    def _borrowed(typingctx, array, start, length):
        if not (isinstance(array, types.Array) and array.ndim == 1 and array.layout == "C"):
            return None
        view_type = array.copy(readonly=False) if array.mutable else array

        def codegen(context, builder, signature, args):
            base_value, first, n = args
            base = make_array(array)(context, builder, base_value)
            view = make_array(view_type)(context, builder)
            intp = context.get_value_type(types.intp)
            first = context.cast(builder, first, signature.args[1], types.intp)
            n = context.cast(builder, n, signature.args[2], types.intp)
            itemsize = context.get_constant(types.intp, context.get_abi_sizeof(
                context.get_data_type(array.dtype)))
            populate_array(view, data=cgutils.gep_inbounds(builder, base.data, first),
                           shape=cgutils.pack_array(builder, [n], ty=intp),
                           strides=cgutils.pack_array(builder, [itemsize], ty=intp),
                           itemsize=itemsize, meminfo=None)
            return view._getvalue()

        return view_type(array, start, length), codegen

    @overload(borrow, inline="always")
    def _borrow_overload(array, start, length):
        if isinstance(array, types.Array) and array.ndim == 1 and array.layout == "C":
            return lambda array, start, length: _borrowed(array, start, length)
        return None

    @intrinsic
    def _unowned(typingctx, array):
        if not (isinstance(array, types.Array) and array.layout == "C"):
            return None

        def codegen(context, builder, signature, args):
            view = make_array(array)(context, builder, args[0])
            view.meminfo = cgutils.get_null_value(view.meminfo.type)
            view.parent = cgutils.get_null_value(view.parent.type)
            return view._getvalue()

        return array(array), codegen

    @overload(unowned, inline="always")
    def _unowned_overload(array):
        if isinstance(array, types.Array) and array.layout == "C":
            return lambda array: _unowned(array)
        return None

    def _aliases_its_array(lhs, args, alias_map, arg_aliases):
        """Tell numba's alias analysis that a borrowed view aliases its array: without it,
        once a kernel is pasted into its caller, its writes into the view (never read
        again there) were removed as dead stores."""
        from numba.core.ir_utils import _add_alias

        _add_alias(lhs, args[0].name, alias_map, arg_aliases)

    from numba.core import ir_utils as _ir_utils

    for _name in ("borrow", "_borrowed", "unowned", "_unowned"):
        _ir_utils.alias_func_extensions[(_name, __name__)] = _aliases_its_array
