"""Diagrams that mix continuous and discrete blocks: :func:`interconnect`.

python-control refuses to connect a continuous block (``dt = 0``) with a discrete one
(``dt = Ts``): "Systems have incompatible timebases" (its issue #451). Yet the loop every
digital-control course is about is exactly that, a continuous plant under a sampled
controller. :func:`interconnect` takes :func:`control.interconnect`'s arguments; when all
blocks share one timebase it returns what python-control returns, and otherwise a
:class:`SampledDataSystem`, which :func:`controlkit.input_output_response` simulates with
the semantics of Simulink and of the digital-control textbooks (Franklin, Powell &
Workman, *Digital Control of Dynamic Systems*, ch. 4; Astrom & Wittenmark,
*Computer-Controlled Systems*, ch. 2):

- a discrete block updates at its own sample instants ``k Ts`` and holds its output in
  between (zero-order hold); it reads the signals it is fed at the instant;
- continuous blocks are integrated between instants, the integrator stopping exactly at
  each, with the discrete outputs held;
- static blocks (``dt = None``) are evaluated wherever their inputs are;
- the rates are integer multiples of the shortest one.
"""

from __future__ import annotations

import functools
import inspect
import math
import warnings

import control as ct
import numpy as np

#: Relative tolerance when a rate is checked to be an integer multiple of the shortest.
RATE_TOLERANCE = 1e-9


class SampledDataSystem(ct.InterconnectedSystem):
    """An interconnect of continuous, discrete and static blocks (see :func:`interconnect`).

    It is an ordinary :class:`control.InterconnectedSystem` with ``dt = 0`` (its
    signals live in continuous time), built by python-control's own signal matching, so
    it draws and lists its signals and states like any diagram. What python-control
    cannot do with it is simulate it: its right-hand side would integrate a discrete
    block's next state as if it were a derivative, so :meth:`_rhs` and :meth:`_out`
    refuse, naming the remedy. For the same reason it cannot be simulated nested in a
    larger interconnect: build the larger diagram from its blocks (``syslist``) instead.

    Attributes
    ----------
    rates : dict
        Block name to its sampling period, for the discrete blocks (of blocks sharing a
        name, the last one's).
    base_period : float
        The shortest period: every instant of every discrete block is a multiple of it.

    Examples
    --------
    >>> plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    >>> pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi",
    ...                       inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = interconnect([plant, pi, error], inputs="r", outputs="y")
    >>> type(loop).__name__, loop.dt, loop.rates, loop.base_period
    ('SampledDataSystem', 0, {'pi': 0.1}, 0.1)
    """

    rates: dict
    base_period: float

    def _refuse(self):
        continuous = [s.name for s in self.syslist if s.isctime(strict=True) and s.nstates]
        raise ValueError(
            f"{self.name!r} is a sampled-data diagram (continuous blocks {continuous}, "
            f"discrete blocks {self.rates}): python-control cannot simulate it, nor an "
            f"interconnect it is nested in; controlkit.input_output_response simulates it, "
            f"and a larger diagram built by controlkit.interconnect from its blocks "
            f"({self.name}.syslist) and the others")

    def _rhs(self, t, x, u):
        self._refuse()

    def _out(self, t, x, u):
        self._refuse()


