"""Running diagrams: initial states built by block name, and runs on any backend.

:func:`simulate` checks its arguments once and hands them to a backend of
:mod:`controlkit.engines`; the results are ordinary :class:`control.TimeResponseData`.
"""

from __future__ import annotations

import sys as _sys
import time
import weakref
from collections.abc import Callable

import control as ct
import numpy as np
from control.timeresp import TimeResponseList

from . import engines

# The engines' modules are imported by the functions that use them: a call that
# python-control runs alone (see input_output_response) imports none of them.


def initial_state(sys, /, **by_block) -> np.ndarray:
    """State vector of an interconnect, given per block name.

    Blocks not named start from their ``x0`` attribute when they have one
    (a :class:`~controlkit.blocks.contract.KernelBlock`'s natural initial state,
    such as the FRIT tuner's ``P(0) = gamma I``), otherwise from zero. A state given
    is checked by the block where it declares a check (the spacecraft plant's
    quaternion must be finite and of unit norm).

    Parameters
    ----------
    sys : control.InterconnectedSystem or control.NonlinearIOSystem
        The diagram (or a single block).
    **by_block : array_like
        Initial state of the block with that name.

    Returns
    -------
    numpy.ndarray
        The stacked initial state, in ``sys.state_labels`` order.

    Examples
    --------
    >>> from controlkit.studies.spacecraft.diagrams import output_zeroing_loop
    >>> initial_state(output_zeroing_loop(), plant=[1, 0, 0, 0]).tolist()
    [1.0, 0.0, 0.0, 0.0]
    >>> initial_state(output_zeroing_loop(), plant=[2, 0, 0, 0])  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ValueError: initial state of block 'plant' must be a unit quaternion ... got norm 2; ...
    """
    from . import _checks
    from .blocks.contract import check_initial_state

    subsystems = getattr(sys, "syslist", [sys])
    names = {s.name for s in subsystems}
    unknown = set(by_block) - names
    if unknown:
        raise ValueError(f"no block named {sorted(unknown)} in {sys.name}; blocks: "
                         f"{sorted(names)}")
    parts = []
    for s in subsystems:
        if s.nstates == 0:
            continue
        value = by_block.get(s.name, getattr(s, "x0", np.zeros(s.nstates)))
        value = _checks.float_array(f"initial state of block {s.name!r}", value).reshape(-1)
        if value.size != s.nstates:
            raise ValueError(f"initial state of block {s.name!r} must have {s.nstates} "
                             f"values ({s.state_labels}), got {value.size}")
        if s.name in by_block:
            check_initial_state(s, value)
        parts.append(value)
    return np.concatenate(parts) if parts else np.zeros(0)


