"""The simulation loops and their rules, written once for every diagram and every mode.

A loop here runs a diagram through its *evaluator*, four functions that know the
diagram:

``evaluate(t, x, U, col, P, ys, ui, held, k) -> int``
    Every block's output into ``ys`` in evaluation order, each block's inputs into
    ``ui``. The diagram's inputs are ``U[:, col]``. At instant ``k >= 0`` a discrete
    block that fires (``k % every == 0``) computes its output and stores it in
    ``held``, one that does not gives ``held``; between instants (``k < 0``) every
    discrete block gives ``held``. Returns the index of a block whose output is NaN
    (a kernel's failure signal, block contract rule 6), else -1.
``outputs(ys, ui, Y, j)``
    The diagram's outputs into ``Y[:, j]``.
``update(t, x, ui, P, xn, k, scratch)``
    ``xn``: the next state of the discrete and sampled blocks that fire at instant
    ``k`` (a copy of ``x`` elsewhere).
``derivatives(t, x, ui, P, dx)``
    The continuous blocks' right-hand sides into ``dx`` at their states' places.

The same loops serve a diagram's own module (:mod:`.codegen`) and the reference's
evaluator of python-control's own block functions (:mod:`controlkit.engines.reference`).
Compiled, the discrete loop is pasted into its caller; the instants' loop is compiled once
for every diagram and takes the evaluator as numba's first-class functions.

Between instants the continuous states are integrated by ``integrate``
(:func:`controlkit.engines.fast.rk.solve_interval`, or :func:`scipy_interval`), a fresh
``solve_ivp`` per interval, so a diagram with no discrete block makes python-control's
one call over ``[T[0], T[-1]]``. :func:`instant_of` and :func:`interpolate` are the only
definitions of which times fall on an instant and of the inputs between time points.
"""

from __future__ import annotations

import math

import numpy as np

from ..._jit import jit
from .rk import NFEV, PAUSED, PROJECTED_STEPS, SUCCESS, solve_interval

#: ``status`` codes beyond a block index: the integrator failed (its code in status[2]);
#: the piece runs again as Python, whose functions may raise where compiled code went on
#: (a stage met a number that is not finite) or could not (a user's function raised in a
#: C function, :func:`caught`).
INTEGRATOR_FAILED, AGAIN_AS_PYTHON = -2, -3
#: The ``k`` that ``evaluate`` is given at the integrator's stages (-1: between instants).
STAGE = -2
#: An evaluation time within this fraction of the base period of an instant is on it.
INSTANT_TOLERANCE = 1e-9
#: Slots of the ``ctrl`` array of :func:`continuous_run`: the next evaluation time to
#: serve, the instant the run is at, whether that instant's interval is under way
#: (paused), the most right-hand side evaluations a call may make (0: no limit; an
#: instant with nothing to integrate counts as one), how many it made, whether a stage
#: that is not finite stops the call (:data:`AGAIN_AS_PYTHON`), and one past the
#: evaluation times the interval under way serves.
NEXT_TIME, INSTANT, UNDER_WAY, BUDGET, SPENT, WATCH_STAGES, SERVES = range(7)


def instant_of(t_eval, times, h):
    """For each evaluation time, the index of the instant of ``times`` it is on, else -1
    (within :data:`INSTANT_TOLERANCE` of the period, so that rounding never moves a
    time across an instant).

    Examples
    --------
    >>> from controlkit.sampled_data import sample_times
    >>> instant_of(np.array([0.0, 0.25, 0.5 + 1e-13]), sample_times(0.5, 0.0, 1.0), 0.5).tolist()
    [0, -1, 1]
    """
    t_eval = np.asarray(t_eval, dtype=float)
    if not h:
        return np.where(t_eval == times[0], 0, -1).astype(np.int64)
    k = np.rint((t_eval - times[0]) / h).astype(np.int64)
    on = (k >= 0) & (k < times.size) & (np.abs(t_eval - times[0] - k * h) <= INSTANT_TOLERANCE * h)
    return np.where(on, k, -1).astype(np.int64)


