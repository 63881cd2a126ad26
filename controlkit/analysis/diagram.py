"""A diagram read as blocks and wires, and its linearization composed from the blocks'.

:func:`flatten` turns any python-control system (an interconnect, nested or not, or a
single block) into its leaf blocks and four matrices read off python-control's public
``connect_map``, ``input_map`` and ``output_map``:

    u_b = W y_b + V u,        y = Y y_b + E u

(``y_b``, ``u_b``: every block's outputs and inputs stacked; ``u``, ``y``: the diagram's).
:func:`signals` solves that for the operating point as python-control does (sweeps of the
blocks' outputs until the inputs stop changing). With every block's Jacobians, the
linearization is linear algebra (:func:`compose` for one timebase,
:func:`compose_sampled` for a diagram of continuous and discrete blocks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import control as ct
import numpy as np
import scipy.linalg

from ..sampled_data import is_multiple


@dataclass
class Leaf:
    """One block of a flattened diagram, with its place in the stacked vectors.

    Examples
    --------
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], name="gain", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> leaf = flatten(loop, {}).leaves[1]
    >>> leaf.name, leaf.u, leaf.y, leaf.period
    ('gain', slice(1, 2, None), slice(1, 2, None), None)
    """

    system: ct.InputOutputSystem
    params: dict
    x: slice
    u: slice
    y: slice
    period: float | None  # None: continuous or static; a float: discrete

    @property
    def name(self) -> str:
        return self.system.name

    def call(self, which, t, x, u) -> np.ndarray:
        """The block's public ``output`` or ``dynamics`` with its parameters (an LTI block
        takes none: python-control warns when it is handed some)."""
        params = None if isinstance(self.system, ct.StateSpace) else self.params
        return np.asarray(getattr(self.system, which)(t, x, u, params), dtype=float).reshape(-1)


@dataclass
class Flat:
    """A diagram as leaf blocks and the matrices ``W, V, Y, E`` (module description).

    Examples
    --------
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], name="gain", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> flat = flatten(loop, {})
    >>> flat.labels  # every block's output
    ['plant.y', 'gain.u', 'error.e']
    >>> flat.W.tolist()  # inputs u (plant), e (gain), r and y (junction) from the outputs
    [[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]
    >>> flat.V.ravel().tolist()  # and from the diagram's input r
    [0.0, 0.0, 1.0, 0.0]
    """

    leaves: list
    W: np.ndarray
    V: np.ndarray
    Y: np.ndarray
    E: np.ndarray
    labels: list = field(default_factory=list)  # every leaf output, "block.signal"

    @property
    def nstates(self) -> int:
        return sum(leaf.system.nstates for leaf in self.leaves)

    def discrete(self) -> list:
        return [leaf for leaf in self.leaves if leaf.period is not None]

    def sampled_data(self) -> bool:
        """Whether continuous dynamics meet discrete blocks, or discrete blocks of two rates."""
        periods = {round(leaf.period, 12) for leaf in self.discrete()
                   if not math.isnan(leaf.period)}  # dt=True joins any one rate
        moving = any(leaf.system.isctime(strict=True) and leaf.system.nstates
                     for leaf in self.leaves)
        return bool(periods) and (moving or len(periods) > 1)


def flatten(sys, params) -> Flat:
    """The leaf blocks of ``sys`` and the matrices that wire them.

    Parameters are merged as python-control merges them when it runs an interconnect:
    a block sees its own, overridden by its diagram's, overridden by ``params``.

    Examples
    --------
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], name="gain", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> [leaf.name for leaf in flatten(loop, {}).leaves]
    ['plant', 'gain', 'error']
    """
    leaves: list[Leaf] = []
    W, V, Y, E = _flatten(sys, dict(params), leaves, [0, 0, 0])
    labels = [f"{leaf.name}.{s}" for leaf in leaves for s in leaf.system.output_labels]
    return Flat(leaves, W, V, Y, E, labels)


def _flatten(sys, params, leaves, offsets):
    if not isinstance(sys, ct.InterconnectedSystem):  # an all-LTI diagram too is read wire by wire
        nx, nu, ny = offsets
        period = None
        if sys.isdtime(strict=True):
            period = float(sys.dt) if sys.dt is not True else math.nan
        leaves.append(Leaf(sys, {**sys.params, **params}, slice(nx, nx + sys.nstates),
                           slice(nu, nu + sys.ninputs), slice(ny, ny + sys.noutputs), period))
        offsets[:] = [nx + sys.nstates, nu + sys.ninputs, ny + sys.noutputs]
        return (np.zeros((sys.ninputs, sys.noutputs)), np.eye(sys.ninputs),
                np.eye(sys.noutputs), np.zeros((sys.noutputs, sys.ninputs)))
    parts = [_flatten(sub, {**sub.params, **sys.params, **params}, leaves, offsets)
             for sub in sys.syslist]
    Wb, Vb, Ob, Eb = (scipy.linalg.block_diag(*(p[i] for p in parts)) for i in range(4))
    nsub_y = sys.connect_map.shape[1]
    # sub_u = M sub_y + N u with sub_y = Ob y_b + Eb sub_u (a sub-diagram may pass an input
    # straight through): sub_u = P y_b + R u
    lhs = np.eye(Eb.shape[1]) - sys.connect_map @ Eb
    P = np.linalg.solve(lhs, sys.connect_map @ Ob)
    R = np.linalg.solve(lhs, sys.input_map)
    out_y, out_u = sys.output_map[:, :nsub_y], sys.output_map[:, nsub_y:]
    W = Wb + Vb @ P
    V = Vb @ R
    Y = out_y @ Ob + (out_y @ Eb + out_u) @ P
    E = (out_y @ Eb + out_u) @ R
    return W, V, Y, E


def base_and_frame(flat) -> tuple[float, int, dict]:
    """The shortest period, the frame (base periods until every block fires together) and
    how often each discrete leaf fires (in base periods), for a sampled-data diagram.

    Examples
    --------
    >>> fast = ct.ss([], [], [], [[1.0]], dt=0.1, name="fast", inputs="y", outputs="v")
    >>> slow = ct.ss(0.5, 1.0, 1.0, 0.0, dt=0.3, name="slow", inputs="v", outputs="u")
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> from controlkit import interconnect
    >>> base, frame, _ = base_and_frame(flatten(interconnect([plant, fast, slow]), {}))
    >>> base, frame
    (0.1, 3)
    """
    periods = [leaf.period for leaf in flat.discrete()]
    if any(math.isnan(p) for p in periods):
        names = [leaf.name for leaf in flat.discrete() if math.isnan(leaf.period)]
        raise ValueError(f"blocks {names} are discrete with no sampling period (dt=True) "
                         f"beside continuous blocks or blocks of other periods")
    base = min(periods)
    every = {}
    for leaf in flat.discrete():
        ratio = leaf.period / base
        if not is_multiple(leaf.period, base):
            raise ValueError(f"the sampling periods must be integer multiples of the "
                             f"shortest ({base:g} s); block {leaf.name!r} runs at "
                             f"{leaf.period:g} s")
        every[id(leaf)] = round(ratio)
    return base, math.lcm(*every.values()), every


def signals(flat, t, x, u):
    """Every block's inputs and outputs at ``(t, x, u)``, as python-control finds them:
    sweeps of the blocks' outputs from zero until the inputs stop changing.

    Examples
    --------
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], name="gain", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> u_b, y_b = signals(flatten(loop, {}), 0.0, np.array([0.5]), np.array([1.0]))
    >>> y_b.tolist()  # y, u = 2 e, e = r - y
    [0.5, 1.0, 0.5]
    """
    u_b = flat.V @ u
    y_b = np.zeros(flat.W.shape[1])
    for _ in range(len(flat.leaves) + 1):
        for leaf in flat.leaves:
            y_b[leaf.y] = leaf.call("output", t, x[leaf.x], u_b[leaf.u])
        new = flat.W @ y_b + flat.V @ u
        if np.array_equal(new, u_b):
            return u_b, y_b
        u_b = new
    raise RuntimeError("algebraic loop detected: the blocks' outputs do not settle at the "
                       "operating point")


@dataclass
class Jacobians:
    """Every leaf's Jacobians placed in the stacked vectors: ``x_b' = A x + B u_b``,
    ``y_b = C x + D u_b``, and how each block was differentiated (:func:`stack`).

    Examples
    --------
    >>> Jacobians(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), np.eye(1),
    ...           {"gain": "linear"}).methods
    {'gain': 'linear'}
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    methods: dict


