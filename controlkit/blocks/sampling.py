"""Zero-order-hold discretisation of continuous nonlinear I/O systems.

python-control's :func:`control.sample_system` handles LTI systems only, and
an interconnect cannot mix a continuous block with a discrete one. The
spacecraft paper's loop is sampled-data (erratum E5): the continuous plant
is held under zero-order hold between samples. :func:`sample_nlsys` turns any
continuous ``NonlinearIOSystem`` into a discrete one that does exactly that.
"""

from __future__ import annotations

import math

import control as ct
import numpy as np
import scipy.integrate

from .. import _checks
from .._jit import python_function
from ..kernels.common import rk4_step

#: The one RK4 step (:func:`controlkit.kernels.common.rk4_step`), as plain Python: it calls
#: a system's Python right-hand side here, where the fast engine inlines the compiled one.
_rk4_step = python_function(rk4_step)

METHODS = ("rk4", "solve_ivp")


class SamplingError(ValueError, FloatingPointError):
    """A sampled block blew up inside a sample (the message names it and what to do).

    Also a ``FloatingPointError``, as a loop that diverged is (its cause may be either):
    ``time`` holds the sample's start, for studies that record when a run diverged.

    Examples
    --------
    >>> import control as ct
    >>> stiff = ct.nlsys(lambda t, x, u, p: -500.0 * x, None, inputs=0, states=1,
    ...                  outputs=1, name="stiff")
    >>> sampled, x = sample_nlsys(stiff, 0.1), [1.0]  # RK4 multiplies x by 2.4e5 a sample
    >>> try:
    ...     for k in range(100):
    ...         with np.errstate(over="ignore", invalid="ignore"):
    ...             x = sampled.dynamics(0.1 * k, x, [])
    ... except SamplingError as error:
    ...     print(str(error)[:38])
    block 'stiff' blows up inside a sample
    """


def blowup_message(name, t, Ts, substeps) -> str:
    """What to say when block ``name`` blew up in the sample starting at ``t``.

    Examples
    --------
    >>> blowup_message("plant", 0.0, 0.1, 1)[:41]
    "block 'plant' blows up inside a sample at"
    """
    return (f"block {name!r} blows up inside a sample at t = {t:g} s: either the loop "
            f"feeding it diverged (a gain too high for the sample time), or RK4 with "
            f"{substeps} substep(s) of {Ts / substeps:g} s is unstable or far too coarse for "
            f"it (stiff or fast dynamics); for the latter, sample it with more substeps "
            f"(sample_nlsys(..., substeps=...)), with method='solve_ivp', or at a smaller Ts")


