"""Block diagrams of the two-wheel spacecraft paper, wired with ``control.interconnect``.

Signals are connected by name: an input called ``q[0]`` is fed by the output
called ``q[0]``. Each builder takes its blocks as arguments, so a reader can
swap one (another plant, another controller) without touching the wiring.
"""

from __future__ import annotations

import control as ct

from ..._checks import warn_caller
from ...blocks import frit, mec
from ...blocks import spacecraft as sc
from ...sampled_data import interconnect as sampled_data_interconnect
from .._period import commanding, require_period, sampled, zero_order_hold

Q = [f"q[{i}]" for i in range(4)]
U = ["u[0]", "u[1]"]
H = ["h[0]", "h[1]"]
MU = ["mu[0]", "mu[1]"]
R = ["r[0]", "r[1]"]


#: Titles of the papers' figures, drawn when a builder's diagram is the paper's: its
#: default name and the paper's blocks (a plant of your own is still the paper's figure).
TITLES = {
    "linearized_plant": "Fig. 2 (red frame): the linearized plant",
    "fig2_loop": "Fig. 2: the linearized plant closed by the outer loop",
    "fig3": "Fig. 3: MEC with a constant gain K",
    "fig4": "Fig. 4: MEC with the on-line FRIT tuner",
}
# the symbol each of the papers' blocks is drawn with (controlkit.blocks.contract.drawn_as)
_PAPERS_SYMBOLS = {"linearizer": r"$\beta(q)\,\mu - \alpha(q)$", "controller": "$F$",
                   "nominal": "$L_n$", "constant_gain": "$K$", "frit": "FRIT"}


def _is_papers(block, role):
    """Whether ``block`` is the papers' block for ``role`` (made by its factory, not renamed)."""
    return getattr(block, "display_name", None) == _PAPERS_SYMBOLS[role]


def _drawing_hints(name, default_name, figure, plant, linearizer, output, nominal=None,
                   gain=None):
    """How :func:`~controlkit.drawing.draw_block_diagram` shows a builder's diagram.

    The blocks' symbols (``$F$``, ``$L_n$``, the junction ``r - h``) are the blocks' own
    (:func:`~controlkit.blocks.contract.drawn_as`): a block passed in is drawn with its own
    name. The builder adds only what is about the wiring: the frame of the linearized
    plant ``L_a`` (Fig. 2), the nominal model in parallel to the plant and a tuner under
    the output (Fig. 3-4), the outputs drawn leaving the loop as the paper draws them
    (``h``, and the tuned ``K``) and the title: the paper's figure (``figure``, a key of
    :data:`TITLES`) when ``name`` is the builder's default and the blocks are the
    paper's, else ``name``.
    """
    frame = (r"$L_a$: linearized plant (Fig. 2)" if _is_papers(linearizer, "linearizer")
             else "linearized plant")
    hints = {"groups": {frame: [linearizer.name, plant.name, output.name]},
             "title": TITLES[figure] if name == default_name and figure is not None else name,
             # the papers' figures draw h leaving the loop (and the tuned K); the other
             # outputs, logged for the results, are named under the drawing
             "outputs": list(H)}
    if nominal is not None:
        hints["beside"] = {nominal.name: plant.name}
    if gain is not None and gain.ninputs:  # a tuner reads mu, hn and h: under the output
        hints.setdefault("beside", {})[gain.name] = output.name
        hints["outputs"] += list(mec.K_SIGNALS)
    return hints


def _plant_side(plant, linearizer, Ts, continuous_plant, name):
    """``(plant, linearizer, hold blocks, interconnect)`` for the plant's side of a loop.

    Sampled (the default, as the paper): the continuous plant under zero-order hold by
    :func:`~controlkit.blocks.sampling.sample_nlsys` (RK4), the diagram discrete. With
    ``continuous_plant``: the plant stays continuous behind a zero-order hold at ``Ts``
    on ``u`` (the linearizer drives ``u_cmd``), a sampled-data diagram
    (:func:`controlkit.interconnect`) whose continuous part is integrated between
    samples; both agree to the integrator's tolerance.
    """
    plant = plant if plant is not None else sc.spacecraft_plant()
    linearizer = require_period(linearizer if linearizer is not None else sc.io_linearizer(),
                                Ts, static_ok=True, loop=name)
    if not continuous_plant:
        return sampled(plant, Ts, loop=name), linearizer, [], ct.interconnect
    if not plant.isctime(strict=True):
        raise ValueError(f"continuous_plant=True needs a continuous plant (dt = 0); "
                         f"{plant.name!r} has dt = {plant.dt}")
    return (plant, commanding(linearizer, U), [zero_order_hold(U, Ts)],
            sampled_data_interconnect)