def simulate(
    sys, T, *, X0, U=0.0, params=None, progress: Callable[[float], None] | None = None,
    chunks: int = 1, engine: str = "python-control", record_every: int = 1,
    on_chunk: Callable | None = None, compile: bool | None = None,
) -> ct.TimeResponseData:
    """Simulate a system, optionally in chunks with progress reports, streamed if long.

    For a drop-in replacement of python-control's function (its arguments in its
    order) use :func:`input_output_response`; this one adds progress reports, chunks and
    streaming for long runs, and takes ``X0`` and ``U`` by keyword only, so that a call
    written for python-control's order (``U`` before ``X0``) cannot swap them silently.

    ``engine`` names a backend of :mod:`controlkit.engines`: ``"python-control"``
    runs :func:`control.input_output_response` (the reference); ``"fast"`` runs
    :func:`controlkit.engines.fast.simulate`, which gives the same response much
    faster; a system it cannot compile runs on the python-control path with a warning
    naming the block.

    A discrete system run in chunks gives the same numbers, bit for bit, as one
    run: each chunk restarts from the state the previous one reached.

    Parameters
    ----------
    sys : control.InputOutputSystem
        System to simulate.
    T : array_like
        Time points (for a discrete system, multiples of ``sys.dt``).
    X0 : array_like
        Initial state, exactly ``sys.nstates`` values (keyword only).
    U : float or array_like
        Inputs: a constant (scalar or one value per input) or an array
        ``(ninputs, len(T))`` (keyword only).
    params : dict, optional
        Parameter values, as for :func:`control.input_output_response`; a key
        no block reads is refused (:func:`controlkit.engines.params.check_params`).
    progress : callable, optional
        Called with the fraction done (0 < f <= 1) after each chunk (a continuous run:
        after each piece the fast engine integrates, or once at the end).
    chunks : int
        Number of pieces a discrete run is cut into (for progress reports), >= 1 (more
        than the run's steps: one step each); a continuous run is integrated in one.
    engine : {"python-control", "fast"}
        Which backend to use (see above).
    record_every : int
        Keep every ``record_every``-th sample (and the last) in the result. A discrete
        run on the fast engine is then streamed through fixed buffers, so a long horizon
        needs memory for the kept samples only (a continuous one holds its run).
    on_chunk : callable, optional
        ``on_chunk(time, outputs, states)``, called with every sample exactly once, in
        order, chunk by chunk and at full resolution: for metrics that need every step
        (a maximum, a peak) while only decimated samples are kept (the python-control
        engine: once, with the whole run). Its arrays are read-only, the callback's to keep.
    compile : bool or None
        On the fast engine, as for :func:`input_output_response`.

    Returns
    -------
    control.TimeResponseData
        As :func:`control.input_output_response` with ``return_x=True``: ``.states`` is
        filled, and ``t, y, x = simulate(...)`` unpacks it.

    Raises
    ------
    controlkit._checks.Diverged
        Where a diagram's state or output becomes NaN or infinite, on either engine.
    KeyboardInterrupt
        On Ctrl-C, with the response so far on its ``response`` attribute.

    Examples
    --------
    >>> import numpy as np, control as ct
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    >>> simulate(sys, np.arange(4), X0=[1.0], chunks=2).outputs.tolist()
    [[1.0, 0.5, 0.25, 0.125]]
    """
    if isinstance(chunks, bool) or not isinstance(chunks, int | np.integer) or chunks < 1:
        raise ValueError(f"chunks must be an integer >= 1, got {chunks!r}")
    for name, given in (("progress", progress), ("on_chunk", on_chunk)):
        if given is not None and not callable(given):
            raise TypeError(f"{name} must be a function or None, got {given!r}")
    from .engines.contract import UnsupportedSystem, check_arguments, recorded_indices
    from .engines.params import check_params

    backend = engines.backend(engine)
    engines.check_compile(compile)
    recorded_indices(1, record_every)  # (its check, before a run)
    T, X0, U = check_arguments(sys, T, X0, U)
    check_params(sys, params)
    options = dict(params=params, progress=progress, chunks=chunks,
                   record_every=record_every, on_chunk=on_chunk)
    resp = None
    try:
        if engine != "python-control":
            try:
                resp = backend.simulate(sys, T, X0, U, compile=compile, **options)
            except UnsupportedSystem as reason:
                _warn(f"{engine} engine not used, running python-control instead: {reason} "
                      "(controlkit.engines.fast.explain(sys) lists every block's tier)")
        if resp is None:
            resp = engines.backend("python-control").simulate(sys, T, X0, U, **options)
    except KeyboardInterrupt as stop:  # (the response so far, as a whole run's)
        resp = getattr(stop, "response", None)
        raise
    finally:
        if resp is not None:  # (python-control's return_x=True response)
            resp.return_x, resp.params = True, params
    return resp