@jit(inline=True)
def interpolate(T, U, t, out):
    """``out[:, 0] = u(t)``, linear between the points of ``T`` as python-control's
    ``ufun``: times outside ``T`` extrapolate the end segments; one time point holds.

    Examples
    --------
    >>> out = np.zeros((1, 1))
    >>> interpolate(np.array([0.0, 1.0]), np.array([[0.0, 2.0]]), 0.25, out).tolist()
    [[0.5]]
    """
    n = T.shape[0]
    if U.shape[0] == 0:  # no inputs: nothing to search for
        return out
    if n == 1:
        for i in range(U.shape[0]):
            out[i, 0] = U[i, 0]
        return out
    idx = _segment(T, t)
    dt = (t - T[idx - 1]) / (T[idx] - T[idx - 1])
    for i in range(U.shape[0]):
        out[i, 0] = U[i, idx - 1] * (1.0 - dt) + U[i, idx] * dt
    return out


@jit(inline=True)
def _segment(T, t):
    """``searchsorted(T, t, "left")`` clipped to ``[1, len(T) - 1]`` (``len(T) >= 2``):
    the segment ``t`` is in if the points were evenly spaced (as python-control asks), or
    a neighbour, checked by ``T[idx - 1] < t <= T[idx]``; else a binary search."""
    n = T.shape[0]
    span = T[n - 1] - T[0]
    if span > 0.0 and t == t:
        guess = (t - T[0]) / span * (n - 1)
        if 0.0 < guess < n - 1:  # (NaN-free, within the points: an index is safe)
            idx = int(math.ceil(guess))
            if idx >= 1 and T[idx - 1] < t and not (T[idx] < t):
                return idx
            if idx + 1 <= n - 1 and T[idx] < t and not (T[idx + 1] < t):
                return idx + 1
            if idx - 1 >= 1 and T[idx - 2] < t and not (T[idx - 1] < t):
                return idx - 1
    idx = np.searchsorted(T, t)
    if idx < 1:
        idx = 1
    if idx > n - 1:
        idx = n - 1
    return idx


def caught(catch: bool) -> str:
    """The text a diagram's module ends with: its three functions that call kernels, as
    the instants' loop takes them compiled. numba's C functions cannot raise, so with
    ``catch`` an exception of a user's function there (an index out of a table, its own
    ``raise``) becomes :data:`AGAIN_AS_PYTHON` (at a stage, the stage's mark), and the
    piece runs again as Python, which raises it; without (a diagram of controlkit's
    kernels, which do not raise: ``try`` costs 0.2-0.5 s of a compile), the calls.

    Examples
    --------
    >>> print(caught(True).split("def ")[2])
    update_caught(t, x, ui, P, xn, k, scratch):
        try:
            update(t, x, ui, P, xn, k, scratch)
        except Exception:
            return -3
        return -1
    <BLANKLINE>
    <BLANKLINE>
    <BLANKLINE>
    """
    def body(call, instead):
        return (f"    try:\n        {call}\n    except Exception:\n        {instead}\n"
                if catch else f"    {call}\n")

    return ("\n\ndef evaluate_caught(t, x, U, col, P, ys, ui, held, k):\n"
            + body("return evaluate(t, x, U, col, P, ys, ui, held, k)",
                   f"return {AGAIN_AS_PYTHON}")
            + "\n\ndef update_caught(t, x, ui, P, xn, k, scratch):\n"
            + body("update(t, x, ui, P, xn, k, scratch)", f"return {AGAIN_AS_PYTHON}")
            + "    return -1\n\n\ndef derivatives_caught(t, x, ui, P, dx):\n"
            + body("derivatives(t, x, ui, P, dx)", "dx[dx.shape[0] - 1] = 1.0"))