def linearized_plant(plant=None, linearizer=None, *, Ts=sc.TS_PAPER, continuous_plant=False,
                     name="linearized_plant"):
    """Fig. 2 (red frame): the plant made linear by the linearizer, ``mu -> h``.

    With an exact model the result is ``h' = mu`` between samples (eq. 10-11).

    Parameters
    ----------
    plant : control.NonlinearIOSystem, optional
        Continuous (sampled here under ZOH at ``Ts``) or already discrete at ``Ts``.
        Default: :func:`~controlkit.blocks.spacecraft.spacecraft_plant` with nominal values.
    linearizer : control.NonlinearIOSystem, optional
        Default: :func:`~controlkit.blocks.spacecraft.io_linearizer` (nominal model).
    Ts : float
        Sampling period, default 0.1 s.
    continuous_plant : bool
        Keep the plant continuous behind a zero-order hold (a sampled-data diagram)
        instead of sampling it (see :func:`output_zeroing_loop`).
    name : str
        System name; the drawing's title unless it is the default (then the paper's
        figure, when the blocks are the paper's).

    Returns
    -------
    control.InterconnectedSystem
        Discrete at ``Ts`` (sampled-data with ``continuous_plant``). Inputs ``mu[0],
        mu[1]``; outputs ``h[0], h[1], u[0], u[1], q[0]..q[3]``.

    Examples
    --------
    >>> sys = linearized_plant()
    >>> sys.input_labels, sys.output_labels[:2]
    (['mu[0]', 'mu[1]'], ['h[0]', 'h[1]'])
    """
    plant, linearizer, hold, make = _plant_side(plant, linearizer, Ts, continuous_plant,
                                                name)
    output = sc.attitude_output()

    #        +------------+  u   +-------------+  q   +--------+  h
    #  mu -->| linearizer |----->| plant (ZOH) |--+-->|  h(q)  |----->
    #        |  eq. 11    |      |  eq. 1-8    |  |   |  eq. 9 |
    #        +------------+      +-------------+  |   +--------+
    #              ^                              |
    #              +--------------- q ------------+
    sys = make(
        [plant, output, linearizer, *hold],  # in signal order: fewest feedthrough sweeps
        inputs=MU,
        outputs=H + U + Q,
        name=name,
    )
    papers = _is_papers(linearizer, "linearizer")
    sys.drawing_hints = _drawing_hints(name, "linearized_plant",
                                       "linearized_plant" if papers else None,
                                       plant, linearizer, output)
    return sys