def input_output_response(sys, timepts=None, inputs=0.0, initial_state=0.0, params=None,
                          ignore_errors=False, transpose=False, return_states=False,
                          squeeze=None, solve_ivp_kwargs=None, evaluation_times="T", *,
                          engine="fast", compile=None, **kwargs):
    """:func:`control.input_output_response`, compiled where it can be, for any diagram.

    Takes python-control's arguments in python-control's order, with its aliases
    (``T``, ``U``, ``X0``, ``return_x``, ``t_eval``, ``solve_ivp_method``, ``method``) and
    rules (a list of systems gives a list of responses; a short ``X0`` is padded with
    zeros, with python-control's warning), and returns what it returns, a
    :class:`control.TimeResponseData`: a user switches by changing one import. Where the
    diagram can run on the fast engine (:mod:`controlkit.engines.fast`) it does, with the
    same numbers; otherwise python-control runs it, with a warning naming the block and
    why (:func:`controlkit.engines.fast.explain`). A run too short for the engine's start
    and preparing a diagram it has not run before to pay is python-control's own
    (:func:`controlkit.engines.fast_start_pays`; ``engine_mode`` ``"python-control"``), so
    that no call is slower than python-control's. A diagram of continuous and discrete
    blocks (:func:`controlkit.interconnect`), which python-control cannot simulate, runs
    with the semantics described in :mod:`controlkit.sampled_data`.

    Parameters
    ----------
    sys, timepts, inputs, initial_state, params, ignore_errors, transpose, \
return_states, squeeze, solve_ivp_kwargs, evaluation_times, **kwargs
        As for :func:`control.input_output_response` (python-control 0.10).
    engine : {"fast", "python-control"}
        ``"python-control"`` always runs python-control (for a sampled-data diagram,
        controlkit's plain-Python reference, :func:`controlkit.engines.reference.
        simulate_sampled_data`).
    compile : bool or None
        How the fast engine runs the diagram's module (:mod:`controlkit.engines.fast.run`):
        ``None`` (default) as Python unless the run is long enough for compiling to pay
        (or the diagram is compiled already), ``True`` compiled (compiling it now, once:
        later runs load it), ``False`` as Python; ``True`` and ``False`` start the engine
        whatever the run's length. ``explain(sys)`` says which blocks can be compiled.

    Returns
    -------
    control.TimeResponseData or control.TimeResponseList
        A list for a list of systems, as python-control; and for many runs of one system
        (beyond python-control): ``params`` a list of dicts, or ``initial_state`` a 2-D
        array with one row of ``sys.nstates`` values per run (one of them may be a single
        value for every run). The runs go in one compiled call over all cores.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.nlsys(lambda t, x, u, p: 0.5 * x + u, inputs=1, states=1, outputs=1, dt=1)
    >>> input_output_response(sys, np.arange(4.0), 1.0, 1.0).outputs.tolist()
    [1.0, 1.5, 1.75, 1.875]

    Three runs from three initial states:

    >>> runs = input_output_response(sys, np.arange(3.0), 0.0, [[1.0], [2.0], [4.0]])
    >>> [r.outputs.tolist() for r in runs]
    [[1.0, 0.5, 0.25], [2.0, 1.0, 0.5], [4.0, 2.0, 1.0]]
    """
    from .compat import timeresp_arguments

    T, U, X0, return_x, t_eval = timeresp_arguments(kwargs, timepts, inputs, initial_state,
                                                    return_states, evaluation_times)
    if kwargs.get("solve_ivp_method") and kwargs.get("method"):  # (python-control's words)
        raise ValueError("ivp_method specified more than once")
    unknown = {k: v for k, v in kwargs.items()  # (a method None or "": not read, unknown)
               if k not in ("solve_ivp_method", "method") or not v}
    if unknown:  # python-control's words, before any run (its own refuses them so)
        raise TypeError("unrecognized keyword(s): ", str(unknown))
    options = dict(params=params, ignore_errors=ignore_errors, transpose=transpose,
                   return_states=return_x, squeeze=squeeze, evaluation_times=t_eval,
                   solve_ivp_kwargs=dict(solve_ivp_kwargs or {}), **kwargs)
    engines.check_engine(engine)
    engines.check_compile(compile)
    if isinstance(sys, list | tuple):
        return TimeResponseList([input_output_response(s, T, U, X0, engine=engine,
                                                       compile=compile, **options)
                                 for s in sys])
    runs = _runs(sys, X0, params)
    if runs is not None:
        return _many(sys, T, U, X0, runs, engine, options, compile)
    mixed = None
    if "controlkit.sampled_data" in _sys.modules:  # (not imported: no such diagram)
        from . import sampled_data as mixed  # (waits for a thread still importing it)
    if mixed is not None and isinstance(sys, mixed.SampledDataSystem):
        if t_eval is None:
            raise ValueError("evaluation_times=None (the solver's own steps) has no meaning "
                             "for a sampled-data diagram, integrated between its instants: "
                             "give the times, or 'T'")
        return _sampled_data_response(sys, T, U, X0, engine, options, compile)
    # (a short run: python-control's own, before more is asked of T)
    own = engine == "fast" and (compile is not None or _starts_engine(sys, np.size(T))) and \
        engines.python_control_s_own(sys, T, options)
    if own and compile:  # (asked for, so said: as for a stiff method)
        _warn(f"compile=True not used: python-control runs this call itself ({own})")
    if own == "":  # (the engine's run: False is python-control's by the rule above)
        from ._checks import Diverged  # (as the engine, about to run, imports it)

        try:
            fast = _fast_response(sys, T, U, X0, options, "python-control",
                                  advice=" (controlkit.explain(sys) lists every block's tier)",
                                  compile=compile)
        except Diverged as diverged:
            if not sys.isdtime(strict=True) and len(getattr(sys, "connect_map", ())):
                raise  # (block inputs: python-control's solver, or its sweep, stops too)
            return _python_control_s_divergence(diverged, sys, T, U, X0, options)
        if fast is not None:
            if getattr(fast, "engine_mode", None) == "compiled" and \
                    getattr(sys, "syslist", None) is None:
                _compiled_lone(sys, add=True)
            return fast
    return _python_control(sys, T, U, X0, options)


