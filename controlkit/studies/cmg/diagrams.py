"""The thesis's closed loop of the CMG (its Fig. 2), wired with ``control.interconnect``."""

from __future__ import annotations

import control as ct

from ...blocks import cmg
from ...sampled_data import interconnect as sampled_data_interconnect
from .._period import require_period, sampled


def cmg_loop(plant=None, controller=None, *, reference=None, saturation=None, Ts=cmg.TS_CMG,
             continuous_plant=False, name="cmg_loop"):
    """References -> adaptive SMC -> torque saturation -> CMG -> controller, sampled at ``Ts``.

    The controller computes from the sampled state; the continuous plant is
    held under zero-order hold between samples (:func:`~controlkit.blocks.sampling.sample_nlsys`).

    Parameters
    ----------
    plant : control.NonlinearIOSystem, optional
        Continuous (sampled here) or discrete at ``Ts``;
        default :func:`~controlkit.blocks.cmg.cmg_plant`.
    controller : control.NonlinearIOSystem, optional
        Default :func:`~controlkit.blocks.cmg.adaptive_smc` at ``Ts``.
    reference, saturation : control.NonlinearIOSystem, optional
        Defaults :func:`~controlkit.blocks.cmg.reference_generator` and
        :func:`~controlkit.blocks.cmg.torque_saturation`.
    Ts : float
        Sampling period (s), default 1 ms.
    continuous_plant : bool
        False (default): the continuous plant is sampled under zero-order hold (RK4 over
        each sample) and the diagram is discrete. True: the plant stays continuous; the
        controller is discrete, so the torques it computes are held between samples
        through the static saturation, and the diagram is a sampled-data one
        (:func:`controlkit.interconnect`; run it with
        :func:`controlkit.input_output_response`). The two agree to the integrator's
        tolerance.
    name : str
        System name; the drawing's title unless it is the default (then the thesis's
        loop, when the blocks are the thesis's).

    Returns
    -------
    control.InterconnectedSystem
        Discrete at ``Ts`` (sampled-data with ``continuous_plant``), no inputs. Outputs
        ``q1, q2, q4, w1, w2, w4, q2d, q4d, T1, T2, T1_cmd, T2_cmd, a1, a2, a3, a4``.

    Examples
    --------
    >>> [s.name for s in cmg_loop().syslist]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    plant = plant if plant is not None else cmg.cmg_plant()
    if continuous_plant and not plant.isctime(strict=True):
        raise ValueError(f"continuous_plant=True needs a continuous plant (dt = 0); "
                         f"{plant.name!r} has dt = {plant.dt}")
    plant = plant if continuous_plant else sampled(plant, Ts, loop=name)
    controller = require_period(
        controller if controller is not None else cmg.adaptive_smc(Ts=Ts), Ts, loop=name)
    reference = reference if reference is not None else cmg.reference_generator()
    saturation = saturation if saturation is not None else cmg.torque_saturation()
    for block in (reference, saturation):
        require_period(block, Ts, static_ok=True, loop=name)

    #  +-----------+ q2d, q4d  +-----------------+ T_cmd +------------+ T1, T2 +-----------+
    #  | reference |---------->|  adaptive SMC   |------>| saturation |------->| CMG (ZOH) |--+
    #  | section 6 | + derivs  | eq. 20-45, a^'s |       | |T1|<=0.6  |        | eq. 1-3   |  |
    #  +-----------+           +-----------------+       | |T2|<=2.4  |        +-----------+  |
    #                                   ^                +------------+                       |
    #                                   +------------ q1, q2, q4, w1, w2, w4 -----------------+
    loop = (sampled_data_interconnect if continuous_plant else ct.interconnect)(
        [reference, plant, controller, saturation],
        inputs=[],
        outputs=cmg.STATES + ["q2d", "q4d", "T1", "T2", "T1_cmd", "T2_cmd",
                              "a1", "a2", "a3", "a4"],
        name=name,
    )
    # the blocks carry the thesis's names (controlkit.blocks.contract.drawn_as); the title
    # is the thesis's loop only when the loop is: the default name and the thesis's blocks
    papers = all(getattr(b, "display_name", None) == symbol for b, symbol in (
        (reference, "references"), (controller, "adaptive SMC"),
        (saturation, "torque limits"), (plant, "CMG")))
    # drawn leaving the loop: the gyroscope's states and the adaptive gains, as the thesis
    # draws them; the references and torques, logged too, are named under the drawing
    loop.drawing_hints = {"title": TITLE if papers and name == "cmg_loop" else name,
                          "outputs": cmg.STATES + ["a1", "a2", "a3", "a4"]}
    return loop


#: Title of the drawing of the thesis's loop (:func:`cmg_loop` with its own blocks).
TITLE = "CMG: adaptive backstepping SMC, sampled at Ts"