@jit(inline=True)
def discrete_run(evaluate, update, outputs, T, x, U, P, Y, X, status, k0, k1, ys, ui, held,
                 xn, scratch):
    """Steps ``k0 .. k1 - 1`` of a discrete diagram (python-control's order); ``x`` in/out.

    At step ``k``: the state is recorded, every output computed (a NaN stops the run with
    ``status = [k, block]``), the diagram's outputs recorded, the states updated.
    """
    nx = x.shape[0]
    for k in range(k0, k1):
        t = T[k]
        for i in range(nx):
            X[i, k] = x[i]
        failed = evaluate(t, x, U, k, P, ys, ui, held, k)
        if failed >= 0:
            status[0] = k
            status[1] = failed
            return
        outputs(ys, ui, Y, k)
        update(t, x, ui, P, xn, k, scratch)
        for i in range(nx):
            x[i] = xn[i]


@jit(inline=True)
def _record(evaluate, outputs, t, x, T, U, ubuf, P, ys, ui, held, j, Y, X, Uo):
    """The diagram at evaluation time ``j`` between instants (discrete outputs held)."""
    interpolate(T, U, t, ubuf)
    failed = evaluate(t, x, ubuf, 0, P, ys, ui, held, -1)
    outputs(ys, ui, Y, j)
    for i in range(x.shape[0]):
        X[i, j] = x[i]
    for i in range(ubuf.shape[0]):
        Uo[i, j] = ubuf[i, 0]
    return failed


@jit(inline=True)
def record_served(evaluate, outputs, j, x, xt, cidx, y_eval, t_eval, T, U, ubuf, P, ys, ui,
                  held, Y, X, Uo):
    """The diagram at evaluation time ``j``, whose continuous states (at ``cidx`` of ``x``)
    the integrator served in ``y_eval[j]``, recorded as :func:`_record` does."""
    for q in range(x.shape[0]):
        xt[q] = x[q]
    for q in range(cidx.shape[0]):
        xt[cidx[q]] = y_eval[j, q]
    return _record(evaluate, outputs, t_eval[j], xt, T, U, ubuf, P, ys, ui, held, j, Y, X,
                   Uo)


@jit(inline=True)
def diagram_rhs(t, y, args, out):
    """The integrator's right-hand side: the continuous states' derivatives at ``(t, y)``
    (``y`` at ``cidx`` of ``x``, whose other states are held; ``args`` as unpacked below).
    """
    evaluate, derivatives, x, xt, cidx, T, U, ubuf, P, ys, ui, held, dx = args
    for i in range(x.shape[0]):
        xt[i] = x[i]
    for q in range(cidx.shape[0]):
        xt[cidx[q]] = y[q]
    interpolate(T, U, t, ubuf)
    not_finite = evaluate(t, xt, ubuf, 0, P, ys, ui, held, STAGE) != -1
    derivatives(t, xt, ui, P, dx)
    for q in range(cidx.shape[0]):
        out[q] = dx[cidx[q]]
        not_finite = not_finite or not math.isfinite(out[q])
    if not_finite:  # (marked in dx's last slot, past the states; the step is rejected)
        dx[dx.shape[0] - 1] = 1.0