def _numpy_raises(compile=None) -> bool:
    """:func:`controlkit.engines.numpy_raises`: the blocks' functions then run as Python,
    said if ``compile`` is True."""
    raises = engines.numpy_raises()
    if raises and compile:
        _warn("compile=True not used: numpy is told to raise, call or log on a floating-point "
              "error (np.seterr), which compiled code cannot")
    return raises


#: The attribute of a system holding python-control's slowest pace on it, s a time point.
_PACE = "_controlkit_python_control_pace"
#: Lone systems (not interconnects) that a run compiled in this process (``compile=True``):
#: their later runs stay on the engine, compiled, whatever their length.
_COMPILED_LONE = weakref.WeakSet()


def _compiled_lone(sys, add=False) -> bool:
    """Whether ``sys`` is in :data:`_COMPILED_LONE` (added first with ``add``); False for
    a system that is not hashable (one that defines ``__eq__`` alone)."""
    try:
        if add:
            _COMPILED_LONE.add(sys)
        return sys in _COMPILED_LONE
    except TypeError:
        return False


def _warn(message: str) -> None:
    """:func:`controlkit._checks.warn_caller`, imported when first needed."""
    from ._checks import warn_caller

    warn_caller(message)


def _starts_engine(sys, points: int) -> bool:
    """Whether ``points`` time points of ``sys`` (a batch's together) go to the engine."""
    return _compiled_lone(sys) or engines.fast_start_pays(
        sys, points, (engines._kept_on(sys, _PACE) or 0.0) * points)


