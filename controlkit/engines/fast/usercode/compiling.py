"""Loading a kernel module with numba, and trusting it only once it agrees with the
user's Python function at trial points; the Python fallback kernel.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import os
import sys as pysys
import types as pytypes
import warnings
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .... import _jit
from ...._quiet import IMPORTING
from ....kernels import user_calls
from ...source import NotCompilable, Plan, plan_function
from .layout import ParamLayout
from .writer import code_digest, kernel_source

#: The source of what kernels call (clip, store, missing_parameter): numba's cache refers
#: to their compiled code by their module, so a kernel's name changes with it and a cache
#: written by another version of them is never loaded.
_CALLS_SOURCE = Path(user_calls.__file__).read_text()


#: The start of a user kernel module's name (and of the line of a diagram's module that
#: imports it: ``from controlkit_user_<hash> import kernel as kernel_<i>``).
USER_MODULE_PREFIX = "controlkit_user_"


def load_kernel(source: str, folder: Path):
    """Write ``source`` as an importable module in ``folder``; its ``kernel``, compiled.

    Every function of the module is compiled with numba (cached on disk), the user's
    functions inlined into ``kernel``. Loading is
    all or nothing: a module that fails to load is not left behind in ``sys.modules``.
    Returns ``(kernel, module_name)``.

    Raises
    ------
    NotCompilable
        When the module cannot be loaded.

    Examples
    --------
    >>> import tempfile
    >>> src = kernel_source(lambda t, x, u, params: 3.0 * u, {})
    >>> kernel, name = load_kernel(src, Path(tempfile.mkdtemp()))
    >>> kernel(0.0, np.zeros(0), np.ones(1), np.zeros(0), np.empty(1)).tolist()
    [3.0]
    """
    key = hashlib.sha256((source + str(_jit.HAVE_NUMBA) + str(_jit.CACHE_FORMAT)
                          + _COMPILE_OPTIONS + _CALLS_SOURCE).encode()).hexdigest()[:20]
    name = f"{USER_MODULE_PREFIX}{key}"
    path = folder / f"{name}.py"
    if not path.exists():  # keep an existing file's date: numba's cache keys on it
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    try:
        return import_user_module(path).kernel, name
    except Exception as error:  # the generated module does not load: nothing is kept
        raise NotCompilable(f"{_NOT_LOADED} ({type(error).__name__}: "
                            f"{error})") from None


def import_user_module(path: Path):
    """Import the user kernel module at ``path`` (see :func:`load_kernel`), its functions
    compiled as the engine calls them; it stays in ``sys.modules`` only if it loads.

    A diagram's module imports its user kernels by name: a process that imports it
    without having made them (the background compiler, :mod:`..background`) loads them
    here first, or it would find plain Python functions numba cannot call.

    Examples
    --------
    >>> import tempfile
    >>> src = kernel_source(lambda t, x, u, params: 2.0 * u, {})
    >>> _, name = load_kernel(src, Path(tempfile.mkdtemp()))
    >>> module = import_user_module(Path(pysys.modules[name].__file__))
    >>> module.kernel(0.0, np.zeros(0), np.ones(1), np.zeros(0), np.empty(1)).tolist()
    [2.0]
    """
    with IMPORTING:  # never seen half-made by another thread
        return _import_user_module(path)


def _import_user_module(path: Path):
    name = path.stem
    if name in pysys.modules:
        return pysys.modules[name]
    if str(path.parent) not in pysys.path:
        pysys.path.append(str(path.parent))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    pysys.modules[name] = module  # numba's disk cache re-imports it by name
    try:
        spec.loader.exec_module(module)
        if _jit.HAVE_NUMBA:
            defined = [n for n, v in vars(module).items()
                       if isinstance(v, pytypes.FunctionType) and v.__module__ == name]
            for n in defined:
                # the user's functions and helpers are inlined into the kernel by numba:
                # called as separate functions, reads of p cost 50 ns a call more
                inline = "never" if n == "kernel" else "always"
                setattr(module, n, _jit.numba.njit(cache=True, inline=inline,
                                                   error_model="numpy")(getattr(module, n)))
        module.kernel  # noqa: B018 - a module without its kernel does not load
    except Exception:
        del pysys.modules[name]
        raise
    return module


#: How the modules' functions are compiled, part of their names: numba's disk cache would
#: otherwise hand back code compiled with other options from the same source.
_COMPILE_OPTIONS = "inline=always,error_model=numpy"


class CompiledKernel(NamedTuple):
    """A user function compiled: ``kernel(t, x, u, p, out)``, and ``pack(values) -> p``.

    Examples
    --------
    >>> import tempfile
    >>> f = lambda t, x, u, params: [params["k"] * u[0]]
    >>> compiled = compiled_kernel(f, {"k": 2.0}, Path(tempfile.mkdtemp()), 1, 0, 1)
    >>> compiled.pack({"k": 5.0}).tolist(), compiled.layout.size
    ([5.0], 1)
    """

    kernel: object
    pack: object
    module: str
    layout: ParamLayout


def _trial_points(n_x, n_u, trials):
    """The run's own points first, then all zeros, then three random ones."""
    points = [(float(t), np.array(x, dtype=float).reshape(-1), np.array(u, dtype=float)
               .reshape(-1)) for t, x, u in trials or ()]
    points = [(t, x, u) for t, x, u in points if x.size == n_x and u.size == n_u]
    points.append((0.0, np.zeros(n_x), np.zeros(n_u)))
    return points + [(t, x.copy(), u.copy()) for t, x, u in _random_points(n_x, n_u)]


