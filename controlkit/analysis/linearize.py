"""python-control's ``linearize`` and ``find_eqpt`` for every diagram
:func:`controlkit.interconnect` builds, continuous, discrete and sampled-data.

python-control's :func:`control.linearize` differentiates a whole interconnect by forward
differences with one step (``1e-6``) for every variable, and cannot run on a diagram that
mixes a continuous plant with a discrete controller (it refuses to build one).
:func:`linearize` takes its arguments and returns its result, a :class:`control.StateSpace`,
computed from each block's Jacobians (exact where they are known: LTI blocks and the
papers' blocks; central differences with a step chosen per variable otherwise, see
:mod:`controlkit.analysis.jacobians`) and the diagram's wiring. A sampled-data diagram
gives the discrete-time model that is exact at its sampling instants.
"""

from __future__ import annotations

import control as ct
import numpy as np

from .._checks import warn_caller
from .diagram import compose, compose_sampled, flatten, signals, stack
from .jacobians import block_jacobians


def linearize(sys, xeq, ueq=None, t=0, params=None, **kw):
    r"""Linearize a diagram at an operating point: :func:`control.linearize`, also for
    sampled-data diagrams.

    Continuous or discrete diagram: the :class:`control.StateSpace` of
    :func:`control.linearize` (``x' = A x + B u``, ``y = C x + D u`` in deviations from
    the operating point, or ``x[k+1] = A x[k] + B u[k]``), built from each block's
    Jacobians and the wiring: LTI blocks and controlkit's blocks of the papers exactly,
    other blocks by central differences with the step
    :math:`h_j = \epsilon^{1/3}\max(1, |z_j|)` per variable (relative error about
    ``1e-10`` for a function smooth on that scale; python-control's forward differences
    with ``1e-6`` reach about ``1e-6``). A function that bends on a finer scale
    (``tanh(x / 1e-5)``), or has a kink at the point (``abs(x)`` at 0, where central
    differences give the mean of the two slopes and python-control's the right one),
    needs a step of its own (``eps``): there the two methods give other numbers.

    Sampled-data diagram (:func:`controlkit.interconnect` of continuous and discrete
    blocks): the discrete-time model at the base period ``h`` that is exact at the
    sampling instants, with the discrete blocks' states among its own. At each instant
    the discrete blocks read their inputs, update and hold their outputs; in between, the
    continuous part, linearized at the operating point, is integrated exactly with the
    held signals and the diagram's inputs held (zero-order hold):

    .. math:: x_c[k+1] = e^{A_c h} x_c[k] + \int_0^h e^{A_c s}\,ds\; G\,z[k],

    computed as one matrix exponential of ``[[A_c, G], [0, 0]] h`` (what
    :func:`control.sample_system` does with ``method="zoh"``). For an LTI plant this is
    exact; for a nonlinear one it is exact for its linearization at the operating point.
    With blocks of several rates the model spans the frame (the shortest period times the
    number of periods until every block fires together), inputs held over the frame; its
    eigenvalues (Floquet multipliers) decide stability.

    Parameters
    ----------
    sys : control.InputOutputSystem
        A block or a diagram (:func:`control.interconnect`,
        :func:`controlkit.interconnect`, nested diagrams too).
    xeq : array_like or control.OperatingPoint
        The state at which to linearize (need not be an equilibrium); a scalar applies to
        every state; an :class:`~control.OperatingPoint` gives the state and the input.
    ueq : array_like, optional
        The input; default 0.
    t : float
        The time (for time-varying blocks).
    params : dict, optional
        Parameter values, as for :func:`control.linearize`.
    eps : float, optional
        A step for the central differences of every variable instead of the per-variable
        one.
    copy_names : bool
        Copy the signal and state names and the system name (with python-control's
        ``$linearized`` suffix), as :func:`control.linearize`.
    name, inputs, outputs, states
        As for :func:`control.linearize`.

    Returns
    -------
    control.StateSpace
        ``dt`` of the diagram (continuous, discrete), or the base period (sampled-data;
        the frame with several rates). Its attribute ``jacobian_methods`` maps each block
        to how it was differentiated: ``"linear"``, ``"exact"``, ``"rk4 (exact)"``,
        ``"variational (solve_ivp)"``, ``"central differences"``.

    Raises
    ------
    TypeError
        ``sys`` is not a python-control system.
    ValueError
        ``xeq``, ``ueq`` longer than the state or input, or not finite; ``t`` or ``eps``
        not finite (the message names the argument); a block that has no derivative at
        the operating point. A vector shorter than the state or input is padded with
        zeros, as python-control pads it (and warns when its last value is not zero).

    Examples
    --------
    A continuous integrator under a discrete gain of 0.8 at 0.5 s:
    ``x[k+1] = x[k] + 0.5 * 0.8 (r[k] - x[k])``.

    >>> import controlkit
    >>> plant = ct.ss(0, 1, 1, 0, name="plant", inputs="u", outputs="y")
    >>> gain = ct.ss([], [], [], [[0.8]], dt=0.5, name="k", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> lin = linearize(controlkit.interconnect([plant, gain, error], inputs="r",
    ...                                         outputs="y"), 0.0)
    >>> lin.A.tolist(), lin.B.tolist(), lin.dt
    ([[0.6]], [[0.4]], 0.5)
    """
    sys = _state_space_or_system(sys)
    if _sizes_unknown(sys):  # (python-control sizes it from the point: its own answer)
        return ct.linearize(sys, xeq, ueq, t, params, **kw)
    eps = kw.pop("eps", None)
    copy_names = kw.pop("copy_names", False)
    x, u = _operating_point(sys, xeq, ueq)
    t = _finite("t", t)
    if eps is not None:
        eps = _finite("eps", eps)
        if eps <= 0:
            raise ValueError(f"eps must be > 0 (a finite-difference step), got {eps!r}")
    if params is not None and not isinstance(params, dict):
        raise ValueError(f"params must be a dict of parameter values, got {params!r}")
    flat, jac = jacobians_at(sys, x, u, t, params, eps)
    if flat.sampled_data():
        A, B, C, D, dt = compose_sampled(flat, jac)
    else:
        (A, B, C, D), dt = compose(flat, jac), sys.dt
    try:
        linsys = ct.StateSpace(A, B, C, D, dt, remove_useless_states=False)
    except ValueError as error:
        if B.shape[1] or not B.shape[0]:
            raise
        raise ValueError(  # (as python-control's own linearize of it raises)
            f"{sys.name!r} has no inputs, and python-control {ct.__version__} cannot hold "
            f"this StateSpace without inputs ({error}); give the diagram an input, or cut a "
            f"loop open with controlkit.analysis.loop_transfers") from error
    if copy_names:
        prefix = ct.config.defaults["iosys.linearized_system_name_prefix"]
        suffix = ct.config.defaults["iosys.linearized_system_name_suffix"]
        linsys = ct.StateSpace(linsys, inputs=sys.input_labels, outputs=sys.output_labels,
                               states=sys.state_labels, name=f"{prefix}{sys.name}{suffix}")
    linsys = ct.StateSpace(linsys, **kw)
    linsys.jacobian_methods = jac.methods
    return linsys