def _python_control(sys, T, U, X0, options):
    """python-control's own run, its pace kept on ``sys`` (:data:`_PACE`);
    ``engine_mode`` ``"python-control"``."""
    from .compat import SYSTEM_CALLS

    start = time.perf_counter()
    with SYSTEM_CALLS:  # (its systems keep a call's params on themselves)
        resp = ct.input_output_response(sys, T, U, X0, **options)
    pace = (time.perf_counter() - start) / max(np.size(T), 1)
    engines._keep_on(sys, _PACE, max(pace, engines._kept_on(sys, _PACE) or 0.0))
    resp.engine_mode = "python-control"
    resp.plot_inputs = resp.plot_inputs and resp.ninputs > 0  # (as the engine's response)
    return resp


def _python_control_s_divergence(diverged, sys, T, U, X0, options):
    """A run the engine stopped on a non-finite number, where python-control's may go on
    (a single system, a diagram of blocks without inputs, a discrete state no output
    shows): python-control's answer, infinities and NaN included. Where a block input
    reads the number, its sweep of the signals cannot settle (its solver stops on a
    continuous one, the caller's check) and it raises a ``RuntimeError`` ("algebraic loop
    detected"), which the engine's error, naming the block, says better."""
    try:
        resp = _python_control(sys, T, U, X0, options)
    except RuntimeError as error:
        raise diverged from error
    _warn(f"fast engine not used, running python-control instead: {diverged}; "
          "python-control's run goes on with non-finite numbers")
    return resp


def _fast_response(sys, T, U, X0, options, instead, *, advice="", compile=None):
    """The fast backend's response, or None after a warning that names why it cannot run
    ``sys`` and what runs ``instead``."""
    from .engines.contract import UnsupportedSystem

    try:
        return engines.backend("fast").response(sys, T, U, X0, compile=compile, **options)
    except UnsupportedSystem as reason:
        _warn(f"fast engine not used, running {instead} instead: {reason}{advice}")
        return None


