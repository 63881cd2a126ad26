"""The fast engine behind :func:`controlkit.input_output_response`: a discrete diagram runs
step by step (:func:`.discrete.simulate`), any other through
:func:`.continuous.run_continuous`; the result is python-control's response object."""

from __future__ import annotations

import control as ct
import numpy as np

from ..._checks import Diverged
from ..contract import (
    UnsupportedSystem,
    integer_state,
    python_control_arguments,
    result_flags,
)
from ..contract import response as base_response
from .continuous import run_continuous
from .discrete import simulate
from .loops import interpolate
from .tiers import as_interconnect


def response(sys, T, U, X0, *, compile=None, **options) -> ct.TimeResponseData:
    """The fast engine behind :func:`controlkit.input_output_response` (same arguments).

    Raises
    ------
    UnsupportedSystem
        For what the engine does not run (the caller then runs python-control).

    Examples
    --------
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x + u, inputs=1, states=1, outputs=1, dt=1)
    >>> loop = ct.interconnect([sys], inputs="u[0]", outputs="y[0]")
    >>> response(loop, np.arange(3.0), 1.0, 1.0).outputs.tolist()
    [1.0, 1.5, 1.75]
    """
    given, sys = sys, as_interconnect(sys)  # the response keeps a single block's labels
    try:
        return _response(given, sys, T, U, X0, compile, options)
    except Diverged as error:
        if isinstance(given, ct.InterconnectedSystem):
            raise  # (python-control's sweep of the signals cannot settle on them either)
        raise UnsupportedSystem(f"{error}; python-control runs a single system on with "
                                "non-finite numbers") from None


def _response(given, sys, T, U, X0, compile, options):
    """:func:`response` of ``given`` run as the interconnect ``sys``."""
    given_X0 = X0
    T, U, X0, t_eval, method, solver = python_control_arguments(sys, T, U, X0, options)
    params = options.get("params")
    if sys.isdtime(strict=True):
        if not np.array_equal(t_eval, T):  # python-control interpolates U at t_eval
            U = interpolated(T, U, t_eval)
        resp = simulate(sys, t_eval, X0, U, params=params, compile=compile)
        integers = integer_state(given_X0, sys.nstates)
        if integers is not None and _integers_count(given, t_eval[0], X0, integers, U[:, 0],
                                                    params):
            raise UnsupportedSystem(
                f"X0 holds integers, which python-control keeps in its first step, where a "
                f"function of this system computes other numbers from them than from floats "
                f"(np.zeros_like(x) fills integers); X0 given as floats "
                f"(X0={np.asarray(X0).tolist()}) runs on the fast engine")
    else:
        resp = run_continuous(sys, T, U, X0, params=params, t_eval=t_eval, method=method,
                              compile=compile, **solver)
    flags = result_flags(options)
    if given is sys and flags["squeeze"] in (None, True, False):
        # the run's own response, labelled for this system: copying its arrays into a second
        # one cost more than a fast discrete loop (8 of 43 ms for 10^6 steps of a servo)
        for name, value in flags.items():
            setattr(resp, name, value)
        return resp
    relabelled = base_response(given, resp.t, resp.y, resp.x, resp.u, **flags)
    relabelled.engine_mode = resp.engine_mode
    return relabelled


def _integers_count(given, t, X0, integers, u, params) -> bool:
    """Whether python-control's first step of ``given`` from the initial state held as
    ``integers`` (see :func:`.contract.integer_state`) gives other numbers than from
    floats, or (a single block) a state still held as integers. The functions run after
    the engine's own run, which refused any that acts outside itself (a print, a write)."""
    x_given = X0.astype(integers)
    try:
        step = np.asarray(given.dynamics(t, x_given, u, params=params))
        out = np.asarray(given.output(t, x_given, u, params=params))
    except Exception:  # noqa: BLE001 - python-control's run raises it, as it does
        return True
    if step.dtype.kind != "f" and not isinstance(given, ct.InterconnectedSystem):
        return True  # a block's update returns integers: its state stays integers
    return not (np.array_equal(step, given.dynamics(t, X0, u, params=params))
                and np.array_equal(out, given.output(t, X0, u, params=params)))


def interpolated(T, U, times):
    """``U`` at ``times``, interpolated as python-control does (:func:`.loops.interpolate`).

    Examples
    --------
    >>> interpolated(np.array([0.0, 2.0]), np.array([[0.0, 4.0]]), np.array([1.0])).tolist()
    [[2.0]]
    """
    out = np.zeros((U.shape[0], len(times)))
    column = np.zeros((U.shape[0], 1))
    for j, t in enumerate(times):
        out[:, j] = interpolate(T, U, float(t), column)[:, 0]
    return out