def output_zeroing_loop(
    plant=None, linearizer=None, controller=None, *, Ts=sc.TS_PAPER, continuous_plant=False,
    name="fig2_loop",
):
    """Fig. 2 closed by the outer controller ``mu = F (r - h)`` (eq. 12), sampled at ``Ts``.

    The blocks are wired flat (not as a nested ``linearized_plant``) so that the
    simulation sweeps one level of blocks.

    Parameters
    ----------
    plant, linearizer : control.NonlinearIOSystem, optional
        As in :func:`linearized_plant`.
    controller : control.NonlinearIOSystem, optional
        Default :func:`~controlkit.blocks.spacecraft.outer_controller` with ``F = 0.0009``.
    Ts : float
        Sampling period, default 0.1 s.
    continuous_plant : bool
        False (default): the continuous plant is sampled under zero-order hold
        (:func:`~controlkit.blocks.sampling.sample_nlsys`, RK4 over each sample: the
        paper's loop, erratum E5) and the diagram is discrete. True: the plant stays
        continuous behind a zero-order hold ``zoh`` on ``u``, and the diagram is a
        sampled-data one (:func:`controlkit.interconnect`; run it with
        :func:`controlkit.input_output_response`), its plant integrated between samples
        by an adaptive method; the two agree to the integrator's tolerance.
    name : str
        System name; the drawing's title unless it is the default (then Fig. 2's, when
        the linearizer and the controller are the paper's).

    Returns
    -------
    control.InterconnectedSystem
        Discrete at ``Ts`` (sampled-data with ``continuous_plant``). Inputs ``r[0],
        r[1]`` (leave at 0 for output zeroing);
        outputs ``h[0], h[1], u[0], u[1], q[0]..q[3], mu[0], mu[1]``; states
        ``plant_q[0]..plant_q[3]`` (python-control prefixes the block name).

    Examples
    --------
    >>> loop = output_zeroing_loop()
    >>> loop.nstates, loop.dt
    (4, 0.1)
    """
    plant, linearizer, hold, make = _plant_side(plant, linearizer, Ts, continuous_plant,
                                                name)
    controller = controller if controller is not None else sc.outer_controller()
    for block in (linearizer, controller):
        require_period(block, Ts, static_ok=True, loop=name)
    output = sc.attitude_output()

    #          +------------+  mu  +------------+  u   +-------------+  q   +-------+
    #  r=0 -->o| controller |----->| linearizer |----->| plant (ZOH) |--+-->| h(q)  |--+--> h
    #        -^| mu=F(r-h)  |      |  eq. 11    |      |  eq. 1-8    |  |   | eq. 9 |  |
    #         | +------------+      +------------+      +-------------+  |   +-------+  |
    #         |                          ^                               |              |
    #         |                          +-------------- q --------------+              |
    #         +---------------------------------- h -----------------------------------+
    sys = make(
        [plant, output, controller, linearizer, *hold],
        inputs=R,
        outputs=H + U + Q + MU,
        name=name,
    )
    papers = _is_papers(linearizer, "linearizer") and _is_papers(controller, "controller")
    sys.drawing_hints = _drawing_hints(name, "fig2_loop", "fig2_loop" if papers else None,
                                       plant, linearizer, output)
    return sys