def _runs(sys, X0, params):
    """``(X0s, params_list)`` when the call asks for several runs of ``sys``, else None."""
    listed = isinstance(params, list | tuple) and all(
        p is None or isinstance(p, dict) for p in params)
    try:  # python-control flattens a ragged list of parts: that is one initial state
        states = np.asarray(X0, dtype=float)
    except (TypeError, ValueError):
        states = np.zeros(0)
    many_states = (states.ndim == 2 and states.shape[1] == (sys.nstates or 0)
                   and states.shape[0] > 1)
    if not (listed or many_states):
        return None
    if listed and not params:
        raise ValueError("params must not be an empty list (a dict, or one dict per run)")
    sets, rows = len(params) if listed else 1, states.shape[0] if many_states else 1
    count = max(sets, rows)
    if sets not in (1, count) or rows not in (1, count):
        raise ValueError(f"params ({sets} sets) and initial_state ({rows} rows) must give the "
                         f"same number of runs, or one of them a single value for every run")
    params_list = list(params) * (count // len(params)) if listed else [params] * count
    if many_states:
        X0s = np.array(np.broadcast_to(np.asarray(states, dtype=float), (count, sys.nstates)))
        # (a writable copy: compiled code made for one kind of array serves the next call)
    else:
        X0s = None  # the single initial state, read as python-control reads it
    return X0s, params_list


def _many(sys, T, U, X0, runs, engine, options, compile):
    """Many runs of ``sys``: one compiled call over all cores where it can be."""
    X0s, params_list = runs
    options = dict(options, params=None)
    rows = X0s  # (each run alone is given its row as the call gave it: integers, float32)
    if X0s is not None and isinstance(X0, list | tuple) and len(X0) == len(X0s):
        rows = list(X0)  # (a list's rows each as written: numpy would make all floats)
    elif X0s is not None and np.asarray(X0).dtype.kind in "biuf":
        rows = np.broadcast_to(np.asarray(X0), X0s.shape)
    # (a batch python-control would finish sooner than the engine starts, or answers in
    # its own way: run by run, each saying why)
    if engine == "fast" and not engines.python_control_s_own(sys, T, options) and (
            compile is not None or _starts_engine(sys, np.size(T) * len(params_list))):
        listed = _many_on_the_engine(sys, T, U, X0, X0s, rows, params_list, options, compile)
        if listed is not None:
            return listed
    listed = []
    for r, p in enumerate(params_list):
        try:
            listed.append(input_output_response(sys, T, U, rows[r] if rows is not None else X0,
                                                engine=engine, compile=compile,
                                                **dict(options, params=p)))
        except Exception as error:  # (raised as itself, the run named)
            error.add_note(f"(in run {r} of {len(params_list)})")
            raise
    return TimeResponseList(listed)


def _many_on_the_engine(sys, T, U, X0, X0s, rows, params_list, options, compile):
    """:func:`_many`'s runs in one call of the engine, or None to answer them run by run."""
    from ._checks import Diverged
    from .engines import contract
    from .engines.contract import UnsupportedSystem
    from .engines.fast import many
    from .engines.fast.response import outputs
    from .engines.fast.tiers import as_interconnect

    if sys.isdtime(strict=True) and any(contract.kept_state(row, sys.nstates) is not None
                                        for row in (rows if rows is not None else [X0])):
        return None  # (integers or float32 in a discrete run: python-control's first step)
    if X0s is not None and not np.isfinite(X0s).all():
        return None  # (python-control's runs where a state is not finite: each says so)
    diagram = as_interconnect(sys)
    try:  # (arguments python-control reads in its own way: run by run, each saying so)
        T_, U_, x0, t_eval, method, solver = contract.python_control_arguments(
            diagram, T, U, X0s[0] if X0s is not None else X0, options)
        if diagram.isdtime(strict=True):  # (its evaluation times are its steps, checked)
            contract.check_arguments(diagram, t_eval, x0)
        X0s = X0s if X0s is not None else np.tile(x0, (len(params_list), 1))
        responses, errors = many.run_many(diagram, T_, U_, X0s, params_list, t_eval=t_eval,
                                          method=method, compile=compile, **solver)
    except UnsupportedSystem as reason:
        _warn(f"fast engine not used, running python-control instead: {reason}")
        return None
    if any(isinstance(error, Diverged | UnsupportedSystem) for error in errors):
        return None  # (a run that diverged, or python-control's: run by run, as alone)
    for r, error in enumerate(errors):
        if error is not None:  # (its own class, whatever its constructor takes)
            error.add_note(f"(in run {r} of {len(errors)})")
            raise error
    listed = TimeResponseList([
        contract.response(sys, resp.t, outputs(sys, diagram, resp, params_list[r]), resp.x,
                          resp.u, **contract.result_flags(dict(options, params=params_list[r])))
        for r, resp in enumerate(responses)])
    for mine, theirs in zip(listed, responses, strict=True):
        mine.engine_mode = theirs.engine_mode
    return listed


def _sampled_data_response(sys, T, U, X0, engine, options, compile):
    """A sampled-data diagram: on the fast engine where it can be, else the reference."""
    from .engines import contract, reference

    try:  # (read once: a short X0's warning is given once; no python-control to answer)
        T, U, X0, t_eval, method, solve_ivp_kwargs = contract.python_control_arguments(
            sys, T, U, X0, options)
    except contract.UnsupportedSystem as reason:
        raise ValueError(f"cannot run the sampled-data diagram {sys.name!r}: {reason}") \
            from None
    if engine == "fast" and not _numpy_raises(compile):  # (else the reference: it raises)
        fast = _fast_response(sys, T, U, X0, options, "controlkit's Python reference",
                              compile=compile)
        if fast is not None:
            return fast
    resp = reference.simulate_sampled_data(sys, T, X0, U, params=options["params"],
                                           t_eval=t_eval, method=method,
                                           solve_ivp_kwargs=solve_ivp_kwargs)
    return contract.response(sys, resp.t, resp.y, resp.x, resp.u,
                             **contract.result_flags(options))
