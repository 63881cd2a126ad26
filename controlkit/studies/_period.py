"""The one sampling period of a diagram: checks shared by the builders."""

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
