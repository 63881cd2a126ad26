"""Simulation backends behind one signature, found by name in :data:`BACKENDS`.

A backend is a module with a function

``simulate(sys, T, X0, U, *, params, progress, chunks, record_every, on_chunk)``

taking the arguments already checked by :func:`.contract.check_arguments` and
returning :func:`.contract.response`'s :class:`control.TimeResponseData`. A backend
that cannot run a system raises :class:`.contract.UnsupportedSystem` with the reason;
:func:`controlkit.simulation.simulate` then runs the reference instead and warns.

:func:`fast_start_pays` is the rule by which :func:`controlkit.input_output_response`
starts the fast engine in a process, or leaves a short run to python-control.
"""

from __future__ import annotations

import importlib
import sys as _sys

import numpy as np

#: Backend name to its module (imported when first used: numba loads only when asked for).
BACKENDS = {"fast": "controlkit.engines.fast", "python-control": "controlkit.engines.reference"}

#: The backends' names.
ENGINES = tuple(BACKENDS)


def backend(name: str):
    """The module of backend ``name`` (one of :data:`ENGINES`).

    Examples
    --------
    >>> backend("python-control").__name__
    'controlkit.engines.reference'
    >>> backend("matlab")
    Traceback (most recent call last):
    ...
    ValueError: engine must be one of ('fast', 'python-control'), got 'matlab'
    """
    return importlib.import_module(BACKENDS[check_engine(name)])


def check_compile(compile) -> None:
    """Refuse a ``compile`` argument other than True, False or None (here, not in
    :mod:`.contract`: a call python-control makes alone imports nothing more).

    Examples
    --------
    >>> check_compile("yes")
    Traceback (most recent call last):
    ...
    ValueError: compile must be True, False or None (decided by the run's length), got 'yes'
    """
    if compile not in (None, True, False):
        raise ValueError(f"compile must be True, False or None (decided by the run's "
                         f"length), got {compile!r}")


def check_engine(name):
    """``name``, or a ValueError naming the engines there are (nothing imported).

    Examples
    --------
    >>> check_engine("fast")
    'fast'
    """
    if name not in BACKENDS:
        raise ValueError(f"engine must be one of {ENGINES}, got {name!r}")
    return name