@functools.lru_cache(maxsize=64)
def _random_points(n_x, n_u):
    """Three fixed random points (a generator made at each call cost 40 us)."""
    rng = np.random.default_rng(0)
    return tuple((t, rng.uniform(0.1, 0.9, n_x), rng.uniform(0.1, 0.9, n_u))
                 for t in (0.0, 0.37, 1.9))


def _is_compile_error(error) -> bool:
    if isinstance(error, RecursionError):  # a recursive helper, inlined without end
        return True
    if not _jit.HAVE_NUMBA:
        return False
    from numba.core.errors import NumbaError

    return isinstance(error, NumbaError)


def _first_line(error) -> str:
    message = str(error).strip().splitlines()
    first = next((m for m in message if m.strip() and "TypingError" not in m
                  and "Failed in nopython" not in m), "")
    return first.strip()[:200]


def compiled_kernel(fn, values: dict, folder: Path, n_out: int, n_x: int, n_u: int, *,
                    layout: ParamLayout | None = None, trials=(),
                    plan: Plan | None = None) -> CompiledKernel:
    """``fn`` compiled for the types of ``values``, checked against ``fn`` at trial points.

    The compiled kernel is compared with ``fn`` itself at ``trials`` (``(t, x, u)``
    points, such as the run's initial state and inputs), at zero and at random points;
    it must agree wherever ``fn`` can be evaluated, and ``fn`` must be evaluable at one
    point at least. ``layout`` (the block's, shared by its functions) and ``plan`` (of
    ``fn``) are made here when not given.

    Raises
    ------
    NotCompilable
        With the reason, when it cannot be compiled or does not agree with ``fn``.

    Examples
    --------
    >>> import tempfile
    >>> f = lambda t, x, u, params: [x[0] + params.get("k", 2.0) * u[0]]
    >>> compiled = compiled_kernel(f, {"k": 3.0}, Path(tempfile.mkdtemp()), 1, 1, 1)
    >>> p = compiled.pack({"k": 0.5})
    >>> compiled.kernel(0.0, np.ones(1), np.ones(1), p, np.empty(1)).tolist()
    [1.5]
    """
    plan = plan or plan_function(fn)
    why = plan.why_not()
    if why is not None:
        raise NotCompilable(why)
    layout = layout or ParamLayout.of([plan], values)
    p = layout.pack(values)
    points = _trial_points(n_x, n_u, trials)
    try:  # the function's text with what it reads from outside frozen in: its identity
        identity = kernel_source(fn, values, False, layout=layout, exact=False, plan=plan)
    except NotCompilable:
        identity = None
    # the values' Python types too: a list and an array of the same numbers pack alike,
    # and Python's answer differs (``v * 2`` repeats a list)
    outcome = identity and (identity, layout.entries, _kinds(values, layout), p.tobytes(),
                            n_out, n_x, n_u,
                            tuple((t, x.tobytes(), u.tobytes()) for t, x, u in points))
    # the code that runs is part of the key: the text read may not be it (a module file
    # edited since its import), and the check is what tells them apart
    codes = tuple(part.function.__code__ for part in plan.tree())
    key = outcome and (outcome, codes)
    known = _CHECKED.get(key) if key else None
    record = _Record(outcome, codes, folder) if key and known is None else None
    if record is not None:  # checked by an earlier process: its outcome, from disk
        known = record.read(layout)
        if known is not None:
            _remember(key, known)
    if known is not None:  # checked at these very points with these values: as then
        if isinstance(known, str):
            raise NotCompilable(known)
        return known
    try:
        result = _checked_kernel(fn, values, folder, n_out, n_x, n_u, layout, plan, p,
                                 points)
    except NotCompilable as why:
        _remember(key, str(why))
        if record is not None and not str(why).startswith(_NOT_LOADED):
            record.write({"why": str(why)})
        raise
    _remember(key, result)
    if record is not None:
        record.write({"module": result.module})
    return result