def jacobians_at(sys, x, u, t, params, eps):
    """The flattened diagram and its blocks' stacked Jacobians at ``(t, x, u)``: the
    operating point's signals found, each block differentiated (its ``check_state``, if
    any, applied to its part of ``x`` first).

    Examples
    --------
    >>> from controlkit.studies.spacecraft.diagrams import output_zeroing_loop
    >>> loop = output_zeroing_loop()
    >>> flat, jac = jacobians_at(loop, np.array([1.0, 0, 0, 0]), np.zeros(2), 0.0, None,
    ...                          None)
    >>> jac.methods["plant"], jac.methods["linearizer"]
    ('rk4 (exact)', 'exact')
    """
    flat = flatten(sys, params or {})
    for leaf in flat.leaves:  # a block's own check of its state (a unit quaternion)
        check = getattr(leaf.system, "check_state", None)
        if check is not None:
            check(f"xeq of block {leaf.name!r}", x[leaf.x])
    u_b, _ = signals(flat, t, x, u)
    blocks = [block_jacobians(leaf.system, t, x[leaf.x], u_b[leaf.u], leaf.params, step=eps)
              for leaf in flat.leaves]
    return flat, stack(flat, blocks)


def _state_space_or_system(sys):
    """``sys`` as a system with states: a transfer function in its state-space form (as
    ``interconnect`` makes it); a frequency response, which has none, refused."""
    if isinstance(sys, ct.TransferFunction):
        return ct.ss(sys)
    if not isinstance(sys, ct.NonlinearIOSystem):
        raise TypeError(f"Can only linearize InputOutputSystem types with a state-space "
                        f"model, got {type(sys).__name__}")
    return sys


def _finite(name, value) -> float:
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite number, got {value!r}") from None
    if not np.isfinite(value):
        raise ValueError(f"{name} must be a finite number, got {value!r}")
    return value