def stack(flat, blocks) -> Jacobians:
    """Place each leaf's ``(A, B, C, D, method)`` of ``blocks`` (in leaf order).

    Examples
    --------
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], name="gain", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> flat = flatten(loop, {})
    >>> jac = stack(flat, [(*(np.atleast_2d(m) for m in (leaf.system.A, leaf.system.B,
    ...                     leaf.system.C, leaf.system.D)), "linear") for leaf in flat.leaves])
    >>> jac.D.tolist()  # rows: outputs y, u, e; columns: inputs u, e, r, y
    [[0.0, 0.0, 0.0, 0.0], [0.0, 2.0, 0.0, 0.0], [0.0, 0.0, 1.0, -1.0]]
    """
    n, nu, ny = flat.nstates, flat.W.shape[0], flat.W.shape[1]
    A, B, C, D = np.zeros((n, n)), np.zeros((n, nu)), np.zeros((ny, n)), np.zeros((ny, nu))
    methods = {}
    for leaf, (a, b, c, d, how) in zip(flat.leaves, blocks, strict=True):
        A[leaf.x, leaf.x], B[leaf.x, leaf.u] = a, b
        C[leaf.y, leaf.x], D[leaf.y, leaf.u] = c, d
        methods[leaf.name] = how
    return Jacobians(A, B, C, D, methods)


