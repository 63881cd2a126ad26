"""A run in pieces of about a tenth of a second: between two pieces a run reports its
progress, Ctrl-C stops it, and the rule of :mod:`.run` may move it from Python to compiled
code; the pieces change no number.
"""

from __future__ import annotations

import time

import numpy as np

#: The length of a piece of a run.
PIECE_SECONDS = 0.1


def same_numbers(a, b) -> bool:
    """Whether two pieces of a run hold the same numbers (NaN where NaN): a last bit that
    compiled code computes otherwise (an operation of numba's that none of the engine's
    rules knows) sends the run to Python, not on.

    Examples
    --------
    >>> same_numbers([1.0, np.nan], [1.0, np.nan]), same_numbers([1.0], [np.nextafter(1.0, 2.0)])
    (True, False)
    """
    return bool(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float),
                               equal_nan=True))


def checked_as(job, params=None) -> tuple:
    """What a compiled piece of ``job`` compared equal with Python's holds for: its module,
    the classes of its parameter values whose compiled meaning can part from Python's
    (zero, negative, fractional, not finite, their size by factors of 256: an integer's
    power outgrows 64 bits) and the types of the call's own
    ``params`` values. A module checked with one class is checked again with another:
    ``1.0 / k`` raises in Python for ``k = 0.0``, ``n ** -1`` is 0.5 for an int, ``True +
    True`` is 2 and ``np.True_ + np.True_`` is ``True``, where compiled code answers alike.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> job = NS(source="m", P=np.array([2.0]))
    >>> checked_as(job, {"k": 2.0}) == checked_as(NS(source="m", P=np.array([3.0])),
    ...                                           {"k": 3.0})
    True
    >>> checked_as(job) == checked_as(NS(source="m", P=np.array([0.0])))
    False
    """
    P = np.asarray(job.P, dtype=float)
    with np.errstate(invalid="ignore", divide="ignore"):
        classes = np.stack([np.sign(P), np.floor(np.log2(np.abs(P)) / 8), P != np.floor(P)])
    types = sorted((repr(k), type(v).__module__, type(v).__qualname__)  # (numpy's bool is
                   for k, v in (params or {}).items())                    # named bool too)
    return job.source, classes.tobytes(), tuple(types)


def where_they_part(blocks, times, mine, theirs) -> str:
    """Where a compiled piece's states ``mine`` first differ from Python's ``theirs`` (one
    column a time of ``times``): the time, and the blocks whose states differ there, whose
    compiled code answered otherwise or was fed by code that did ("" where they agree).
    Sharpest for a discrete run, where a step's update reads the states of the step
    before; an integrator's steps spread a difference over the states they couple.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> blocks = [NS(x0=0, system=NS(name="plant", nstates=2)),
    ...           NS(x0=2, system=NS(name="pi", nstates=1))]
    >>> where_they_part(blocks, [0.0, 0.1], np.zeros((3, 2)), [[0, 0], [0, 0], [0, 1e-16]])
    "; first at t = 0.1 s, in the state of 'pi'"
    """
    mine, theirs = np.asarray(mine, dtype=float), np.asarray(theirs, dtype=float)
    differ = (mine != theirs) & ~(np.isnan(mine) & np.isnan(theirs))
    columns = np.nonzero(differ.any(axis=0))[0]
    if not columns.size:
        return ""
    rows = set(np.nonzero(differ[:, columns[0]])[0].tolist())
    names = [repr(b.system.name) for b in blocks
             if rows & set(range(b.x0, b.x0 + b.system.nstates))]
    return f"; first at t = {times[columns[0]]:g} s, in the state of {', '.join(names)}"


class Pieces:
    """Piece sizes of about :data:`PIECE_SECONDS`, learnt from the pieces run so far.

    Examples
    --------
    >>> pieces = Pieces(first=10)
    >>> pieces.next()
    10
    >>> pieces.took(10, 0.001)
    >>> pieces.next() > 10
    True
    """

    def __init__(self, first=64):
        self.size = first

    def next(self) -> int:
        return int(self.size)

    def took(self, size: int, seconds: float) -> None:
        if size >= self.size:  # a full piece: aim at the target
            rate = size / max(seconds, 1e-6)
            self.size = int(min(max(rate * PIECE_SECONDS, 16), self.size * 8))


def interrupted(stop, response_so_far):
    """The ``KeyboardInterrupt`` ``stop`` that ended a run, carrying what was computed
    (``.response``). The same exception, its kind kept: a command that handles ``kill
    PID`` as a subclass of it (``controlkit reproduce``) still sees that kind.

    Examples
    --------
    >>> error = interrupted(KeyboardInterrupt(), "so far")
    >>> error.response, str(error)[:20]
    ('so far', 'the run was stopped;')
    """
    stop.response = response_so_far
    if not stop.args:
        stop.args = ("the run was stopped; what was computed is on this exception's `response`",)
    return stop


#: The clock the pieces and the rule are timed by (seconds, monotonic).
now = time.perf_counter


def quiet_numbers():
    """numpy's warnings of overflow and invalid results off while a module runs as Python:
    compiled code gives none, and the engine says itself where a state or an output went
    non-finite (a division by zero still warns, as in python-control).

    Examples
    --------
    >>> with quiet_numbers():
    ...     float(np.float64(1e308) * 10)
    inf
    """
    return np.errstate(over="ignore", under="ignore", invalid="ignore")