def _vector(name, legacy, value, size, labels) -> np.ndarray:
    """A state or input vector read as python-control reads it: a scalar for every entry
    (a 0-d array is a vector of one), a list of numbers and arrays concatenated, a short
    vector padded with zeros (with python-control's warning when its last value is not
    zero); too long or not finite is refused."""
    scalar = np.isscalar(value)  # (python-control's test: a 0-d array is a vector)
    if isinstance(value, (list, tuple)):
        try:
            parts = [np.asarray(v, dtype=float).reshape(-1) for v in value]
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be numbers, got {value!r}") from None
        value = np.concatenate(parts) if parts else np.zeros(0)
    try:
        value = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers, got {value!r}") from None
    value = np.full(size, float(value)) if scalar else value.reshape(-1)
    shown = ", ".join(labels[:6]) + (", ..." if len(labels) > 6 else "")
    if value.size > size:
        raise ValueError(f"{name} must have {size} values ({shown}), got {value.size}")
    if value.size < size:
        if value.size and value[-1] != 0:
            warn_caller(f"{legacy} too short; padding with zeros ({name} has {value.size} "
                        f"values for {size}: {shown})", UserWarning)
        value = np.concatenate([value, np.zeros(size - value.size)])
    if not np.all(np.isfinite(value)):
        bad = [labels[i] for i in np.flatnonzero(~np.isfinite(value))]
        raise ValueError(f"{name} must be finite; not finite at {bad}")
    return value


def _operating_point(sys, xeq, ueq):
    if isinstance(xeq, ct.OperatingPoint):
        ueq = xeq.inputs if ueq is None else ueq
        xeq = xeq.states
    ueq = 0.0 if ueq is None else ueq
    return (_vector("xeq", "x0", xeq, sys.nstates, sys.state_labels),
            _vector("ueq", "u0", ueq, sys.ninputs, sys.input_labels))


def find_eqpt(sys, initial_state=0.0, inputs=None, outputs=None, t=0, params=None, *args,
              **kwargs):
    """:func:`control.find_eqpt`, also for sampled-data diagrams.

    A continuous or discrete diagram is handed to :func:`control.find_eqpt` as it is: the
    same arguments, the same result. A sampled-data diagram
    (:func:`controlkit.interconnect` of continuous and discrete blocks) is at equilibrium
    when every continuous state's derivative is zero and every discrete state is a fixed
    point of its update, the signals the same at every instant and in between; its
    ``derivs`` (with ``deriv_indices``) are the continuous derivatives and, for a discrete
    state, its change over one sample, ``x[k+1] - x[k]``.

    Parameters
    ----------
    sys : control.InputOutputSystem
    initial_state, inputs, outputs, t, params, *args, **kwargs
        As for :func:`control.find_eqpt`, by position too (``input_indices``,
        ``output_indices``, ``state_indices``, ``deriv_indices``, ``derivs``,
        ``root_method``, ``root_kwargs``, ``return_outputs``, ``return_result``).

    Returns
    -------
    control.OperatingPoint or tuple
        As :func:`control.find_eqpt` returns.

    Examples
    --------
    A continuous plant ``x' = -x + u`` under a discrete integral controller at 0.1 s: at
    equilibrium the output equals the reference.

    >>> import controlkit
    >>> plant = ct.ss(-1, 1, 1, 0, name="plant", inputs="u", outputs="y")
    >>> ctrl = ct.ss(1, 0.1, 0.5, 0, dt=0.1, name="ctrl", inputs="e", outputs="u")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = controlkit.interconnect([plant, ctrl, error], inputs="r", outputs="y")
    >>> point = find_eqpt(loop, [0, 0], inputs=2.0)
    >>> point.states.round(9).tolist(), point.outputs.round(9).tolist()
    ([2.0, 4.0], [2.0])
    """
    if not isinstance(sys, ct.InputOutputSystem):
        raise TypeError(f"find_eqpt needs a python-control system, got {type(sys).__name__}")
    if _sizes_unknown(sys) or not flatten(sys, params or {}).sampled_data():
        return ct.find_eqpt(sys, initial_state, inputs, outputs, t, params, *args, **kwargs)
    return ct.find_eqpt(_residual_system(sys), initial_state, inputs, outputs, t, params,
                        *args, **kwargs)


def _sizes_unknown(sys) -> bool:
    """Whether ``sys`` leaves its number of inputs, outputs or states undeclared (an
    ``nlsys`` python-control sizes from the arguments of each call)."""
    return None in (sys.ninputs, sys.noutputs, sys.nstates)


def _residual_system(sys):
    """A continuous system whose right-hand side is a sampled-data diagram's residual:
    the continuous derivatives, and ``x[k+1] - x[k]`` for the discrete states."""

    def evaluate(t, x, u, params):
        flat = flatten(sys, params)
        u_b, y_b = signals(flat, t, x, u)
        return flat, u_b, y_b

    def residual(t, x, u, params):
        flat, u_b, _ = evaluate(t, x, u, params)
        dx = np.zeros(x.size)
        for leaf in flat.leaves:
            if leaf.system.nstates:
                step = leaf.call("dynamics", t, x[leaf.x], u_b[leaf.u])
                dx[leaf.x] = step - x[leaf.x] if leaf.period is not None else step
        return dx

    def output(t, x, u, params):
        flat, u_b, y_b = evaluate(t, x, u, params)
        return flat.Y @ y_b + flat.E @ u

    return ct.nlsys(residual, output, inputs=sys.input_labels, outputs=sys.output_labels,
                    states=sys.state_labels, dt=0, name=sys.name, params={})
