"""Kernels: the equations of the blocks, one plain function per update or output.

One module per family of blocks, mirroring :mod:`controlkit.blocks`
(``common``, ``spacecraft``, ``mec``, ``cmg``). A kernel is named after its
block and role: ``<block>_output``, ``<block>_update`` (discrete) or
``<block>_rhs`` (continuous). What a kernel must be and do is the block
contract in :class:`controlkit.blocks.contract.KernelBlock`.
"""
