"""Problems for tests/test_rk.py and benchmarks/bench_rk.py: ``rhs(t, y, args, out)``,
and :func:`solve_ivp`, the integrator run as Python on one of them.

Every problem takes the same kind of ``args``: ``(p, T, U)`` -- parameters (1-D), and the
time points and input samples (``U[k, j]`` is input ``k`` at ``T[j]``) of a tabulated
input, read with python-control's linear interpolation (:func:`input_at`). One type of
``args`` means one compiled caller of the integrator for all of them.

The scipy reference calls the *same* Python function (``py_func``), so both sides
evaluate the right-hand side with identical operations -- provided numba compiles them to
the same operations: cubes are written ``x * x * x`` because numba turns ``x ** 3`` into
multiplications while Python calls ``pow`` (they differ in the last bit for ~25% of
``x``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from controlkit._jit import jit, python_function
from controlkit.engines.fast import rk


def solve_ivp(rhs, t_span, y0, method="RK45", t_eval=None, args=(), rtol=1e-3, atol=1e-6,
              max_step=np.inf, first_step=None, log_steps=0):
    """One interval integrated by :func:`rk.solve_interval` run as Python (a Python call
    of ``rhs(t, y, args, out)`` per stage), as ``scipy.integrate.solve_ivp(..., t_eval)``
    integrates it; ``t_eval=None`` evaluates nothing. ``log_steps`` keeps the times of the
    first accepted steps. Returns a dict: ``t`` and ``y`` (scipy's layout) of the times
    served, ``y_end``, ``status``, ``message``, ``success``, ``nfev``, ``n_accepted``,
    ``n_rejected``, ``t_reached``, ``step_times``, ``stiffness``, ``projected_steps``."""
    y0 = np.asarray(y0, dtype=np.float64)
    n = y0.shape[0]
    atol = np.ascontiguousarray(np.broadcast_to(np.asarray(atol, dtype=np.float64), (n,)))
    t_eval = np.zeros(0) if t_eval is None else np.ascontiguousarray(t_eval, dtype=float)
    y_eval = np.full((t_eval.shape[0], n), np.nan)
    y_end = np.empty(n)
    work = rk.make_workspace(n, int(log_steps), t_eval.shape[0])
    status, served = rk.solve_interval(
        None, python_function(rhs), args, rk.METHOD_INDEX[method], float(t_span[0]),
        float(t_span[1]), y0, float(rtol), atol, float(max_step),
        0.0 if first_step is None else float(first_step), t_eval, 0, True, y_eval, y_end,
        work, 0, False)
    status = int(status)
    return {"t": t_eval[:served], "y": y_eval[:served].T, "y_end": y_end, "status": status,
            "message": rk.STATUS_MESSAGES[status], "success": status == rk.SUCCESS,
            "nfev": int(work.ints[rk.NFEV]), "n_accepted": int(work.ints[rk.N_ACCEPTED]),
            "n_rejected": int(work.ints[rk.N_REJECTED]),
            "t_reached": float(work.floats[rk.TIME_REACHED]),
            "step_times": rk.step_times(work).copy(),
            "stiffness": float(work.floats[rk.STIFFNESS]),
            "projected_steps": float(work.floats[rk.PROJECTED_STEPS])}


@jit
def input_at(t, T, U, out):
    """python-control's input interpolation (``input_output_response``'s ``ufun``).

    ``j = clip(searchsorted(T, t, 'left'), 1, len(T) - 1)``,
    ``s = (t - T[j-1]) / (T[j] - T[j-1])``, ``u = U[:, j-1] (1 - s) + U[:, j] s``
    (extrapolated linearly outside ``T``).
    """
    j = np.searchsorted(T, t, side="left")
    if j < 1:
        j = 1
    if j > T.shape[0] - 1:
        j = T.shape[0] - 1
    s = (t - T[j - 1]) / (T[j] - T[j - 1])
    for k in range(U.shape[0]):
        out[k] = U[k, j - 1] * (1.0 - s) + U[k, j] * s
    return out


@jit
def linear3(t, y, args, out):
    """``y' = A y + b``: companion form of ``(s+1)(s+2)(s+3)``, constant input ``p[0]``."""
    p = args[0]
    out[0] = y[1]
    out[1] = y[2]
    out[2] = -6.0 * y[0] - 11.0 * y[1] - 6.0 * y[2] + p[0]
    return out