def _solve(lhs, rhs, what):
    try:
        return np.linalg.solve(lhs, rhs)
    except np.linalg.LinAlgError:
        raise ValueError(f"the diagram's algebraic loop has no unique solution near the "
                         f"operating point ({what}): its linearization is not defined "
                         f"there") from None


def compose(flat, jac, wiring=None):
    """``(A, B, C, D)`` of a diagram of one timebase from its blocks' Jacobians.

    ``y_b = C x + D (W y_b + V u)`` gives ``y_b``; then ``u_b`` and ``x' = A x + B u_b``.
    ``wiring`` replaces ``(W, V, Y, E)`` (a loop cut open, :mod:`controlkit.analysis.loops`).

    Examples
    --------
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[2.0]], name="gain", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, gain, error], inputs="r", outputs="y")
    >>> from controlkit.analysis.linearize import jacobians_at
    >>> flat, jac = jacobians_at(loop, np.zeros(1), np.zeros(1), 0.0, None, None)
    >>> [m.tolist() for m in compose(flat, jac)]  # x' = -x + 2 (r - x)
    [[[-3.0]], [[2.0]], [[1.0]], [[0.0]]]
    """
    W, V, Y, E = wiring or (flat.W, flat.V, flat.Y, flat.E)
    lhs = np.eye(W.shape[1]) - jac.D @ W
    Yx, Yu = (_solve(lhs, rhs, "the outputs") for rhs in (jac.C, jac.D @ V))
    return (jac.A + jac.B @ W @ Yx, jac.B @ (W @ Yu + V), Y @ Yx, Y @ Yu + E)


