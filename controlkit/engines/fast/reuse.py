"""Using a prepared :class:`~.run.Job` again when a diagram is called again unchanged.

A notebook calls the same diagram again and again. :func:`~.run.prepare` reads every
user function's outside values afresh, writes their text and lays out the diagram's
tables: a good part of a short call. The :func:`job_key` of a call holds everything that
work depends on, read now; when it is the key of the diagram's last job, that job is the
one :func:`~.run.prepare` would make again.

What the key holds (anything else, or a value it cannot hold exactly, gives no key, and
the job is made afresh). Numbers are held by their bits (``0.0`` and ``-0.0`` differ),
arrays by their contents (a digest above 4 kB):

- the diagram's wiring: its connection, input and output maps and its rate;
- each block's sizes and rate, and
  - a controlkit block: the block, its kernels, what they run
    (:func:`~.codegen.kernel_identity`) and their parameter vector;
  - an LTI block: its ``A``, ``B``, ``C``, ``D`` (changed in place or not);
  - a user's ``nlsys``: its functions, their :class:`~controlkit.engines.source.Plan`
    (the same plan object only while everything it read from outside is unchanged:
    :meth:`~controlkit.engines.source.Plan.valid`), the contents of the arrays, lists
    and tuples those plans read, and the parameters python-control hands the block;
  - a sampled block (RK4): its substeps and the key of the block it samples;
- whether the job runs compiled or as Python.
"""

from __future__ import annotations

import hashlib

import control as ct
import numpy as np

from ...blocks.contract import KernelBlock
from ...blocks.sampling import SampledSystem
from .. import _KEPT_JOBS, _keep_on, _kept_on, source
from . import store
from .codegen import kernel_identity
from .tiers import _local_params


class _Unknown(Exception):
    """A part of the key that cannot be held exactly: no key."""


class _Same:
    """An object in a key: equal to the very same object only (and kept alive, so that
    no other object can take its place)."""

    __slots__ = ("obj",)

    def __init__(self, obj):
        self.obj = obj

    def __eq__(self, other):
        return isinstance(other, _Same) and self.obj is other.obj

    __hash__ = None


def _value(value):
    """``value`` as an exactly comparable tuple (raises _Unknown): numbers by their bits
    (``0.0`` and ``-0.0`` differ, a NaN equals itself), arrays by their contents."""
    if value is None or isinstance(value, bool | int | str):
        return (type(value), value)
    if isinstance(value, float):
        return (type(value), value.hex())
    if isinstance(value, complex):
        return (type(value), value.real.hex(), value.imag.hex())
    if isinstance(value, np.generic):
        if value.dtype.kind not in "biufc":
            raise _Unknown
        return (type(value), value.tobytes())
    if isinstance(value, np.ndarray):
        if value.dtype.kind not in "biufc":
            raise _Unknown
        return (np.ndarray, value.dtype.str, value.shape, _bytes(value))
    if isinstance(value, list | tuple):
        return (type(value), tuple(_value(v) for v in value))
    raise _Unknown


#: Arrays up to this many bytes are kept in a key as they are; larger ones by a digest.
_DIGEST_ABOVE = 4096


def _bytes(array):
    data = np.ascontiguousarray(array)
    if data.nbytes <= _DIGEST_ABOVE:
        return data.tobytes()
    return hashlib.blake2b(memoryview(data).cast("B"), digest_size=20).digest()


def _contents(value):
    """What can change inside ``value`` without changing its identity."""
    if isinstance(value, np.ndarray | list | tuple):
        return _value(value)
    return None


def _params(local: dict):
    return tuple((key, _value(v)) for key, v in local.items())


def _user(block, local, compiled):
    """The key of a user's ``nlsys`` given the parameters it is handed (run as Python:
    its functions and parameters; compiled: also what their plans read from outside)."""
    if not compiled:  # called as they are: the same functions, the same parameters
        return (_Same(block), _Same(block.outfcn), _Same(block.updfcn), _params(local))
    parts = []
    for fn in (block.outfcn, block.updfcn if block.nstates else None):
        if fn is None:
            parts.append(None)
            continue
        try:
            plan = source.plan_function(fn)
        except source.NotCompilable:
            raise _Unknown from None
        if plan.why_not() is not None:
            raise _Unknown
        inside = tuple(_contents(v) for each in plan.tree() for v in each.frozen.values())
        read = tuple(_contents(v) for each in plan.tree() for _, v in each.checks)
        parts.append((_Same(fn), _Same(plan), inside, read))
    return (_Same(block), tuple(parts), _params(local))


