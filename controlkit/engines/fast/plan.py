"""A diagram reduced to numbers (a row per block), which the code generator writes out.

:func:`make_plan` takes the blocks of a diagram (their kernels and offsets, from
:func:`.tiers.blocks_of`) and its evaluation order, and describes each block as numbers:
a :class:`TableRow` (offsets into the stacked state ``x``, the stacked block inputs ``ui``
and outputs ``ys`` and the parameters ``P``, its kernels, its kind and rate). Nothing in
a plan is compiled: :mod:`.codegen` writes it, with the interconnect's maps, into source.

A block is one of four kinds (:data:`KINDS`), by its timebase:

- ``static``: no state of its own in time (``dt = None``, or a continuous block with no
  state): evaluated wherever its inputs are;
- ``discrete``: ``dt = Ts``; it computes its output and updates its state at its
  instants, every :attr:`every` base periods, and holds its output in between;
- ``sampled``: a continuous block under zero-order hold
  (:func:`controlkit.blocks.sampling.sample_nlsys` with RK4): a discrete block whose
  update is ``substeps`` RK4 steps of its right-hand side;
- ``continuous``: ``dt = 0`` with states: integrated between instants.
"""

from __future__ import annotations

import functools
from collections import namedtuple
from dataclasses import dataclass

import numpy as np

from ... import _jit
from ..contract import UnsupportedSystem

#: Block kinds, by number in the plan's table.
KINDS = ("static", "discrete", "sampled", "continuous")
STATIC, DISCRETE, SAMPLED, CONTINUOUS = range(4)

#: Columns of :attr:`Plan.rows`: offsets and sizes in x, ui, ys and P; feedthrough;
#: output and update kernel (index into :attr:`Plan.kernels`, -1 for none); kind;
#: instants between firings (discrete and sampled blocks); RK4 substeps and their length
#: (sampled).
COLUMNS = ("X0", "NX", "U0", "NU", "Y0", "NY", "P0", "NP", "FT", "OUT", "UPD", "KIND",
           "EVERY", "SUB", "H")


class TableRow(namedtuple("TableRow", COLUMNS)):
    """One block of :attr:`Plan.rows` by column name (``row.X0``).

    Examples
    --------
    >>> row = TableRow(*range(len(COLUMNS)))
    >>> row.X0, row.KIND, row.SUB
    (0, 11, 13)
    """

    __slots__ = ()


@dataclass
class Plan:
    """A diagram as arrays (see the module's description).

    Attributes
    ----------
    sys : control.InterconnectedSystem
        The diagram.
    blocks : list
        Its blocks with their kernels (:class:`.tiers.PlacedBlock`).
    order : list of int
        Block indices in evaluation order (outputs that read only their state first).
    rows : list of TableRow
        One per block, columns :data:`COLUMNS`.
    kernels : list
        The distinct kernel functions, indexed by the rows' ``OUT`` and ``UPD``.
    continuous : numpy.ndarray
        Indices in ``x`` of the states that are integrated in continuous time.
    ny, nu : int
        Sizes of ``ys`` and ``ui``.

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> plan = prepare(cmg_loop()).plan
    >>> [KINDS[row.KIND] for row in plan.rows]
    ['static', 'sampled', 'discrete', 'static']
    """

    sys: object
    blocks: list
    order: list
    rows: list
    kernels: list
    continuous: np.ndarray
    ny: int
    nu: int

    @property
    def held(self) -> bool:
        """Whether discrete blocks hold their outputs between their instants (a sampled-data
        diagram: of several rates, or of continuous and discrete blocks), which
        python-control's own evaluation of a diagram cannot do."""
        from ...sampled_data import SampledDataSystem

        return isinstance(self.sys, SampledDataSystem)

    @functools.cached_property
    def controlkit_s_own(self) -> set[int]:
        """The indexes of the kernels that are controlkit's own (NaN in, NaN out, never an
        error); the others are the user's, which may raise as Python where their compiled
        form gives inf or NaN (what :func:`.codegen.kernel_identity` names by a dotted
        name under ``controlkit.kernels``)."""
        own = set()
        for i, fn in enumerate(self.kernels):
            module = str(getattr(_jit.python_function(fn), "__module__", None))
            if not isinstance(getattr(fn, "identity", None), str) and (
                    f"{module}.".startswith("controlkit.kernels.")):
                own.add(i)
        return own

    @property
    def calls_users(self) -> bool:
        """Whether a kernel is the user's (not :attr:`controlkit_s_own`): its compiled form
        may give inf or NaN, or raise, where Python raises."""
        return len(self.controlkit_s_own) < len(self.kernels)

    @functools.cached_property
    def inputs_exact(self) -> list[bool]:
        """Whether each block input written out as the sum of its terms is python-control's
        ``connect_map @ outputs + input_map @ u`` to the bit: both parts :func:`exact_sum`,
        and the second one term at most when the first has any (so that the parts are
        added last, as python-control adds them)."""
        nonzero = np.count_nonzero
        return [bool(exact_sum(c) and exact_sum(i) and (nonzero(i) <= 1 or not nonzero(c)))
                for c, i in zip(np.asarray(self.sys.connect_map, dtype=float),
                                np.asarray(self.sys.input_map, dtype=float), strict=True)]

    @functools.cached_property
    def outputs_exact(self) -> list[bool]:
        """:func:`exact_sum` of each row of the output map: which outputs are written out."""
        return [exact_sum(row) for row in np.atleast_2d(np.asarray(self.sys.output_map,
                                                                    dtype=float))]

    def parameters(self) -> np.ndarray:
        """The stacked parameter vector ``P`` (each block's packed ``p``, in order)."""
        return np.concatenate([b.kernel.params for b in self.blocks] + [np.zeros(0)])