@jit(inline=True)
def continuous_run(evaluate, update, outputs, integrate, machine, rhs_args, times, results,
                   state, buffers, solver, ctrl, status):
    """The instants of a diagram with continuous states; ``x``, ``held``, ``ctrl`` in/out.
    A call may stop early, the run to go on with the next call (see ``ctrl``).

    The arguments come grouped in tuples (Python passes a call of more than 30
    arguments as ``*args``, which numba cannot paste in):
    ``times = (instants, t_final, T, U, t_eval, eval_instant)``,
    ``results = (Y, X, Uo)``, ``state = (x, P, held)``,
    ``buffers = (ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work)``,
    ``solver = (method, rtol, atol, max_step, first_step)``.
    ``instants[k]`` is the ``k``-th instant; after the last one the integration runs to
    ``t_final``. ``integrate`` has the signature of
    :func:`controlkit.engines.fast.rk.solve_interval` (``machine`` is its first argument)
    and integrates :func:`diagram_rhs` with ``rhs_args``. ``ctrl`` (:data:`NEXT_TIME`,
    :data:`INSTANT`, :data:`UNDER_WAY`, :data:`BUDGET`) says where the run is: a call goes
    on from there and returns when the run is done, fails, or has spent its budget of
    evaluations inside an interval (``ctrl[UNDER_WAY] == 1``: call again). On failure
    ``status`` is ``[time index, block, 0, 0]`` for a NaN output, or ``[time index,
    INTEGRATOR_FAILED, code, steps]`` (``steps``: the projected steps of a run stopped as
    too stiff).
    """
    instants, t_final, T, U, t_eval, eval_instant = times
    Y, X, Uo = results
    x, P, held = state
    ys, ui, xn, scratch, xt, cidx, yc, y_eval, ubuf, work = buffers
    method, rtol, atol, max_step, first_step = solver
    m = t_eval.shape[0]
    nx = x.shape[0]
    nc = cidx.shape[0]
    K = instants.shape[0]
    k = ctrl[INSTANT]
    ctrl[SPENT] = 0
    while k < K:
        if ctrl[BUDGET] > 0 and ctrl[SPENT] >= ctrl[BUDGET]:
            return
        t = instants[k]
        resume = ctrl[UNDER_WAY] == 1
        if not resume:
            interpolate(T, U, t, ubuf)
            failed = evaluate(t, x, ubuf, 0, P, ys, ui, held, k)
            if failed != -1:
                status[0] = ctrl[NEXT_TIME]
                status[1] = failed
                return
            i = ctrl[NEXT_TIME]
            while i < m and eval_instant[i] == k:
                outputs(ys, ui, Y, i)
                for q in range(nx):
                    X[q, i] = x[q]
                for q in range(ubuf.shape[0]):
                    Uo[q, i] = ubuf[q, 0]
                i += 1
            ctrl[NEXT_TIME] = i
            if update(t, x, ui, P, xn, k, scratch) == AGAIN_AS_PYTHON:
                status[0] = i
                status[1] = AGAIN_AS_PYTHON
                return
            for q in range(nx):
                x[q] = xn[q]
        i = ctrl[NEXT_TIME]
        last = k + 1 == K
        t1 = t_final if last else instants[k + 1]
        if not resume:  # the evaluation times this interval serves, found once (a paused
            stop = i  # interval keeps them: a continuous run's one spans every time point)
            while stop < m and eval_instant[stop] < 0 and (
                    t_eval[stop] < t1 or last and t_eval[stop] <= t1):
                stop += 1
            ctrl[SERVES] = stop
        stop = ctrl[SERVES]
        if nc == 0 or not t1 > t:  # nothing to integrate: the signals at those times
            for j in range(i, stop):
                failed = _record(evaluate, outputs, t_eval[j], x, T, U, ubuf, P, ys, ui,
                                 held, j, Y, X, Uo)
                if failed != -1:
                    status[0] = j
                    status[1] = failed
                    return
            ctrl[NEXT_TIME] = stop
            ctrl[SPENT] += 1
            k += 1
            ctrl[INSTANT] = k
            continue
        evaluations = 0
        if not resume:
            for q in range(nc):
                yc[q] = x[cidx[q]]
        else:
            evaluations = work.ints[NFEV]
        budget = 0 if ctrl[BUDGET] <= 0 else max(1, ctrl[BUDGET] - ctrl[SPENT])
        dx = rhs_args[-1]  # (its last slot: a stage that met inf or NaN, diagram_rhs)
        dx[dx.shape[0] - 1] = 0.0
        code, served = integrate(machine, diagram_rhs, rhs_args, method, t, t1, yc, rtol, atol,
                                 max_step, first_step, t_eval[:stop], i, last,
                                 y_eval[:stop], yc, work, budget, resume)
        ctrl[SPENT] += work.ints[NFEV] - evaluations
        if ctrl[WATCH_STAGES] == 1 and dx[dx.shape[0] - 1] != 0.0:
            # a stage met inf or NaN, where a function of the user's run as Python may have
            # raised (math.log of a negative, a float divided by zero), even in a step the
            # integrator then rejected: the caller runs this piece again as Python
            status[0] = i
            status[1] = AGAIN_AS_PYTHON
            return
        if code == PAUSED:
            ctrl[UNDER_WAY] = 1
            return
        ctrl[UNDER_WAY] = 0
        for j in range(i, served):
            failed = record_served(evaluate, outputs, j, x, xt, cidx, y_eval, t_eval, T, U,
                                   ubuf, P, ys, ui, held, Y, X, Uo)
            if failed != -1:
                status[0] = j
                status[1] = failed
                return
        ctrl[NEXT_TIME] = served
        for q in range(nc):  # on failure: the state where the integrator stopped
            x[cidx[q]] = yc[q]
        if code != SUCCESS:
            status[0] = served
            status[1] = INTEGRATOR_FAILED
            status[2] = code
            status[3] = int(work.floats[PROJECTED_STEPS])
            return
        k += 1
        ctrl[INSTANT] = k