def interconnect(syslist, connections=None, inplist=None, outlist=None, *args, **kwargs):
    """:func:`control.interconnect`, also for blocks of different timebases.

    Takes exactly :func:`control.interconnect`'s arguments. When every block shares one
    timebase (python-control's rules: ``dt = None`` joins anything) the result is
    :func:`control.interconnect`'s. Otherwise continuous blocks (``dt = 0``), discrete
    blocks (``dt = Ts``, several rates allowed when each is an integer multiple of the
    shortest) and static blocks make a :class:`SampledDataSystem`; see the module's
    description for how it is simulated.

    Parameters
    ----------
    syslist, connections, inplist, outlist, *args, **kwargs
        As for :func:`control.interconnect` (its later parameters, ``params``,
        ``check_unused``..., by position too).

    Returns
    -------
    control.InputOutputSystem
        :func:`control.interconnect`'s result, or a :class:`SampledDataSystem`.

    Raises
    ------
    ValueError
        Rates that are not integer multiples of the shortest, or a discrete block of
        unspecified period (``dt = True``) beside a continuous one, naming the blocks.

    Examples
    --------
    A continuous plant under a PI controller sampled at 0.1 s:

    >>> plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    >>> pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi",
    ...                       inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> interconnect([plant, pi, error], inputs="r", outputs="y").rates
    {'pi': 0.1}

    Blocks at 0.1 s and 0.25 s cannot share instants:

    >>> slow = ct.sample_system(ct.tf([1.0], [1.0, 1.0]), 0.25, name="filter",
    ...                         inputs="y", outputs="yf")
    >>> try:
    ...     interconnect([plant, pi, error, slow], inputs="r", outputs="yf")
    ... except ValueError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    the sampling periods must be integer multiples of the shortest (0.1 s of 'pi'); got
    'filter' at 0.25 s
    """
    if args:  # (python-control's later parameters given by position: params, ...)
        bound = inspect.signature(ct.interconnect).bind(
            syslist, connections, inplist, outlist, *args, **kwargs).arguments
        kwargs = {**{name: bound[name] for name in list(bound)[4:] if name != "kwargs"},
                  **bound.get("kwargs", {})}
    systems = list(syslist)
    periods = _periods(systems)
    if periods is None:  # one timebase: python-control's own result
        return ct.interconnect(systems, connections, inplist, outlist, **kwargs)
    if kwargs.get("dt") not in (None, 0):
        raise ValueError(f"dt must be None or 0 for a diagram of blocks of several "
                         f"timebases (continuous and discrete, or several sampling "
                         f"periods), got dt={kwargs['dt']!r}")
    kwargs.pop("dt", None)
    # as python-control does: a transfer function joins a diagram as its state space
    systems = [ct.ss(s, name=s.name) if isinstance(s, ct.TransferFunction) else s
               for s in systems]
    # python-control's own signal matching, on stand-ins of the blocks that share one
    # timebase (it refuses mixed ones); the diagram is then built of the blocks themselves
    # (one stand-in per block object: a block listed twice is python-control's copy)
    stand_ins = {id(s): _stand_in(s) for s in systems}
    matched = ct.interconnect([stand_ins[id(s)] for s in systems], connections, inplist,
                              outlist, **kwargs)
    systems = [s if s.name == twin.name else s.copy(name=twin.name)  # a block used twice
               for s, twin in zip(systems, matched.syslist, strict=True)]
    with warnings.catch_warnings():  # (python-control said it of the build just made)
        warnings.filterwarnings("ignore", "duplicate (object|name) found")
        sys = SampledDataSystem(matched.syslist, params=matched.params, name=matched.name,
                                inputs=matched.input_labels, outputs=matched.output_labels,
                                states=matched.state_labels, dt=0,
                                connection_type=matched.connection_type)
    sys.set_input_map(matched.input_map)
    sys.set_output_map(matched.output_map)
    sys.set_connect_map(matched.connect_map)
    sys.syslist = systems
    sys.rates = dict(periods)
    # (of the blocks, not of the names: two blocks may share one, at other rates)
    sys.base_period = min(period for _, period in periods)
    return sys


def _stand_in(block):
    """A block of the same name, signals, states and parameters in continuous time, for
    python-control to match signals on (it is never simulated)."""
    return ct.nlsys(_never, _never, inputs=block.input_labels, outputs=block.output_labels,
                    states=block.state_labels, name=block.name,
                    params=getattr(block, "params", {}), dt=0)


def _never(t, x, u, params):
    raise RuntimeError("a stand-in of controlkit.interconnect is never simulated")


def _periods(systems):
    """None when ``systems`` share a timebase; else checks the rates of a mixed diagram and
    gives ``(name, period)`` of each discrete block, in order."""
    try:  # python-control's own rule of one timebase (periods np.isclose, say)
        functools.reduce(ct.common_timebase, systems, None)
        return None
    except ValueError:
        pass
    discrete = [s for s in systems if s.dt is not None and s.dt is not True and s.dt != 0]
    unspecified = [s for s in systems if s.dt is True]
    if unspecified:
        names = [s.name for s in unspecified]
        raise ValueError(f"blocks {names} are discrete with no sampling period (dt=True); "
                         f"give them their period (dt=Ts) to join continuous blocks or "
                         f"blocks of other periods")
    shortest = min(discrete, key=lambda s: s.dt)
    off = [s for s in discrete if not is_multiple(s.dt, shortest.dt)]
    if off:
        listed = ", ".join(f"{s.name!r} at {float(s.dt)!r} s" for s in off)
        raise ValueError(f"the sampling periods must be integer multiples of the shortest "
                         f"({float(shortest.dt)!r} s of {shortest.name!r}); got {listed}")
    return [(s.name, float(s.dt)) for s in discrete]


def is_multiple(period, base) -> bool:
    """Whether ``period`` is an integer multiple of ``base``, to :data:`RATE_TOLERANCE`
    (the one rule of the rates, here and in :mod:`controlkit.analysis`).

    Examples
    --------
    >>> is_multiple(0.3, 0.1), is_multiple(0.25, 0.1)
    (True, False)
    """
    ratio = period / base
    return abs(ratio - round(ratio)) <= RATE_TOLERANCE * max(1.0, ratio)


def sample_instants(sys, T0, Tf):
    """The instants ``T0 + k base_period`` up to ``Tf`` of a :class:`SampledDataSystem`.

    Examples
    --------
    >>> plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], dt=0.5, name="k", inputs="y", outputs="u")
    >>> sample_instants(interconnect([plant, gain]), 0.0, 1.2).tolist()
    [0.0, 0.5, 1.0]
    """
    return sample_times(sys.base_period, T0, Tf)


def sample_times(base_period, T0, Tf):
    """The discrete instants ``T0 + k h`` up to ``Tf`` (``[T0]`` when ``h`` is 0).

    Examples
    --------
    >>> sample_times(0.5, 0.0, 1.2).tolist(), sample_times(0.0, 0.0, 5.0).tolist()
    ([0.0, 0.5, 1.0], [0.0])
    """
    h = float(base_period or 0.0)
    if not h:
        return np.array([float(T0)])
    count = math.floor((Tf - T0) / h * (1 + 1e-12)) + 1
    return T0 + np.arange(count) * h