@jit
def decay(t, y, args, out):
    """``y' = -p[0] y`` (one state: numpy's dot products take other paths then)."""
    out[0] = -args[0][0] * y[0]
    return out


@jit
def van_der_pol(t, y, args, out):
    """``y0' = y1``, ``y1' = mu (1 - y0^2) y1 - y0``, ``mu = p[0]``."""
    mu = args[0][0]
    out[0] = y[1]
    out[1] = mu * (1.0 - y[0] * y[0]) * y[1] - y[0]
    return out


@jit
def pendulum(t, y, args, out):
    """``theta'' = -(g/l) sin(theta) - c theta'`` with ``g/l = p[0]``, ``c = p[1]``."""
    p = args[0]
    out[0] = y[1]
    out[1] = -p[0] * math.sin(y[0]) - p[1] * y[1]
    return out


@jit
def lag_with_input(t, y, args, out):
    """``tau y' = u(t) - y`` with ``u`` tabulated (``tau = p[0]``; scratch ``p[1:]``)."""
    p, T, U = args
    u = input_at(t, T, U, p[1:2])
    out[0] = (u[0] - y[0]) / p[0]
    return out


@jit
def mass_spring_with_input(t, y, args, out):
    """``x'' = (u(t) - k x - k3 x^3 - c x') / m``; ``p = (m, k, k3, c, scratch)``."""
    p, T, U = args
    u = input_at(t, T, U, p[4:5])
    out[0] = y[1]
    out[1] = (u[0] - p[1] * y[0] - p[2] * (y[0] * y[0] * y[0]) - p[3] * y[1]) / p[0]
    return out


@jit
def chain10(t, y, args, out):
    """Five unit masses in a row joined by springs ``k x + k3 x^3`` and dampers ``c``.

    ``y = (x_1..x_5, v_1..v_5)``, ``p = (k, k3, c, forcing amplitude, forcing rate)``;
    the first mass is driven by ``a sin(w t)`` and the last is tied to a wall.
    """
    p = args[0]
    k = p[0]
    k3 = p[1]
    c = p[2]
    for i in range(5):
        out[i] = y[5 + i]
    for i in range(5):
        left_x = y[i - 1] if i > 0 else 0.0
        left_v = y[5 + i - 1] if i > 0 else 0.0
        right_x = y[i + 1] if i < 4 else 0.0
        right_v = y[5 + i + 1] if i < 4 else 0.0
        d_left = y[i] - left_x
        d_right = right_x - y[i]
        force = (
            -k * d_left
            - k3 * (d_left * d_left * d_left)
            + k * d_right
            + k3 * (d_right * d_right * d_right)
            - c * (y[5 + i] - left_v)
            + c * (right_v - y[5 + i])
        )
        if i == 0:
            force += p[3] * math.sin(p[4] * t)
        out[5 + i] = force
    return out


@jit
def lorenz(t, y, args, out):
    """Lorenz's system (chaotic): ``sigma, rho, beta = p[0], p[1], p[2]``."""
    p = args[0]
    out[0] = p[0] * (y[1] - y[0])
    out[1] = y[0] * (p[1] - y[2]) - y[1]
    out[2] = y[0] * y[1] - p[2] * y[2]
    return out


@jit
def stiffish(t, y, args, out):
    """Linear with eigenvalues ``-1`` and ``-p[0]``: explicit steps sit at their
    stability limit, so steps are rejected again and again."""
    out[0] = -y[0] + y[1]
    out[1] = -args[0][0] * y[1]
    return out


@jit
def blow_up(t, y, args, out):
    """``y' = y^2``: from ``y(0) = 1`` the solution ``1 / (1 - t)`` ends at ``t = 1``."""
    out[0] = y[0] * y[0]
    return out