@jit(inline=True)
def instants_loop(evaluate, update, outputs, derivatives, machine, rhs_args, times, results,
                  state, buffers, solver, ctrl, status):
    """:func:`continuous_run` integrated by :func:`controlkit.engines.fast.rk.solve_interval`,
    what a diagram's module calls. Compiled once (:func:`.store.instants_loop`), it takes
    the evaluator as first-class functions (:func:`evaluator_signatures`): a new diagram
    compiles its own four functions, not the loop.
    """
    continuous_run(evaluate, update, outputs, solve_interval, machine,
                   (evaluate, derivatives) + rhs_args, times, results, state, buffers,
                   solver, ctrl, status)


def evaluator_signatures(numba, rhs_args, results, state, buffers):
    """The numba signatures of ``evaluate``, ``update``, ``outputs`` and ``derivatives``
    as :func:`instants_loop` calls them with these arrays (the times are floats, the
    indexes integers), and the types of its arguments with the
    four functions as numba's ``FunctionType`` of each.

    Examples
    --------
    >>> from controlkit import _jit
    >>> if _jit.available():
    ...     numba = _jit.numba_module()
    ...     v = np.zeros(2)
    ...     sigs, _ = evaluator_signatures(numba, (v, v), (np.zeros((1, 3)),) * 3,
    ...                                    (v, v, v), (v, v, v, v, v, np.zeros(2, np.int64),
    ...                                                v, np.zeros((3, 2)), np.zeros((1, 1)),
    ...                                                None))
    ...     str(sigs[0].return_type)
    ... else:
    ...     'int64'
    'int64'
    """
    types, typeof = numba.types, numba.typeof
    f8, i8 = types.float64, types.int64
    x, P, held = (typeof(a) for a in state)
    ys, ui, xn, scratch, _, _, _, _, ubuf, _ = (typeof(a) for a in buffers)
    signatures = (i8(f8, x, ubuf, i8, P, ys, ui, held, i8),  # evaluate
                  i8(f8, x, ui, P, xn, i8, scratch),  # update
                  types.none(ys, ui, typeof(results[0]), i8),  # outputs
                  types.none(f8, x, ui, P, typeof(rhs_args[-1])))  # derivatives
    return signatures, tuple(types.FunctionType(s) for s in signatures)


