"""The one sampling period of a diagram: checks and converters shared by the builders."""

from __future__ import annotations

from ..blocks.sampling import sample_nlsys


def require_period(block, Ts, *, static_ok=False, loop="the loop"):
    """Refuse ``block`` unless it runs at the loop's period ``Ts``.

    With ``static_ok``, a block without a period of its own (``dt`` None or
    True) joins the loop too. The message names the block, the loop (``loop``, e.g. the
    builder's name) and what to do: a continuous block is sampled first, or the diagram
    is wired with :func:`controlkit.interconnect`, which joins continuous and discrete
    blocks.

    Examples
    --------
    >>> from controlkit.blocks.mec import nominal_model
    >>> try:
    ...     require_period(nominal_model(0.2), 0.1)
    ... except ValueError as error:
    ...     print(error)
    block 'nominal' runs at dt = 0.2 s but the loop runs at Ts = 0.1 s; build it with Ts=0.1
    """
    if static_ok and (block.dt is None or block.dt is True):  # dt = 1 is a period, not True
        return block
    if block.dt == 0:
        if block.nstates == 0 and static_ok:
            raise ValueError(
                f"block {block.name!r} has no states but is declared continuous (dt = 0), "
                f"and {loop} is sampled at Ts = {Ts} s: build it with dt=None, which "
                f"joins a continuous or a discrete diagram")
        raise ValueError(
            f"block {block.name!r} is continuous (dt = 0) but {loop} is sampled at "
            f"Ts = {Ts} s: sample it first (controlkit.sample_nlsys({block.name}, {Ts}), "
            f"or control.sample_system for an LTI block), or wire the diagram yourself "
            f"with controlkit.interconnect, which joins continuous and discrete blocks")
    if block.dt != Ts:
        raise ValueError(f"block {block.name!r} runs at dt = {block.dt} s but {loop} runs at "
                         f"Ts = {Ts} s; build it with Ts={Ts}")
    return block


def sampled(plant, Ts, *, loop="the loop"):
    """The plant as a block at ``Ts``: a continuous plant is put under ZOH, a discrete one checked.

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> sampled(spacecraft_plant(), 0.1).dt
    0.1
    """
    if plant.isctime(strict=True):
        return sample_nlsys(plant, Ts)
    return require_period(plant, Ts, loop=loop)


def zero_order_hold(signals, Ts, *, name="zoh"):
    """A D/A converter: the discrete identity at ``Ts`` from ``<s>_cmd`` to each ``<s>``.

    Its output is the command at each instant, held until the next: between a digital
    controller and a continuous plant in a sampled-data diagram
    (:func:`controlkit.interconnect`).

    Examples
    --------
    >>> hold = zero_order_hold(["u[0]", "u[1]"], 0.1)
    >>> hold.input_labels, hold.output_labels, hold.dt
    (['u_cmd[0]', 'u_cmd[1]'], ['u[0]', 'u[1]'], 0.1)
    """
    from ..blocks.contract import KernelBlock
    from ..kernels.common import identity_output

    hold = KernelBlock(identity_output, feedthrough=True, dt=Ts, name=name,
                       inputs=[_command(s) for s in signals], outputs=list(signals))
    hold.display_name = "ZOH"
    return hold


def _command(signal):
    base, bracket, index = signal.partition("[")
    return f"{base}_cmd{bracket}{index}"


def commanding(block, signals):
    """A copy of ``block`` whose outputs ``signals`` are renamed ``<s>_cmd``: it drives a
    :func:`zero_order_hold` instead of the plant (the caller's block is left as it was).

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import io_linearizer
    >>> commanding(io_linearizer(), ["u[0]", "u[1]"]).output_labels
    ['u_cmd[0]', 'u_cmd[1]']
    """
    copy = block.copy(name=block.name)
    copy.set_outputs([_command(s) if s in signals else s for s in block.output_labels])
    return copy
