"""The one sampling period of a diagram: checks and converters shared by the builders."""

from __future__ import annotations

from ..blocks.sampling import sample_nlsys


def require_period(block, Ts, *, static_ok=False):
    """Refuse ``block`` unless it runs at the loop's period ``Ts``.

    With ``static_ok``, a block without a period of its own (``dt`` None or
    True) joins the loop too.

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
    if block.dt != Ts:
        raise ValueError(f"block {block.name!r} runs at dt = {block.dt} s but the loop runs at "
                         f"Ts = {Ts} s; build it with Ts={Ts}")
    return block


def sampled(plant, Ts):
    """The plant as a block at ``Ts``: a continuous plant is put under ZOH, a discrete one checked.

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> sampled(spacecraft_plant(), 0.1).dt
    0.1
    """
    if plant.isctime(strict=True):
        return sample_nlsys(plant, Ts)
    return require_period(plant, Ts)


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