def evaluation_order(sys, blocks):
    """State-only outputs first, then feedthrough blocks in dependency order.

    Raises
    ------
    UnsupportedSystem
        Naming the blocks of an algebraic loop.

    Examples
    --------
    >>> from controlkit.engines.fast.tiers import blocks_of
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> loop = cmg_loop()
    >>> [loop.syslist[i].name for i in evaluation_order(loop, blocks_of(loop))]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    owner = np.empty(sum(b.system.noutputs for b in blocks), dtype=int)
    for b in blocks:
        owner[b.y0:b.y0 + b.system.noutputs] = b.index
    needs = {}
    for b in blocks:
        rows = sys.connect_map[b.u0:b.u0 + b.system.ninputs]
        needs[b.index] = {int(owner[j]) for j in np.nonzero(rows.any(axis=0))[0]}
    order = [b.index for b in blocks if not b.kernel.feedthrough]
    done = set(order)
    pending = [b.index for b in blocks if b.kernel.feedthrough]
    while pending:
        ready = [i for i in pending if needs[i] <= done]
        if not ready:
            names = [sys.syslist[i].name for i in pending]
            raise UnsupportedSystem(f"algebraic loop through blocks {names}")
        for i in ready:
            order.append(i)
            done.add(i)
            pending.remove(i)
    return order


def exact_sum(coefficients) -> bool:
    """Whether ``coefficients @ v`` summed term by term from 0.0 is numpy's to the bit for
    any ``v``, whatever order its BLAS sums a row in and whichever products it fuses
    (``fma``): one nonzero term, or two exact ones (of magnitude 1, as a junction's).

    Examples
    --------
    >>> [exact_sum(np.array(c)) for c in ([0.0, 2.5], [1.0, -1.0], [0.5, 0.25])]
    [True, True, False]
    """
    nonzero = coefficients[coefficients != 0.0]
    return nonzero.size <= 1 or nonzero.size == 2 and bool(np.all(np.abs(nonzero) == 1.0))


def _kind(block, kernel, diagram_dt) -> int:
    """A block's kind; one of unspecified timebase (``dt = None``) with states takes the
    diagram's, as python-control does (integrated in a continuous diagram)."""
    system = block.system
    dt = diagram_dt if system.dt is None and system.nstates else system.dt
    if kernel.rk4 is not None:
        return SAMPLED
    if dt is True or (dt is not None and dt > 0):
        return DISCRETE
    if (dt == 0 or dt is None) and system.nstates and kernel.update is not None:
        return CONTINUOUS
    return STATIC


def make_plan(sys, blocks, order) -> Plan:
    """The :class:`Plan` of ``sys`` with ``blocks`` (from :func:`.tiers.blocks_of`).

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.tiers import blocks_of
    >>> gain = ct.ss([], [], [], [[2.0]], name="k", inputs="e", outputs="u")
    >>> plant = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], name="p", inputs="u",
    ...               outputs="y")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> blocks = blocks_of(loop)
    >>> plan = make_plan(loop, blocks, evaluation_order(loop, blocks))
    >>> plan.continuous.tolist(), plan.inputs_exact
    ([0], [True, True, True, True])
    """
    base = float(getattr(sys, "base_period", 0.0) or 0.0)
    if not base and sys.isdtime(strict=True) and sys.dt is not True:
        base = float(sys.dt)
    kernels, index = [], {}

    def kernel_index(fn):
        if fn is None:
            return -1
        if id(fn) not in index:
            index[id(fn)] = len(kernels)
            kernels.append(fn)
        return index[id(fn)]

    rows, continuous = [], []
    for b in blocks:
        k, s = b.kernel, b.system
        kind = _kind(b, k, sys.dt)
        every = 0
        if kind in (DISCRETE, SAMPLED):
            timed = base and s.dt is not True and s.dt is not None
            every = max(1, round(float(s.dt) / base)) if timed else 1
        substeps, h = (k.rk4[1], float(k.rk4[0] / k.rk4[1])) if kind == SAMPLED else (0, 0.0)
        rows.append(TableRow(b.x0, s.nstates, b.u0, s.ninputs, b.y0, s.noutputs, b.p0,
                             int(k.params.size), int(k.feedthrough), kernel_index(k.output),
                             kernel_index(k.update if s.nstates else None), kind, every,
                             int(substeps), h))
        if kind == CONTINUOUS:
            continuous += range(b.x0, b.x0 + s.nstates)
    return Plan(sys=sys, blocks=blocks, order=[int(i) for i in order], rows=rows,
                kernels=kernels, continuous=np.array(continuous, dtype=np.int64),
                ny=sys.connect_map.shape[1], nu=sys.connect_map.shape[0])