class _Kept:
    """What controlkit keeps on a python-control system for its next call (python-control's
    pace on it, a block's one-block diagram, a diagram's prepared jobs); copied or pickled
    as None."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def __reduce__(self):  # (copy and deepcopy too: a pickle needs no controlkit to load)
        return (type(None), ())


def _kept_on(sys, attribute):
    """What :func:`_keep_on` kept on ``sys`` under ``attribute``, else None."""
    kept = getattr(sys, attribute, None)
    return kept.value if isinstance(kept, _Kept) else None


def _keep_on(sys, attribute, value) -> None:
    """Keep ``value`` on ``sys`` (nothing when it takes no attributes)."""
    try:
        setattr(sys, attribute, _Kept(value))
    except (AttributeError, TypeError):  # an object that takes no attributes
        pass


#: The attribute of a diagram its prepared jobs are kept in (:mod:`.fast.reuse`).
_KEPT_JOBS = "_controlkit_kept_job"
#: python-control takes at least this many times as long as the fast engine's Python run
#: of a diagram (measured on the benchmark rows: 2.5-3.4x, the spacecraft 9.8x; a chain
#: of one-line user functions, 1.2x).
PYTHON_CONTROL_SLOWER = 2.0
#: The least python-control took against it, measured (a chain of one-line functions):
#: what work done on speculation (its worth not known yet) must fit in.
PYTHON_CONTROL_LEAST = 1.2
#: The fast engine's start in a process: importing its modules (13-16 ms measured on a
#: 2-core machine).
FAST_START_SECONDS = 0.016
#: What the engine pays to prepare a diagram it has not run before in the process (a new
#: one, or one built again, as a notebook's cell run again builds it): seconds, and
#: seconds per block (reading each block's functions, writing the diagram's module:
#: 0.2-0.5 ms a block measured, counted at 1 ms for a Python run under 2x faster).
PREPARE_SECONDS = (0.0005, 0.001)
#: python-control's time per output point and per block of a diagram, at least: 11-24 us
#: measured on chains of one-line user functions, 35-130 us on the continuous benchmark
#: rows, 80 us on a discrete one.
PYTHON_CONTROL_POINT_SECONDS = 10e-6
#: python-control's time per output point of a lone system (not an interconnect), at
#: least: 16 us measured on a one-state nlsys. It calls the system's own functions, as
#: the engine's Python run does, which is then no faster (0.95-1.05x): only a compiled
#: run gains, after numba's start and a compile (1-2 s), so the engine takes a lone
#: system's run when python-control's would last longer than :data:`LONE_SECONDS`.
LONE_POINT_SECONDS = 16e-6
LONE_SECONDS = 3.0


def fast_start_pays(sys, points: int, longest: float = 0.0) -> bool:
    """Whether a call of :func:`controlkit.input_output_response` on ``sys`` goes to the
    fast engine, rather than leave the run to python-control.

    A diagram (an interconnect) run before in this process: always (the engine keeps its
    prepared job). Else only when python-control would take longer than what the engine
    pays before its run (its start, :data:`FAST_START_SECONDS`, unless it has started in
    this process; preparing the diagram, :data:`PREPARE_SECONDS`) and its own run, taken
    as :data:`PYTHON_CONTROL_SLOWER` times shorter: python-control's time estimated as
    ``points`` times the blocks times :data:`PYTHON_CONTROL_POINT_SECONDS` (its least
    measured: an estimate that errs towards python-control), or ``longest``,
    python-control's own time on ``sys`` at its pace in this process (a stiff run of few
    points). A lone system: only when python-control would take longer than
    :data:`LONE_SECONDS`, estimated as ``points`` times :data:`LONE_POINT_SECONDS`, or
    ``longest``.

    Examples
    --------
    >>> import control as ct
    >>> loop = ct.interconnect([ct.tf([1], [1, 1], name="p", inputs="u", outputs="y")],
    ...                        inputs="u", outputs="y")
    >>> fast_start_pays(loop, 100_000)  # about 1 s in python-control
    True
    >>> fast_start_pays(loop, 100)  # about 1 ms: less than preparing the diagram
    False
    >>> fast_start_pays(loop.syslist[0], 100_000)  # a lone system: about 1.6 s
    False
    """
    if getattr(sys, "syslist", None) is None:  # a lone system
        return max(points * LONE_POINT_SECONDS, longest) > LONE_SECONDS
    if _kept_on(sys, _KEPT_JOBS):  # (run before: its prepared job is kept on it)
        return True
    started = "controlkit.engines.fast" in _sys.modules
    blocks = len(sys.syslist)
    expected = max(points * blocks * PYTHON_CONTROL_POINT_SECONDS, longest)
    paid = (0.0 if started else FAST_START_SECONDS) + PREPARE_SECONDS[0] \
        + PREPARE_SECONDS[1] * blocks
    slower = PYTHON_CONTROL_SLOWER
    return expected > paid * slower / (slower - 1.0)


def numpy_raises() -> bool:
    """Whether numpy is told to raise, call or log on a floating-point error
    (``np.seterr``), which compiled code cannot do.

    Examples
    --------
    >>> with np.errstate(divide="raise"):
    ...     numpy_raises()
    True
    """
    return any(mode not in ("ignore", "warn") for mode in np.geterr().values())


def python_control_s_own(sys, T, options) -> str:
    """Why python-control answers a call of :func:`controlkit.input_output_response` (one
    run, or each of many) in its own way, which the engine leaves to it (its error, or its
    answer to arguments it reads otherwise than the engine would: times not increasing,
    evaluation times it refuses or evaluates one by one, a discrete diagram's times not
    spaced by its period, functions handed time points of another float type or a list as
    the state of a system alone without states, numpy told to raise); else ``""``.

    ``options`` are the call's keywords (``evaluation_times``, ``solve_ivp_kwargs``,
    ``squeeze``).

    Examples
    --------
    >>> import control as ct
    >>> lag = ct.nlsys(lambda t, x, u, p: -x + u, None, inputs=1, states=1, outputs=1)
    >>> T = np.linspace(0.0, 1.0, 11)
    >>> python_control_s_own(lag, T, {"solve_ivp_kwargs": {}})
    ''
    >>> python_control_s_own(lag, T, {"solve_ivp_kwargs": {}, "evaluation_times": T[::-1]})
    'evaluation times that do not increase'
    """
    isdtime = getattr(sys, "isdtime", None)  # (not a system: python-control's error)
    discrete = isdtime is None or isdtime(strict=True)
    dt = sys.dt if discrete and isdtime else False  # (a discrete diagram's period, or True)
    if getattr(sys, "nstates", None) == 0 and getattr(sys, "syslist", None) is None:
        return "a system alone without states, whose functions python-control hands x = []"
    if numpy_raises():
        return "numpy is told to raise, call or log on a floating-point error (np.seterr)"
    squeeze = options.get("squeeze")
    if not any(squeeze is allowed for allowed in (None, True, False)):
        return f"squeeze={squeeze!r}"
    times = options.get("evaluation_times", "T")  # (the default: the string "T")
    if times is None:
        return "evaluation_times=None: the solver's own steps"
    given = not (isinstance(times, str) and times == "T")
    grid = False
    if "controlkit.blocks.sampling" in _sys.modules:  # (imported for a grid)
        from ..blocks.sampling import TimeGrid  # (waits for a thread still importing it)

        grid = isinstance(T, TimeGrid)  # (increasing by construction, and kept lazy)
    if not grid:
        if "t_eval" in options["solve_ivp_kwargs"] or np.size(T) < 2:
            return "t_eval in solve_ivp_kwargs, or a single time point"
        listed = not isinstance(T, np.ndarray) or not isinstance(times, str | np.ndarray)
        if listed and discrete:
            return "time points as a list, which python-control subtracts as lists"
        why = _times_own(T, "time points", False if given else dt)
        if why:
            return why
    return _times_own(times, "evaluation times", dt) if given else ""


def _times_own(times, what, dt) -> str:
    """Why python-control answers time points ``times`` in its own way (not numbers, not
    1-D, not increasing, of a float type other than 64 bits; of a discrete system, ``dt``
    not False: fewer than two, or not equally spaced by ``dt``, which it refuses, or, of a
    system without states, evaluates at each), else ``""``."""
    if isinstance(times, np.ndarray) and times.dtype != np.float64 \
            and times.dtype.kind not in "iu":
        return f"{what} of {times.dtype}"  # (handed to the functions as they are)
    try:
        times = np.asarray(times, dtype=float)
    except (TypeError, ValueError):
        return f"{what} that are not numbers"
    if times.ndim != 1 or times.size == 0:
        return f"{what} of shape {times.shape}"
    steps = np.diff(times)
    if not np.isfinite(times).all():  # (python-control refuses in its solver's words, the
        return "" if what == "time points" else f"{what} not finite"  # engine names T)
    if not (steps > 0).all():
        return f"{what} that do not increase"
    if dt is not False and (times.size < 2 or not np.allclose(steps, steps[0]) or (
            dt is not True and not np.isclose(steps[0], dt))):
        return f"{what} not equally spaced by the sampling time"
    return ""
