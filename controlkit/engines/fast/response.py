"""The fast engine behind :func:`controlkit.input_output_response`: a discrete diagram runs
step by step (:func:`.discrete.simulate`), any other through
:func:`.continuous.run_continuous`; the result is python-control's response object."""

from __future__ import annotations

import control as ct
import numpy as np

from ...compat import SYSTEM_CALLS
from ...sampled_data import SampledDataSystem
from ..contract import UnsupportedSystem, kept_state, python_control_arguments, result_flags
from ..contract import response as base_response
from .continuous import StiffProblem, run_continuous
from .discrete import simulate
from .tiers import LONE_TRANSFER_FUNCTION, _local_params, as_interconnect


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
    if isinstance(sys, ct.TransferFunction):  # (an interconnect's block converts, as ours)
        raise UnsupportedSystem(LONE_TRANSFER_FUNCTION)
    given, sys = sys, as_interconnect(sys)  # the response keeps a single block's labels
    return _response(given, sys, T, U, X0, compile, options)


def _response(given, sys, T, U, X0, compile, options):
    """:func:`response` of ``given`` run as the interconnect ``sys``."""
    given_X0, given_times = X0, options.get("evaluation_times", "T")
    given_times = T if isinstance(given_times, str) else given_times
    # python-control hands its functions the time points as given: integers stay so
    if isinstance(given_times, list | tuple | range):  # (integers stay integers there too)
        given_times = np.asarray(given_times)
    integer_times = isinstance(given_times, np.ndarray) and given_times.dtype.kind in "iu"
    T, U, X0, t_eval, method, solver = python_control_arguments(sys, T, U, X0, options)
    params = options.get("params")
    if sys.isdtime(strict=True):
        U = read_inputs(T, U, t_eval)
        try:
            resp = simulate(sys, t_eval, X0, U, params=params, compile=compile)
        except UnsupportedSystem:
            raise
        except Exception as error:
            if integer_times:  # (a table indexed by t, say): python-control's own answer
                raise UnsupportedSystem(_INTEGER_TIMES.format(
                    f"fails on a float t ({type(error).__name__})")) from None
            raise
        kept = kept_state(given_X0, sys.nstates)
        if kept is not None and _first_step_differs(given, t_eval[0], X0, U[:, 0], params,
                                                t_eval[0], X0.astype(kept)):
            held, example = (("integers", "np.zeros_like(x) fills integers")
                             if kept.kind in "biu" else
                             (f"{kept.name} numbers", f"0.9 * x[0] is a {kept.name}"))
            raise UnsupportedSystem(
                f"X0 holds {held}, which python-control keeps in its first step, where a "
                f"function of this system computes other numbers from them than from "
                f"floats ({example}); X0 given as floats (X0={np.asarray(X0).tolist()}) "
                f"runs on the fast engine")
        returned = _lone_returns(given, t_eval[0], X0, U[:, 0], params)
        if returned is not None:
            raise UnsupportedSystem(
                f"its functions return {returned} numbers, which python-control keeps in the "
                f"response of a system alone (and in its next state, from an update), where "
                f"the engine's arrays hold 64-bit floats")
        if integer_times and _first_step_differs(given, t_eval[0], X0, U[:, 0], params,
                                             given_times[0], X0):
            raise UnsupportedSystem(_INTEGER_TIMES.format(
                "computes other numbers from it than from a float t"))
    else:
        try:
            resp = run_continuous(sys, T, U, X0, params=params, t_eval=t_eval,
                                  method=method, compile=compile, **solver)
        except RuntimeError as error:
            if (not options.get("ignore_errors") or isinstance(error, StiffProblem)
                    or isinstance(given, SampledDataSystem)):
                raise  # (a stiff run would take python-control hours; no run of its own)
            # python-control then answers with what its solver reached, success False
            raise UnsupportedSystem(f"{error}; with ignore_errors=True python-control's "
                                    f"run returns the response up to there") from None
        resp.y = outputs(given, sys, resp, params)
    flags = result_flags(options)
    if given is sys and given.nstates and flags["squeeze"] in (None, True, False):
        # the run's own response, labelled for this system: copying its arrays into a second
        # one cost more than a fast discrete loop (8 of 43 ms for 10^6 steps of a servo)
        for name, value in flags.items():
            setattr(resp, name, value)
    else:
        if not given.nstates:  # python-control's response without states keeps no params
            flags.pop("params")
        relabelled = base_response(given, resp.t, resp.y, resp.x if given.nstates else None,
                                   resp.u, **flags)
        relabelled.engine_mode, resp = resp.engine_mode, relabelled
    if integer_times:
        resp.t = given_times.reshape(-1)  # python-control's time points, as given
    return resp


#: Why a discrete run whose time points are integers goes to python-control.
_INTEGER_TIMES = ("T holds integers, which python-control hands to the functions as the time "
                  "t, and a function of this system {}; T given as floats (T.astype(float)) "
                  "runs on the fast engine")