def _kinds(values: dict, layout: ParamLayout) -> tuple:
    """The Python types of the parameters the layout reads (of a list's or a tuple's
    items as well)."""
    kinds = []
    for entry in layout.entries:
        value = values.get(entry.key)
        kind = type(value).__qualname__
        if isinstance(value, list | tuple):
            kind += repr(sorted({type(item).__qualname__ for item in value}))
        kinds.append(kind)
    return tuple(kinds)


#: Kernels checked in this process by what decides the check's outcome (the function's
#: text with its outside reads frozen, the parameters, the trial points): a notebook's
#: repeated call checked the same kernel again, 0.4 ms a function a call (a third of a
#: short continuous run of the car in benchmarks/bench_continuous.py).
_CHECKED: dict = {}


def _remember(key, outcome) -> None:
    if key:
        if len(_CHECKED) >= 4096:  # a long sweep over initial states: start again
            _CHECKED.clear()
        _CHECKED[key] = outcome


#: The start of the reason given when a kernel module does not load: a passing cause (a
#: full disk, a folder being cleaned), never kept on disk as the kernel's outcome.
_NOT_LOADED = "its compiled module does not load"


class _Record:
    """The outcome of a kernel's check kept on disk, for later processes.

    Checking a kernel loads its compiled code from numba's cache to run it at the trial
    points, about 7 ms a function: most of a notebook's first call of a short run (its
    diagram's module, itself loaded from the cache, has the kernels compiled into it). The
    outcome depends on ``outcome`` (the function's text with its outside reads frozen, the
    parameters and their types, the trial points), on numba's, numpy's and Python's
    versions and numba's settings (``NUMBA_DISABLE_JIT`` runs the "compiled" kernel as
    Python, which always agrees), and on the
    function really being the text read from its file: the contents of ``codes`` (its
    code and its helpers') are part of the record's name, so a file edited since its
    import is checked again, against the function that runs.
    """

    FORMAT = 1

    def __init__(self, outcome, codes, folder: Path):
        numba = ("none",) if not _jit.HAVE_NUMBA else (
            _jit.numba.__version__, _jit.numba.config.DISABLE_JIT,  # (Python "compiled")
            _jit.numba.config.BOUNDSCHECK)
        digest = hashlib.sha256(repr((self.FORMAT, outcome, numba, np.__version__,
                                      pysys.version, _COMPILE_OPTIONS, _CALLS_SOURCE,
                                      _jit.CACHE_FORMAT)).encode())
        for code in codes:
            code_digest(code, digest)
        self.folder = folder
        self.path = folder / "checked" / f"{digest.hexdigest()[:32]}.json"

    def read(self, layout: ParamLayout):
        """The kept outcome: a :class:`CompiledKernel`, the reason it is not compilable
        (a ``str``), or None when there is none (or it cannot be used)."""
        try:
            kept = json.loads(self.path.read_text())
        except (OSError, ValueError):
            return None
        if isinstance(kept.get("why"), str):
            return kept["why"]
        module = kept.get("module")
        if not (isinstance(module, str) and module.startswith(USER_MODULE_PREFIX)):
            return None
        path = self.folder / f"{module}.py"
        if not path.exists():
            return None
        try:
            kernel = import_user_module(path).kernel
        except Exception:  # noqa: BLE001 - checked again, as if never kept
            return None
        return CompiledKernel(kernel, layout.pack, module, layout)

    def write(self, outcome: dict) -> None:
        """Keep ``outcome`` (written whole or not at all; a failure to write is ignored)."""
        try:
            self.path.parent.mkdir(exist_ok=True)
            tmp = self.path.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps(outcome))
            os.replace(tmp, self.path)
        except OSError:
            pass