def sample_nlsys(
    sys, Ts, *, method="rk4", substeps=1, rtol=1e-10, atol=1e-12, name=None
) -> ct.NonlinearIOSystem:
    """Discretise a continuous-time I/O system under zero-order hold.

    Over each sample ``[k Ts, (k+1) Ts)`` the input is held at ``u(k Ts)`` and
    the state is integrated through ``x' = f(t, x, u(k Ts))``:

        x[k+1] = x[k] + integral_{k Ts}^{(k+1) Ts} f(t, x(t), u[k]) dt
        y[k]   = g(k Ts, x[k], u[k])

    Parameters
    ----------
    sys : control.NonlinearIOSystem, control.StateSpace or control.TransferFunction
        Continuous-time system (``sys.dt == 0``); its parameters are passed on.
        A linear system (``StateSpace``, ``TransferFunction``) is sampled
        exactly, as :func:`control.sample_system` with ``method="zoh"`` does
        (``method`` and ``substeps`` do not apply), keeping its name and its
        signal names.
    Ts : float
        Sampling period, > 0.
    method : {"rk4", "solve_ivp"}
        ``"rk4"``: classical fourth-order Runge-Kutta with ``substeps`` equal
        steps per sample; the local error is about ``(lambda Ts / substeps)^5 / 120``
        for the fastest rate ``lambda`` of the system, so choose ``substeps``
        with ``lambda Ts / substeps`` well below 1 (for the spacecraft at 0.1 s
        and the CMG at 1 ms one step already gives rounding-level accuracy).
        ``"solve_ivp"``: adaptive DOP853 from scipy with ``rtol``/``atol``;
        accurate to the tolerance, much slower - a reference.
    substeps : int
        Runge-Kutta steps per sample (``"rk4"`` only), >= 1.
    rtol, atol : float
        Tolerances of ``"solve_ivp"``.
    name : str, optional
        Name of the discrete system; default: the continuous system's name,
        so that it drops into a diagram in place of the continuous block.

    Raises
    ------
    SamplingError
        On use, when a Runge-Kutta substep from a finite state blows up to a
        non-finite one: the message names the block and what to do. (A loop
        that diverges is reported by the blocks it feeds, usually earlier.)

    Returns
    -------
    SampledSystem
        Discrete (``dt = Ts``; a linear system stays a ``StateSpace`` or
        ``TransferFunction``) with the same inputs, outputs, states and
        parameters, recording the continuous system and the settings.

    Examples
    --------
    >>> import control as ct
    >>> integrator = ct.nlsys(lambda t, x, u, p: u, inputs=1, states=1, outputs=1)
    >>> sampled = sample_nlsys(integrator, 0.1)
    >>> sampled.dynamics(0.0, [1.0], [2.0]).round(12).tolist()
    [1.2]
    """
    if not isinstance(sys, ct.InputOutputSystem):
        raise ValueError(f"sys must be a python-control I/O system, got {type(sys).__name__}")
    if not sys.isctime(strict=True):
        raise ValueError(
            f"sys must be continuous time (dt = 0) to be sampled, got dt = {sys.dt!r}"
        )
    Ts = _checks.positive_scalar("Ts", Ts)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if isinstance(substeps, bool) or not isinstance(substeps, int) or substeps < 1:
        raise ValueError(f"substeps must be an integer >= 1, got {substeps!r}")
    rtol = _checks.positive_scalar("rtol", rtol)
    atol = _checks.positive_scalar("atol", atol)
    if isinstance(sys, (ct.StateSpace, ct.TransferFunction)):
        return ct.sample_system(sys, Ts, method="zoh", name=name or sys.name)
    return SampledSystem(sys, Ts, method=method, substeps=substeps, rtol=rtol, atol=atol,
                         name=name)


class SampledSystem(ct.NonlinearIOSystem):
    """A continuous system under zero-order hold at ``Ts``: what :func:`sample_nlsys` returns.

    Its update integrates the continuous system over one sample with the input held
    (RK4 with ``substeps`` steps, or DOP853 to ``rtol``/``atol``); its output is the
    continuous system's output. Build it with :func:`sample_nlsys`, which checks the
    arguments.

    Attributes
    ----------
    continuous : control.NonlinearIOSystem
        The system that was sampled.
    method : {"rk4", "solve_ivp"}
    substeps : int
    rtol, atol : float
        The sampling settings.
    kernels : BlockKernels or None
        For the fast engine: the continuous block's kernels under RK4, when it is a
        :class:`~controlkit.blocks.contract.KernelBlock` sampled by ``"rk4"``.
    uncompiled_reason : str or None
        Why ``kernels`` is None.

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> sampled = sample_nlsys(spacecraft_plant(), 0.1)
    >>> sampled.dt, sampled.method, sampled.kernels.rk4
    (0.1, 'rk4', (0.1, 1))
    """

    def __init__(self, sys, Ts, *, method, substeps, rtol, atol, name=None):
        self.continuous = sys
        self.method, self.substeps, self.rtol, self.atol = method, substeps, rtol, atol
        super().__init__(
            self._next_state, self._output, inputs=sys.input_labels,
            outputs=sys.output_labels, states=sys.state_labels, dt=Ts,
            params=dict(sys.params), name=name or sys.name)
        kernel = getattr(sys, "kernels", None)
        if method == "rk4" and kernel is not None and kernel.update is not None:
            self.kernels = kernel.sampled(Ts, substeps)  # the fast engine inlines the same RK4
            self.uncompiled_reason = None
        else:
            self.kernels = None
            self.uncompiled_reason = getattr(sys, "uncompiled_reason", None) or (
                "sampled with solve_ivp" if method == "solve_ivp" else "not a controlkit block")
        self.check = getattr(sys, "check", None)
        self.check_state = getattr(sys, "check_state", None)
        if self.name == sys.name:  # the same element, held: drawn as the block was
            for attribute in ("display_name", "junction"):
                if hasattr(sys, attribute):
                    setattr(self, attribute, getattr(sys, attribute))

    def _next_state(self, t, x, u, params):
        sys, Ts = self.continuous, self.dt
        if self.method == "rk4":
            def rhs(tau, xi, u, p, out):  # the kernel form rk4_step calls
                out[:] = sys.dynamics(tau, xi, u, params)
                return out

            h = Ts / self.substeps
            x = np.array(x, dtype=float)
            work = tuple(np.empty(x.size) for _ in range(5))
            for i in range(self.substeps):
                x_next = _rk4_step(rhs, t + i * h, x, u, None, h, work, np.empty(x.size))
                if not np.isfinite(x_next).all():
                    error = SamplingError(blowup_message(self.name, t, Ts, self.substeps))
                    error.time = float(t)
                    raise error
                x = x_next
            return x
        sol = scipy.integrate.solve_ivp(
            lambda tau, xi: sys.dynamics(tau, xi, u, params), (t, t + Ts),
            np.asarray(x, dtype=float),
            method="DOP853", rtol=self.rtol, atol=self.atol)
        if not sol.success:
            raise RuntimeError(f"solve_ivp failed inside a sample at t = {t:g}: {sol.message}")
        return sol.y[:, -1]

    def _output(self, t, x, u, params):
        return self.continuous.output(t, x, u, params)