def compose_sampled(flat, jac, wiring=None):
    """``(A, B, C, D, period)`` of a sampled-data diagram, exact at its instants.

    Over one frame (the base periods until every discrete block fires together), in
    terms of ``z = (x, u)`` at the frame's start, ``u`` held over the frame:

    1. at each base instant, the signals with the firing discrete blocks' outputs fresh
       and the others held; the firing blocks' held outputs are renewed and their states
       updated, ``x_d <- A_d x_d + B_d u_d``;
    2. between instants, the continuous blocks integrate ``x_c' = A_c x_c + G z`` with the
       discrete outputs held: ``exp([[A_c, G], [0, 0]] h)`` gives both ``x_c`` and its
       forcing over the base period ``h`` (the zero-order-hold discretisation of
       :func:`control.sample_system`).

    The outputs are those at the frame's first instant. With one rate the frame is the
    base period.

    Examples
    --------
    >>> from controlkit import interconnect
    >>> from controlkit.analysis.linearize import jacobians_at
    >>> plant = ct.ss(0.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[-2.0]], dt=0.25, name="gain", inputs="y", outputs="u")
    >>> flat, jac = jacobians_at(interconnect([plant, gain], inputs=[], outputs="y"),
    ...                          np.zeros(1), np.zeros(0), 0.0, None, None)
    >>> A, B, C, D, period = compose_sampled(flat, jac)
    >>> A.tolist(), period  # x[k+1] = x[k] - 0.25 * 2 x[k]
    ([[0.5]], 0.25)
    """
    W, V, Y, E = wiring or (flat.W, flat.V, flat.Y, flat.E)
    base, frame, every = base_and_frame(flat)
    n, m = flat.nstates, V.shape[1]
    ny = W.shape[1]
    lift = np.hstack([np.zeros((m, n)), np.eye(m)])
    X = np.hstack([np.eye(n), np.zeros((n, m))])
    held = np.zeros((ny, n + m))
    discrete_rows = np.zeros(ny, dtype=bool)
    moving = np.zeros(n, dtype=bool)
    for leaf in flat.leaves:
        if leaf.period is not None:
            discrete_rows[leaf.y] = True
        elif leaf.system.nstates:
            moving[leaf.x] = True
    continuous_rows = ~discrete_rows
    for k in range(frame):
        firing = [leaf for leaf in flat.discrete() if k % every[id(leaf)] == 0]
        fresh = continuous_rows.copy()
        for leaf in firing:
            fresh[leaf.y] = True
        y_z = _signals_linear(jac, W, V @ lift, X, held, fresh)
        if k == 0:
            C_D = Y @ y_z + E @ lift
        U = W @ y_z + V @ lift
        held = np.where(fresh[:, None] & discrete_rows[:, None], y_z, held)
        for leaf in firing:
            X[leaf.x] = jac.A[leaf.x, leaf.x] @ X[leaf.x] + jac.B[leaf.x] @ U
        if moving.any():
            # between instants: continuous and static blocks live, discrete outputs held
            Yc = np.eye(n)[moving]  # x_c's rows of x
            lhs = np.eye(ny) - np.diag(continuous_rows.astype(float)) @ jac.D @ W
            gain = _solve(lhs, np.diag(continuous_rows.astype(float)) @ jac.C[:, moving],
                          "between instants")
            forcing = _solve(lhs, np.diag(continuous_rows.astype(float)) @ jac.D @ V @ lift
                             + held, "between instants")
            A_c = Yc @ jac.A[:, moving] + Yc @ jac.B @ W @ gain
            G = Yc @ jac.B @ (W @ forcing + V @ lift)
            nc = A_c.shape[0]
            M = np.zeros((nc + n + m, nc + n + m))
            M[:nc, :nc], M[:nc, nc:] = A_c, G
            step = scipy.linalg.expm(M * base)
            X[moving] = step[:nc, :nc] @ X[moving] + step[:nc, nc:]
    return X[:, :n], X[:, n:], C_D[:, :n], C_D[:, n:], base * frame


def _signals_linear(jac, W, Vz, X, held, fresh):
    """``y_b`` in terms of ``z``: fresh rows ``C x + D u_b``, the others held."""
    F = np.diag(fresh.astype(float))
    lhs = np.eye(W.shape[1]) - F @ jac.D @ W
    return _solve(lhs, F @ (jac.C @ X + jac.D @ Vz) + (np.eye(W.shape[1]) - F) @ held,
                  "at an instant")
