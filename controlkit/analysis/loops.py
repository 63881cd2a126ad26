"""A loop cut open at a signal: loop gain, sensitivity and complementary sensitivity.

:func:`loop_transfers` linearizes a closed loop at its operating point and cuts it at the
signals you name (the analysis point of MATLAB's ``getLoopTransfer``): every block that
read a cut signal now reads a new input of the same name, and the signal its block
produces becomes an output. With negative feedback as the convention, the loop gain is

    L = -(transfer from the injected signal back to the signal),

and at the same point ``S = (I + L)^-1`` (sensitivity: how a disturbance or a relative
model error at that point passes through the closed loop) and
``T = L (I + L)^-1 = I - S`` (complementary sensitivity). python-control's
:func:`~control.bode_plot`, :func:`~control.nyquist_plot` and
:func:`~control.stability_margins` take them as they are.
"""

from __future__ import annotations

from typing import NamedTuple

import control as ct
import numpy as np

from .diagram import compose, compose_sampled
from .linearize import _finite, _operating_point, _state_space_or_system, jacobians_at


class LoopTransfers(NamedTuple):
    """The loop gain ``L``, sensitivity ``S`` and complementary sensitivity ``T`` at a cut.

    Each is a :class:`control.StateSpace` whose inputs and outputs are the cut signals.

    Examples
    --------
    >>> plant = ct.tf([1], [1, 0], name="plant", inputs="u", outputs="y")
    >>> minus = ct.summing_junction(["r", "-y"], "u", name="error")
    >>> transfers = loop_transfers(ct.interconnect([plant, minus], inputs="r", outputs="y"),
    ...                            "u", 0.0)
    >>> transfers.T.input_labels, round(complex(transfers.T(0.0)).real, 12)
    (['u'], 1.0)
    """

    L: ct.StateSpace
    S: ct.StateSpace
    T: ct.StateSpace


def loop_transfers(sys, at, xeq, ueq=None, t=0, params=None, *, eps=None) -> LoopTransfers:
    """Loop gain, sensitivity and complementary sensitivity of ``sys`` cut open at ``at``.

    The loop is linearized at its operating point ``(xeq, ueq)`` as
    :func:`~controlkit.analysis.linearize` does (continuous, discrete or sampled-data: the
    injected signal is then held over each sample, which is what it is when it leaves a
    discrete block or a hold), then cut.

    Parameters
    ----------
    sys : control.InputOutputSystem
        A closed loop (any diagram :func:`controlkit.interconnect` builds).
    at : str or list of str
        The signals to cut: a block's output (``"u[0]"``), every entry of a vector
        (``"u"`` for ``u[0]``, ``u[1]``, ...), or ``"block.signal"`` when two blocks
        name an output alike. Several signals give a MIMO loop.
    xeq, ueq, t, params, eps
        The operating point and settings, as for :func:`~controlkit.analysis.linearize`.

    Returns
    -------
    LoopTransfers
        ``(L, S, T)``, with the same timebase as the linearization.

    Raises
    ------
    ValueError
        A signal that no block outputs, that two blocks output (name it
        ``"block.signal"``), or that no block reads (there is no loop to cut); an
        operating point of the wrong size.

    Examples
    --------
    An integrator under unit feedback: ``L = 1/s``, ``S = s/(s + 1)``.

    >>> plant = ct.tf([1], [1, 0], name="plant", inputs="u", outputs="y")
    >>> minus = ct.summing_junction(["r", "-y"], "u", name="error")
    >>> loop = ct.interconnect([plant, minus], inputs="r", outputs="y")
    >>> L, S, T = loop_transfers(loop, "u", 0.0)
    >>> complex(L(2j)), complex(S(2j)).real
    ((-0-0.5j), 0.8)
    """
    sys = _state_space_or_system(sys)
    x, u = _operating_point(sys, xeq, ueq)
    t = _finite("t", t)
    flat, jac = jacobians_at(sys, x, u, t, params, None if eps is None else _finite("eps", eps))
    columns, labels = _cut_signals(flat, at)
    W, V, Y, E = flat.W.copy(), flat.V, flat.Y, flat.E
    readers = W[:, columns].copy()
    W[:, columns] = 0.0
    k, m, p = len(columns), V.shape[1], Y.shape[0]
    V = np.hstack([V, readers])
    Y = np.vstack([Y, np.eye(W.shape[1])[columns]])
    E = np.block([[E, np.zeros((p, k))], [np.zeros((k, m + k))]])
    if flat.sampled_data():
        A, B, C, D, dt = compose_sampled(flat, jac, (W, V, Y, E))
    else:
        (A, B, C, D), dt = compose(flat, jac, (W, V, Y, E)), sys.dt
    B, C, D = B[:, m:], C[p:], D[p:, m:]
    names = dict(inputs=labels, outputs=labels, states=sys.state_labels)
    L = ct.StateSpace(A, -B, C, -D, dt, name=f"L at {', '.join(labels)}",
                      remove_useless_states=False, **names)
    # S = (I + L)^-1, T = I - S, both realised on L's states
    R = np.linalg.inv(np.eye(k) - D)  # (I + D_L)^-1 with D_L = -D
    A_s = A + B @ R @ C  # A - B_L R C_L with B_L = -B, C_L = C
    S = ct.StateSpace(A_s, -B @ R, -R @ C, R, dt, name=f"S at {', '.join(labels)}",
                      remove_useless_states=False, **names)
    T = ct.StateSpace(A_s, -B @ R, R @ C, np.eye(k) - R, dt,
                      name=f"T at {', '.join(labels)}", remove_useless_states=False, **names)
    return LoopTransfers(L, S, T)


