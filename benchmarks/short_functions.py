"""A continuous loop of user blocks with one-line functions, for the session benchmark.

A first-order plant with a soft saturation on its input, ``dx/dt = -a x + u / (1 + |u|)``,
under a PI controller, optionally rewired with a low-pass filter on the measurement: the
kind of loop a course writes in a cell, each function a line reading ``params`` with
``params.get``. Its functions compile in 0.1-0.15 s each, short enough for the engine's
rule to compile them one per call within the time a call saves against python-control
(python-control's cruise loop has a vehicle function that takes 0.4-0.5 s).
:func:`loop` has :func:`cruise.loop`'s signature for its continuous form.
"""

import control as ct
import numpy as np


def plant_rate(t, x, u, params):
    return [-params.get("a", 1.0) * x[0] + u[0] / (1.0 + abs(u[0]))]


def plant_output(t, x, u, params):
    return [x[0]]


def pi_rate(t, x, u, params):
    return [u[0] - u[1]]


def pi_output(t, x, u, params):
    return [params.get("kp", 2.0) * (u[0] - u[1]) + params.get("ki", 1.0) * x[0]]


def filter_rate(t, x, u, params):
    return [(u[0] - x[0]) / params.get("tau", 0.2)]


def loop(dt=None, filtered=False, points=20_000, horizon=None):
    """The loop, continuous (``dt`` must be None), with a measurement filter if
    ``filtered``: ``(loop, T, X0, U)`` for ``points`` time points 0.01 s apart (or spread
    over ``horizon`` seconds), a unit step reference."""
    if dt is not None:
        raise ValueError(f"dt must be None (the loop is continuous), got {dt!r}")
    measured = "yf" if filtered else "y"
    blocks = [ct.nlsys(plant_rate, plant_output, inputs="u", outputs="y", states="xp",
                       name="plant"),
              ct.nlsys(pi_rate, pi_output, inputs=["r", measured], outputs="u", states="z",
                       name="pi")]
    if filtered:
        blocks.append(ct.nlsys(filter_rate, plant_output, inputs="y", outputs="yf",
                               states="xf", name="filter"))
    sys = ct.interconnect(blocks, inputs="r", outputs=["y", "u"],
                          name="short_filtered" if filtered else "short")
    T = np.arange(points) * 0.01 if horizon is None else np.linspace(0.0, horizon, points)
    U = np.ones((1, T.size))
    return sys, T, np.zeros(3 if filtered else 2), U