def scipy_loop(evaluate, update, outputs, derivatives, machine, rhs_args, times, results,
               state, buffers, solver, ctrl, status):
    """:func:`instants_loop` integrated by scipy's ``solve_ivp`` (:func:`scipy_interval`,
    Python only): ``solver[0]`` is scipy's name of the method.

    Examples
    --------
    A run by an implicit method goes through it, and gives python-control's numbers:

    >>> import control as ct
    >>> from controlkit import input_output_response
    >>> lag = ct.nlsys(lambda t, x, u, params: -x + u, lambda t, x, u, params: x,
    ...                states=1, inputs=1, outputs=1, name="lag")
    >>> T = np.linspace(0.0, 1.0, 5)
    >>> ours = input_output_response(lag, T, 1.0, solve_ivp_method="BDF", compile=False)
    >>> theirs = ct.input_output_response(lag, T, 1.0, solve_ivp_method="BDF")
    >>> bool(np.array_equal(ours.outputs, theirs.outputs))
    True
    """
    continuous_run(evaluate, update, outputs, scipy_interval, None,
                   (evaluate, derivatives) + rhs_args, times, results, state, buffers,
                   solver, ctrl, status)


def scipy_interval(machine, rhs, args, method, t0, t1, y0, rtol, atol, max_step,
                   first_step, t_eval, i_eval, closed_right, y_eval, y_end, work, budget,
                   resume):
    """:func:`controlkit.engines.fast.rk.solve_interval`'s contract kept by
    :func:`scipy.integrate.solve_ivp` (Python only; never paused: ``machine``, ``budget``
    and ``resume`` unused). ``method`` is scipy's name; ``work`` counts the evaluations.
    The last interval (``closed_right``) is served as python-control's call, by
    ``t_eval``; the state at its end is the last time served.

    Raises
    ------
    RuntimeError
        When scipy's solver fails, with its message and the interval.

    Examples
    --------
    >>> from controlkit.engines.fast.rk import make_workspace
    >>> def decay(t, y, args, out):
    ...     out[0] = -y[0]
    >>> y_eval, y = np.zeros((2, 1)), np.ones(1)
    >>> status, served = scipy_interval(None, decay, (), "BDF", 0.0, 1.0, y, 1e-8,
    ...     np.full(1, 1e-10), np.inf, 0.0, np.array([0.5, 1.0]), 0, True, y_eval, y,
    ...     make_workspace(1), 0, False)
    >>> status, served, bool(abs(y[0] - np.exp(-1.0)) < 1e-6)
    (0, 2, True)
    """
    import scipy.integrate

    n = y0.shape[0]

    def fun(t, y):
        out = np.empty(n)
        rhs(t, np.ascontiguousarray(y, dtype=float), args, out)
        return out

    stop = i_eval
    while stop < t_eval.shape[0] and (t_eval[stop] < t1 or closed_right and t_eval[stop] <= t1):
        stop += 1
    options = {"rtol": rtol, "atol": atol}
    if math.isfinite(max_step):
        options["max_step"] = max_step
    if first_step > 0:
        options["first_step"] = first_step
    # the whole span once, as python-control calls it: the times it serves by t_eval when
    # it is the last interval, else read from the dense output
    sol = scipy.integrate.solve_ivp(fun, (t0, t1), np.array(y0, dtype=float), method=method,
                                    dense_output=stop > i_eval and not closed_right,
                                    t_eval=t_eval[i_eval:stop] if closed_right else None,
                                    **options)
    work.ints[NFEV] = sol.nfev
    if not sol.success:
        raise RuntimeError(f"solve_ivp ({method}) failed between t = {t0:g} and {t1:g} s: "
                           f"{sol.message}")
    if stop > i_eval:  # (the dense output called on the times at once, as solve_ivp's
        # t_eval calls each step's: one by one, its products round otherwise)
        y_eval[i_eval:stop, :] = (sol.y if closed_right else sol.sol(t_eval[i_eval:stop])).T
    if sol.y.size:  # (the last interval's end is only known if it is an evaluation time)
        y_end[:] = sol.y[:, -1]
    return SUCCESS, stop