def _checked_kernel(fn, values, folder, n_out, n_x, n_u, layout, plan, p, points):
    """:func:`compiled_kernel`'s work: compile, then compare with ``fn`` at ``points``."""
    attempts = [(False, True), (False, False)]
    if layout.has_ints:
        attempts += [(True, True), (True, False)]
    failure = None
    for exact, direct in attempts:
        try:
            source = kernel_source(fn, values, direct, layout=layout, exact=exact, plan=plan)
        except NotCompilable:
            if direct:
                continue  # not every return is a literal list: copy the result instead
            raise
        kernel, name = load_kernel(source, folder)
        ours = []
        try:
            for t, x, u in points:
                try:
                    ours.append(kernel(t, x.copy(), u.copy(), p, np.full(n_out, np.nan)))
                except Exception as error:  # noqa: BLE001 - compared with Python's below
                    if _is_compile_error(error):
                        raise
                    ours.append(error)
        except Exception as error:  # noqa: BLE001 - numba's typing errors
            failure = failure or error
            continue
        break
    else:
        raise NotCompilable(f"numba cannot compile it: {_first_line(failure)}")
    compared = 0
    for (t, x, u), mine in zip(points, ours, strict=True):
        try:  # trial points of ours: what numpy or the function warns there is not the user's
            with np.errstate(all="ignore"), warnings.catch_warnings():
                warnings.simplefilter("ignore")
                ref = np.asarray(fn(t, x.copy(), u.copy(), dict(values)),
                                 dtype=float).reshape(-1)
        except Exception:  # noqa: BLE001 - undefined there: not a point to compare at
            continue
        if ref.shape != (n_out,):
            raise NotCompilable(f"it returns {ref.size} values, the block declares {n_out}")
        if isinstance(mine, Exception):
            raise NotCompilable(f"its compiled version raises {type(mine).__name__} at "
                                f"t = {t:g}, where Python's does not")
        if not np.allclose(mine, ref, rtol=1e-12, atol=1e-12, equal_nan=True):
            raise NotCompilable(f"its compiled version differs from it at t = {t:g} "
                                f"(x = {np.round(x, 6).tolist()}, u = {np.round(u, 6).tolist()})")
        compared += 1
    if not compared:
        raise NotCompilable("it raises at every trial point, so its compiled version could "
                            "not be checked against it")
    return CompiledKernel(kernel, layout.pack, name, layout)


def python_kernel(fn, values: dict):
    """A kernel ``(t, x, u, p, out)`` calling the user's ``fn`` from Python.

    Examples
    --------
    >>> k = python_kernel(lambda t, x, u, params: params["a"] * x, {"a": 2.0})
    >>> k(0.0, np.ones(1), np.zeros(0), None, np.empty(1)).tolist()
    [2.0]
    """
    params = dict(values)

    def kernel(t, x, u, p, out):
        out[:] = np.asarray(fn(t, x, u, params), dtype=float).reshape(-1)
        return out

    return kernel