def _rate(dt):
    return dt if dt is None or dt is True else _value(float(dt))


def _own(block):
    """A controlkit block: its kernels (made when it was built), what they run (a global
    they read may change between calls) and their parameters."""
    kernels = block.kernels
    return (_Same(block), _Same(kernels), _value(kernels.params), tuple(
        kernel_identity(f) for f in (kernels.output, kernels.update) if f is not None))


def _kernels(sys, block, params, compiled):
    if isinstance(block, KernelBlock):
        if block.kernels is None:
            raise _Unknown
        return _own(block)
    if isinstance(block, ct.StateSpace):
        return (_Same(block), *(_value(np.asarray(m)) for m in (block.A, block.B, block.C,
                                                             block.D)))
    local = _local_params(sys, block, params)
    if isinstance(block, SampledSystem):
        inner = block.continuous
        if block.method != "rk4":
            raise _Unknown
        if isinstance(inner, KernelBlock) and inner.kernels is not None:
            within = _own(inner)
        elif isinstance(inner, ct.InterconnectedSystem | KernelBlock):
            raise _Unknown
        else:
            within = _user(inner, {**inner.params, **local}, compiled)
        return (_Same(block), _rate(block.dt), block.substeps, within)
    if isinstance(block, ct.InterconnectedSystem) or not isinstance(block, ct.NonlinearIOSystem):
        raise _Unknown
    return _user(block, local, compiled)


def job_key(sys, params=None, compiled=False):
    """Everything :func:`~.run.prepare` reads of ``sys`` and ``params`` for a job run
    ``compiled`` or not, read now, as a comparable tuple; None when some of it cannot be
    held exactly.

    Examples
    --------
    >>> import control as ct
    >>> sys = ct.nlsys(lambda t, x, u, params: -params["a"] * x + u, None, inputs=1,
    ...                states=1, outputs=1, params={"a": 1.0}, name="lag")
    >>> loop = ct.interconnect([sys], inputs="u[0]", outputs="y[0]")
    >>> job_key(loop, {"a": 2.0}) == job_key(loop, {"a": 2.0})
    True
    >>> job_key(loop, {"a": 2.0}) == job_key(loop, {"a": 3.0})
    False
    >>> job_key(loop, {"a": object()}) is None  # not a value it can compare exactly
    True
    """
    if not isinstance(sys, ct.InterconnectedSystem):
        return None
    try:
        blocks = tuple(((b.nstates, b.ninputs, b.noutputs, _rate(b.dt)),
                        _kernels(sys, b, params, compiled)) for b in sys.syslist)
        wiring = (_rate(sys.dt), _rate(getattr(sys, "base_period", None)),
                  *(_value(np.asarray(m, dtype=float))
                    for m in (sys.connect_map, sys.input_map, sys.output_map)))
    except Exception:  # noqa: BLE001 - _Unknown, or anything prepare finds and says so
        return None
    return (str(store.CACHE_DIR), bool(compiled), wiring, blocks)


def reused(sys, key):
    """The job kept for ``sys`` under ``key``, else None.

    Examples
    --------
    >>> reused(object(), None) is None
    True
    """
    if key is None:
        return None
    key_kept, job = (_kept_on(sys, _KEPT_JOBS) or {}).get(key[1], (None, None))
    if job is None or job.sys is not sys or key_kept != key:
        return None
    return job


def keep(sys, key, job) -> None:
    """Keep ``job`` for ``sys`` under ``key`` (one job run as Python and one compiled).

    The job is kept on the diagram itself: it lives as long as the diagram does, and a
    copy or a pickle of the diagram (for a worker process) carries none.

    Examples
    --------
    >>> keep(object(), None, None)
    """
    if key is None:
        return
    jobs = _kept_on(sys, _KEPT_JOBS)
    if jobs is None:
        jobs = {}
        _keep_on(sys, _KEPT_JOBS, jobs)
    jobs[key[1]] = (key, job)