def reduced(sys, *, inputs=None, outputs=None, tol=1e-12) -> ct.StateSpace:
    """The states of ``sys`` on a path from its inputs to its outputs, the others dropped.

    A state is kept when an input reaches it and it reaches an output through the
    nonzero entries of ``B``, ``A`` and ``C`` (entries below ``tol`` times the largest of
    their matrix count as zero). A dropped state is uncontrollable or unobservable, so
    the transfer function is the same: this is :func:`control.minreal` for the modes a
    diagram's wiring decouples (the spacecraft's rotation about the antenna axis, the
    quaternion's norm), which needs no slycot and no tolerance on pole-zero
    cancellations.

    Parameters
    ----------
    sys : control.StateSpace
    inputs, outputs : list of str, optional
        Keep only these inputs or outputs (labels), before the states are chosen.
    tol : float
        Relative threshold below which an entry is a zero of the wiring.

    Examples
    --------
    >>> sys = ct.ss([[1.0, 0.0], [0.0, -2.0]], [[1.0], [0.0]], [[1.0, 1.0]], 0.0)
    >>> reduced(sys).nstates
    1
    """
    inputs = sys.input_labels if inputs is None else list(inputs)
    outputs = sys.output_labels if outputs is None else list(outputs)
    for kind, chosen, known in (("inputs", inputs, sys.input_labels),
                                ("outputs", outputs, sys.output_labels)):
        unknown = [s for s in chosen if s not in known]
        if unknown:
            raise ValueError(f"{kind} {unknown} are not among {known}")
    iu = [sys.input_labels.index(s) for s in inputs]
    iy = [sys.output_labels.index(s) for s in outputs]
    A, B, C, D = sys.A, sys.B[:, iu], sys.C[iy], sys.D[np.ix_(iy, iu)]

    def links(M):
        return np.abs(M) > tol * max(np.abs(M).max(initial=0.0), np.finfo(float).tiny)

    edges = links(A)  # edges[i, j]: x_j drives x_i
    reached, seen = links(B).any(axis=1), links(C).any(axis=0)
    for _ in range(A.shape[0]):
        reached = reached | (edges[:, reached].any(axis=1))
        seen = seen | (edges[seen].any(axis=0))
    keep = np.flatnonzero(reached & seen)
    return ct.StateSpace(A[np.ix_(keep, keep)], B[keep], C[:, keep], D, sys.dt,
                         inputs=inputs, outputs=outputs,
                         states=[sys.state_labels[i] for i in keep], name=sys.name,
                         remove_useless_states=False)


def _cut_signals(flat, at):
    """The columns of ``y_b`` for the signals named in ``at``, and their labels."""
    names = [at] if isinstance(at, str) else list(at) if at is not None else []
    if not names or not all(isinstance(n, str) for n in names):
        raise ValueError(f"at must name one signal or several (e.g. 'u[0]' or ['u[0]', "
                         f"'u[1]']), got {at!r}")
    columns = []
    for name in names:
        found = [j for j, label in enumerate(flat.labels) if _matches(label, name)]
        if not found:
            shown = sorted({label.split(".", 1)[1] for label in flat.labels})
            raise ValueError(f"at: no block outputs a signal {name!r}; signals: {shown}")
        owners = {flat.labels[j].split(".", 1)[0] for j in found}
        if len(owners) > 1:
            raise ValueError(f"at: {name!r} is output by blocks {sorted(owners)}; name it "
                             f"'block.signal'")
        for j in found:
            if not flat.W[:, j].any():
                raise ValueError(f"at: no block reads {flat.labels[j]!r}, so there is no "
                                 f"loop to cut there")
        columns += [j for j in found if j not in columns]
    return columns, [flat.labels[j].split(".", 1)[1] for j in columns]


def _matches(label, name) -> bool:
    block, signal = label.split(".", 1)
    for candidate in (signal, label):
        if candidate == name or (candidate.startswith(name + "[") and "[" not in name):
            return True
    return False