def mec_loop(
    plant=None, linearizer=None, controller=None, *, K="frit", nominal=None, h0=(0.0, 0.0),
    Ts=sc.TS_PAPER, continuous_plant=False, name="mec_loop",
):
    """Fig. 3 / Fig. 4: the linearized loop with a model error compensator.

    ``mu_n = F (r - h)`` drives the ideal model ``hn' = mu_n`` (erratum E3) and
    the compensator adds ``K (hn - h)``: ``mu = mu_n + K (hn - h)`` (eq. 13-15).
    The gain comes from a source block chosen by ``K``:

    - a number or 2x2 matrix: a :func:`~controlkit.blocks.mec.constant_gain` (Fig. 3);
    - ``"frit"``: the on-line FRIT tuner with the paper's settings (Fig. 4);
    - a block with outputs ``K[0]..K[3]`` (e.g. a :func:`~controlkit.blocks.frit.frit_tuner`
      with other settings, or your own tuner).

    For the loop without MEC use :func:`output_zeroing_loop`.

    Parameters
    ----------
    plant, linearizer : control.NonlinearIOSystem, optional
        As in :func:`linearized_plant`.
    controller : control.NonlinearIOSystem, optional
        Outer controller with output ``mu_n``, static or discrete at ``Ts``; default
        ``outer_controller(F=0.0009, output="mu_n")``. With ``K="frit"`` its attribute
        ``F`` is the ``F`` of the tuner's reference model ``M = F/(s+F)``; a controller
        without one gets the paper's ``F = 0.0009`` and a warning saying so.
    K : float, array_like, "frit" or control.NonlinearIOSystem
        The gain source (see above).
    nominal : control.NonlinearIOSystem, optional
        Ideal model; default :func:`~controlkit.blocks.mec.nominal_model` at ``Ts``.
    h0 : array_like
        Initial output, used by the default tuner (``K="frit"``).
    Ts : float
        Sampling period (s).
    continuous_plant : bool
        Keep the plant continuous behind a zero-order hold (a sampled-data diagram)
        instead of sampling it (see :func:`output_zeroing_loop`).
    name : str
        System name, and the title of its drawing: with the default name and the paper's
        blocks the drawing is titled as Fig. 3 or Fig. 4, otherwise ``name``.

    Returns
    -------
    control.InterconnectedSystem
        Discrete at ``Ts`` (sampled-data with ``continuous_plant``). Inputs ``r[0],
        r[1]``; outputs ``h[0], h[1], u[0], u[1],
        q[0]..q[3], mu[0], mu[1], mu_n[0], mu_n[1], hn[0], hn[1], K[0]..K[3]``.

    Raises
    ------
    ValueError
        A block of another period, or a continuous one (the message names it and says
        how to sample it, or to wire the diagram with :func:`controlkit.interconnect`);
        a gain source without the outputs ``K[0]..K[3]``.

    Examples
    --------
    >>> loop = mec_loop(K=0.1)
    >>> [s.name for s in loop.syslist]
    ['plant', 'output', 'nominal', 'gain', 'controller', 'mec', 'linearizer']
    """
    plant, linearizer, hold, make = _plant_side(plant, linearizer, Ts, continuous_plant,
                                                name)
    controller = controller if controller is not None else sc.outer_controller(output="mu_n")
    nominal = nominal if nominal is not None else mec.nominal_model(Ts)
    for block in (linearizer, controller, nominal):
        require_period(block, Ts, static_ok=True, loop=name)
    if isinstance(K, str):
        if K != "frit":
            raise ValueError(f'K must be a gain, "frit" or a gain-source block, got {K!r}')
        gain = frit.frit_tuner(_frit_filter_constant(controller), Ts, h0=h0)
    elif isinstance(K, ct.InputOutputSystem):
        gain = K
    else:
        gain = mec.constant_gain(K)
    if gain.output_labels != mec.K_SIGNALS:
        raise ValueError(f"the gain source must output {mec.K_SIGNALS}, got {gain.output_labels}")
    require_period(gain, Ts, static_ok=True, loop=name)
    compensator = mec.mec_compensator()
    MU_N, HN = ["mu_n[0]", "mu_n[1]"], ["hn[0]", "hn[1]"]

    #                    +-----------+ hn
    #           +------->|  nominal  |------------+
    #           |  mu_n  | hn' = mu_n|            v
    #     +------------+ +-----------+       +---------+  mu   +------------+  u
    # r ->| controller |-------------------->|   MEC   |------>| linearizer |----+
    #   +>| F (r - h)  |      mu_n           | mu_n +  |   |   |   eq. 11   |    |
    #   | +------------+    +-------------+K | K(hn-h) |   |   +------------+    |
    #   |                   | gain source |->|         |   |         ^ q         v
    #   |                   | const. (3)  |  +---------+   |   +-----------+ +-------------+
    #   |                   | FRIT (4)    |<-- mu, h, hn --+   | h(q) eq.9 |<| plant (ZOH) |
    #   |                   +-------------+                    +-----------+ +-------------+
    #   +------------------------------ h --------------------------+
    output = sc.attitude_output()
    sys = make(
        [plant, output, nominal, gain, controller, compensator,
         linearizer, *hold],
        inputs=R,
        outputs=H + U + Q + MU + MU_N + HN + mec.K_SIGNALS,
        name=name,
    )
    figure = ("fig4" if _is_papers(gain, "frit") else
              "fig3" if _is_papers(gain, "constant_gain") else None)
    if not all(_is_papers(b, role) for b, role in ((linearizer, "linearizer"),
                                                   (controller, "controller"),
                                                   (nominal, "nominal"))):
        figure = None
    sys.drawing_hints = _drawing_hints(name, "mec_loop", figure, plant, linearizer, output,
                                       nominal, gain)
    return sys


def _frit_filter_constant(controller):
    """The ``F`` of the FRIT tuner's reference model ``M = F / (s + F)``: the controller's.

    The tuner asks which ``K`` makes the loop look like ``F / (s + F)``, so ``F`` must be
    the outer loop's. A controller of the papers (:func:`~controlkit.blocks.spacecraft.
    outer_controller`) says its ``F``; for any other the paper's value is used, with a
    warning that names it and how to choose another.
    """
    if hasattr(controller, "F"):
        return controller.F
    warn_caller(
      f"mec_loop(K=\"frit\"): controller {controller.name!r} has no attribute F, so the "
      f"FRIT tuner's reference model M = F/(s+F) uses the paper's F = {sc.F_PAPER} 1/s; "
      f"for another, pass K=controlkit.blocks.frit.frit_tuner(F, Ts, h0=h0) or set "
      f"{controller.name}.F", UserWarning)
    return sc.F_PAPER