def time_grid(horizon, Ts, *, lazy=False):
    """Sample times ``0, Ts, ..., N Ts`` with ``N = round(horizon / Ts)``.

    ``horizon`` must be a positive multiple of ``Ts`` (within rounding). With
    ``lazy=True`` the grid is a :class:`TimeGrid`, which makes its samples chunk by
    chunk: a streamed run of 10^7 steps then holds no 80 MB time vector.

    Examples
    --------
    >>> time_grid(0.3, 0.1).tolist()
    [0.0, 0.1, 0.2, 0.30000000000000004]
    >>> time_grid(0.3, 0.1, lazy=True)[1:3].tolist()
    [0.1, 0.2]
    """
    horizon = _checks.positive_scalar("horizon", horizon)
    Ts = _checks.positive_scalar("Ts", Ts)
    if not math.isfinite(horizon / Ts):  # (1e308 s at 0.1 s: more steps than a float holds)
        raise ValueError(f"horizon / Ts must be a finite number of steps, got {horizon:g} / "
                         f"{Ts:g}")
    steps = round(horizon / Ts)
    if steps < 1 or not math.isclose(steps * Ts, horizon, rel_tol=1e-9):
        raise ValueError(f"horizon must be a positive multiple of Ts = {Ts:g}, got {horizon:g}")
    grid = TimeGrid(steps + 1, Ts)
    return grid if lazy else grid[:]


class TimeGrid:
    """The uniform grid ``k Ts``, ``k = 0..size-1``, made on demand (see :func:`time_grid`).

    Indexing with a slice or an index array gives the same float64 values as the full
    array ``np.arange(size) * Ts`` would; ``np.asarray(grid)`` makes the full array.

    Examples
    --------
    >>> g = TimeGrid(5, 0.5)
    >>> len(g), g[[0, 4]].tolist(), float(g[-1])
    (5, [0.0, 2.0], 2.0)
    """

    def __init__(self, size: int, Ts: float):
        self.size, self.Ts = int(size), float(Ts)
        self.shape, self.ndim, self.dtype = (self.size,), 1, np.dtype(float)

    def __len__(self):
        return self.size

    def __getitem__(self, index):
        if isinstance(index, slice):
            values = np.arange(*index.indices(self.size), dtype=float)
        elif np.ndim(index) == 0:
            k = int(index) + (self.size if int(index) < 0 else 0)
            if not 0 <= k < self.size:
                raise IndexError(f"index {index} out of a grid of {self.size} samples")
            return k * self.Ts
        else:
            values = np.arange(self.size, dtype=float)[index] if np.asarray(index).dtype \
                == bool else np.asarray(index, dtype=float)
        values *= self.Ts
        return values

    def __array__(self, dtype=None, copy=None):
        values = self[:]
        return values if dtype is None else values.astype(dtype)