@jit
def nan_after(t, y, args, out):
    """``y' = -y`` up to ``t = p[0]``, NaN after it (a model leaving its domain)."""
    if t > args[0][0]:
        out[0] = math.nan
    else:
        out[0] = -y[0]
    return out


@jit
def nan_always(t, y, args, out):
    """A derivative that is NaN from the start."""
    out[0] = math.nan
    return out


@jit
def huge_constant(t, y, args, out):
    """``y' = 1e308``: the state overflows to infinity near ``t = 1.8``."""
    out[0] = 1e308
    return out


def no_table():
    """An empty input table, for problems without a tabulated input."""
    return np.zeros(2), np.zeros((0, 2))


def square_wave_table(t_end, points, period, levels=(0.0, 1.0)):
    """A square wave sampled at ``points`` times on ``[0, t_end]`` (linear in between)."""
    T = np.linspace(0.0, t_end, points)
    U = np.where(np.floor(2 * T / period) % 2 == 0, levels[1], levels[0])[None, :]
    return T, np.ascontiguousarray(U)


@dataclass
class Problem:
    """A right-hand side with its parameters, initial state and interval."""

    name: str
    rhs: object
    y0: np.ndarray
    t_span: tuple
    p: np.ndarray
    T: np.ndarray = field(default_factory=lambda: no_table()[0])
    U: np.ndarray = field(default_factory=lambda: no_table()[1])

    @property
    def args(self):
        return (self.p, self.T, self.U)

    def scipy_fun(self):
        """``fun(t, y)`` for scipy, calling the same Python code as the compiled one."""
        python_rhs = getattr(self.rhs, "py_func", self.rhs)
        args = self.args
        n = self.y0.shape[0]

        def fun(t, y):
            out = np.empty(n)
            python_rhs(t, y, args, out)
            return out

        return fun


def make_problems():
    """The problems the tests sweep, by name."""
    square_T, square_U = square_wave_table(10.0, 101, 2.5)
    force_T = np.linspace(0.0, 15.0, 61)
    force_U = (np.sin(force_T) + (force_T > 5.0) - 2.0 * (force_T > 10.0))[None, :]
    problems = [
        Problem("linear3", linear3, np.array([1.0, 0.0, 0.0]), (0.0, 10.0), np.array([1.0])),
        Problem("decay", decay, np.array([2.0]), (0.0, 5.0), np.array([0.7])),
        Problem("van_der_pol", van_der_pol, np.array([2.0, 0.0]), (0.0, 20.0),
                np.array([2.0])),
        Problem("pendulum", pendulum, np.array([2.5, 0.0]), (0.0, 50.0),
                np.array([9.81, 0.05])),
        Problem("lag_square_input", lag_with_input, np.array([0.0]), (0.0, 10.0),
                np.array([0.3, 0.0]), square_T, square_U),
        Problem("mass_spring_input", mass_spring_with_input, np.array([0.0, 0.0]),
                (0.0, 15.0), np.array([1.0, 4.0, 0.5, 0.4, 0.0]), force_T,
                np.ascontiguousarray(force_U)),
        Problem("chain10", chain10, np.linspace(0.1, 0.5, 10) * np.r_[np.ones(5), -np.ones(5)],
                (0.0, 30.0), np.array([1.0, 0.3, 0.05, 0.5, 1.3])),
        Problem("lorenz", lorenz, np.array([1.0, 1.0, 1.0]), (0.0, 10.0),
                np.array([10.0, 28.0, 8.0 / 3.0])),
        Problem("stiffish", stiffish, np.array([1.0, 1.0]), (0.0, 5.0), np.array([300.0])),
    ]
    return {problem.name: problem for problem in problems}


@jit
def pendulum_held_torque(t, y, args, out):
    """The pendulum driven by a torque ``p[2]`` that a discrete controller holds."""
    p = args[0]
    out[0] = y[1]
    out[1] = -p[0] * math.sin(y[0]) - p[1] * y[1] + p[2]
    return out