def _first_step_differs(given, t, X0, u, params, t_given, x_given) -> bool:
    """Whether python-control's first step of ``given`` at the time and from the initial
    state as it holds them (``t_given``, ``x_given``: integers or float32, see
    :func:`.contract.kept_state`) gives other numbers than at the engine's floats ``t``
    and ``X0``, or (a single block) a state still held as integers. The functions run
    after the engine's own run, which refused any that acts outside itself (a print)."""
    with SYSTEM_CALLS:  # (python-control's systems keep a call's params on themselves)
        try:
            step = np.asarray(given.dynamics(t_given, x_given, u, params=params))
            out = np.asarray(given.output(t_given, x_given, u, params=params))
        except Exception:  # noqa: BLE001 - python-control's run raises it, as it does
            return True
        if step.dtype.kind != "f" and not isinstance(given, ct.InterconnectedSystem):
            return True  # a block's update returns integers: its state stays integers
        return not (np.array_equal(step, given.dynamics(t, X0, u, params=params))
                    and np.array_equal(out, given.output(t, X0, u, params=params)))


def _lone_returns(given, t, x, u, params) -> str | None:
    """The type other than 64-bit floats that a discrete system alone (not an interconnect,
    whose signals python-control keeps in arrays of floats) returns at its first step
    (ints of ``round``, bools of a comparison, ``float32``, complex numbers), else None."""
    if isinstance(given, ct.InterconnectedSystem) or not isinstance(given, ct.NonlinearIOSystem):
        return None
    with SYSTEM_CALLS:  # (python-control's systems keep a call's params on themselves)
        try:
            values = [np.asarray(given.output(t, x, u, params=params))]
            if given.nstates:
                values.append(np.asarray(given.dynamics(t, x, u, params=params)))
        except Exception:  # noqa: BLE001 - the run answered: its first step did not raise
            return None
    kinds = [value.dtype.name for value in values if value.dtype != np.float64]
    return kinds[0] if kinds else None


def outputs(given, diagram, resp, params) -> np.ndarray:
    """The outputs of a continuous run ``resp`` of ``given`` (run as ``diagram``), as
    python-control makes them: the run's own, save for a lone system with states, whose
    output function python-control calls after its solver, on each time's column of the
    states and of the inputs, ``given.outfcn(t, X[:, i], U[:, i], params)`` (numpy's product
    of a matrix and such a strided column rounds otherwise than of a copy: a state-space
    block's ``C @ x`` moves in the last bit), with the system's parameters updated by the
    call's (its ``outfcn`` None: the states).

    Examples
    --------
    >>> sys = ct.ss([[-1.0, 0.0], [1.0, -2.0]], [[1.0], [0.0]], [[0.3, 0.7]], [[0.0]])
    >>> run = ct.TimeResponseData(np.arange(2.0), np.zeros((1, 2)), np.array(
    ...     [[1.0, 0.5], [2.0, 0.5]]), np.zeros((1, 2)))
    >>> outputs(sys, as_interconnect(sys), run, None).tolist()
    [[1.7, 0.5]]
    """
    if given is diagram or not given.nstates or given.isdtime(strict=True):
        return resp.y
    X, U = resp.x, resp.u
    if given.outfcn is None:
        return np.array(X[:given.noutputs])
    current = _local_params(diagram, given, params)  # (the diagram holds none of its own)
    Y = np.zeros((given.noutputs, len(resp.t)))
    with SYSTEM_CALLS:
        for i, t in enumerate(resp.t):
            Y[:, i] = np.asarray(given.outfcn(t, X[:, i], U[:, i], current)).reshape(-1)
    return Y


def read_inputs(T, U, times):
    """``U`` at ``times`` as python-control's input function (its ``ufun``) reads it for a
    discrete run, on every time at once: linear between the points of ``T`` (the end
    segments extrapolated), so that at a point itself it is
    ``U[:, k - 1] * 0.0 + U[:, k] * 1.0``: the number given, save that a ``-0.0`` after a
    positive value reads ``0.0`` (which a block's ``atan2`` or ``1 / u`` tells apart).

    Examples
    --------
    >>> read_inputs(np.array([0.0, 2.0]), np.array([[0.0, 4.0]]), np.array([1.0])).tolist()
    [[2.0]]
    >>> read_inputs(np.arange(3.0), np.array([[1.0, -0.0, -0.0]]), np.arange(3.0)).tolist()
    [[1.0, 0.0, -0.0]]
    """
    if len(T) < 2:  # one time point holds (:func:`.loops.interpolate`)
        return np.repeat(U[:, :1], len(times), axis=1)
    if np.array_equal(times, T) and not np.signbit(U[U == 0.0]).any():
        return U  # (its own points and no negative zero: U as given, without a copy)
    idx = np.clip(np.searchsorted(T, times, side="left"), 1, len(T) - 1)
    dt = (times - T[idx - 1]) / (T[idx] - T[idx - 1])
    return U[:, idx - 1] * (1.0 - dt) + U[:, idx] * dt
