"""The store: one folder of the user's where compiled code is kept, found by its content.

Compiled code comes from modules of the store, each a text numba compiles once and keeps
in its ``__pycache__``: a diagram's module (:mod:`.codegen`), the user functions compiled
for it (:mod:`.usercode`), the step machine and the instants' loop. A module's file name
is a digest of its text, of controlkit's source files it can hold and of the versions of
Python, numpy and scipy: an edit or an upgrade makes new modules, never a stale one. Files
are written whole (again if found changed); a compiled module has a record (``<name>.json``),
as has a user's function numba refused (later sessions run it as Python: :func:`refuse`).

Code is imported from the store only if the folder and numba's cache folder are the
user's own (:func:`controlkit._checks.not_own`), checked at each use and before any compile
or load (:func:`numba_checked`); else the engine compiles nothing and says why.
``CONTROLKIT_CACHE_DIR`` sets the folder (default ``~/.cache/controlkit/store``).
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import os
import sys as pysys
import threading
import time
import warnings
from pathlib import Path

import numpy as np
import scipy

from ... import _jit
from ..._checks import not_own, numba_cache_not_own

#: Where compiled code is kept (see the module's description).
CACHE_DIR = Path(os.environ.get("CONTROLKIT_CACHE_DIR")  # (set but empty: the default)
                 or Path.home() / ".cache" / "controlkit" / "store")


class StoreRefused(RuntimeError):
    """The store folder (or numba's cache folder) is not the user's own: nothing is
    compiled (the message says why).

    Examples
    --------
    >>> str(StoreRefused("the store /x is a link"))
    'the store /x is a link'
    """


def folder() -> Path:
    """The store folder, created if need be, after checking that it is the user's own.

    Raises
    ------
    StoreRefused
        When it, or numba's cache folder, is not the user's own (:mod:`controlkit._checks`).

    Examples
    --------
    >>> folder().is_dir()
    True
    """
    path = Path(os.path.abspath(CACHE_DIR))
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as error:
        raise StoreRefused(f"the store {path} cannot be created "
                           f"({error.strerror or error})") from None
    why = not_own(path) or numba_cache_not_own()
    if why is not None:
        raise StoreRefused(f"controlkit compiles nothing: {why} (set CONTROLKIT_CACHE_DIR "
                           f"to a folder of your own)")
    return path


def numba_checked():
    """numba (imported now if need be), the store and numba's cache folder checked as
    numba's next compile reads it (:func:`folder`): what every compile or load calls first.

    Examples
    --------
    >>> numba_checked().__name__ if _jit.available() else "numba"
    'numba'
    """
    module = _jit.numba_module()
    module.config.reload_config()  # (numba's settings as its next compile reads them)
    folder()
    return module


#: The source files of controlkit's whose code a compiled module can hold, by its kind.
SOURCES = {"machine": ("_jit.py", "engines/fast/rk/*.py"),
           "loop": ("_jit.py", "compat.py", "engines/fast/loops.py", "engines/fast/rk/*.py"),
           "other": ("_jit.py", "compat.py", "engines/**/*.py", "kernels/*.py")}
#: Digests of those files by kind (made once a process).
_OWN_SOURCE: dict = {}


def _own_source(kind: str) -> str:
    """A digest of the source files a module of ``kind`` can hold, by name and content
    (a reinstall of the same files keeps it). Made once a process, as the code it stands
    for was imported once."""
    if kind not in _OWN_SOURCE:
        root = Path(__file__).resolve().parents[2]
        patterns = SOURCES.get(kind, SOURCES["other"])
        digest = hashlib.sha256()
        for path in sorted({p for pattern in patterns for p in root.glob(pattern)}):
            digest.update(f"{path.relative_to(root)}\0".encode())
            digest.update(hashlib.sha256(path.read_bytes()).digest())
        _OWN_SOURCE[kind] = digest.hexdigest()
    return _OWN_SOURCE[kind]


def name_of(text: str, kind: str) -> str:
    """The module name of ``text`` in the store: ``<kind>_<digest>``.

    Examples
    --------
    >>> name_of("VALUE = 1\\n", "diagram").startswith("diagram_")
    True
    """
    versions = (pysys.version, np.__version__, scipy.__version__)
    key = "\0".join((text, _own_source(kind), *versions))
    return f"{kind}_{hashlib.sha256(key.encode()).hexdigest()[:24]}"


#: Held while a thread writes, imports or compiles a store module (threads share them):
#: re-entrant, as compiling a diagram imports its kernels' modules.
LOCK = threading.RLock()


def module_file(text: str, kind: str) -> Path:
    """The store file of ``text``, written (whole, atomically) unless it is there with that
    text; StoreRefused for a text Python would read otherwise (a coding line in it).

    Examples
    --------
    >>> module_file("VALUE = 1\\n", "diagram").read_text()
    'VALUE = 1\\n'
    """
    data = text.encode()
    if importlib.util.decode_source(data) != text:  # (names and values are data: never code)
        raise StoreRefused("a module text that Python would read as other code")
    path = folder() / f"{name_of(text, kind)}.py"
    with LOCK:  # (rewritten only if changed: numba's cache index keys on its date)
        if not path.exists() or path.read_bytes() != data:
            tmp = path.with_name(f".{path.stem}.{os.getpid()}.tmp")
            with open(tmp, "xb") as file:
                file.write(data)
            os.replace(tmp, path)
    return path


def import_module(path: Path, names: dict | None = None):
    """The module at ``path`` (a store file), run once a process with ``names`` in its
    namespace first, registered as ``controlkit_store_<name>`` in ``sys.modules`` (where
    numba's cache finds it by name); a module that fails to run is not kept.

    Examples
    --------
    >>> import_module(module_file("VALUE = 1\\n", "diagram")).VALUE
    1
    """
    name = f"controlkit_store_{Path(path).stem}"
    with LOCK:  # (another thread sees the module once it has run)
        module = pysys.modules.get(name)
        if module is None:
            folder()  # checked again at each import
            spec = importlib.util.spec_from_file_location(name, path)
            module = importlib.util.module_from_spec(spec)
            vars(module).update(names or {})
            pysys.modules[name] = module
            try:
                spec.loader.exec_module(module)
            except BaseException:
                del pysys.modules[name]
                raise
    return module


def _read_record(path: Path) -> dict:
    try:
        kept = json.loads(path.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return {}
    return kept if isinstance(kept, dict) else {}


def record(path: Path) -> dict | None:
    """The record of the store module at ``path``: None until it was compiled once.

    Examples
    --------
    >>> record(Path("/nonexistent/diagram_x.py")) is None
    True
    """
    kept = _read_record(path)
    return kept if kept and "refused" not in kept else None


@functools.lru_cache(maxsize=512)  # (asked at every compiled job made: read once)
def refusal(text: str, kind: str) -> str | None:
    """What numba said when it refused to compile the store module of ``text`` (with the
    numba installed now, :func:`refuse`), else None: a compile that fails is not tried."""
    try:
        kept = _read_record(folder() / f"{name_of(text, kind)}.py")
    except StoreRefused:
        return None
    said = kept.get("refused")
    return said if isinstance(said, str) and kept.get("numba") == _numba_version() else None


def refuse(path: Path, error: Exception) -> None:
    """Record numba's refusal (``error``) of the store module at ``path`` (:func:`refusal`).

    Examples
    --------
    >>> refuse(module_file("def f(x):\\n    return x.tolist()\\n", "user"),
    ...        TypeError("Unknown attribute 'tolist'"))
    >>> refusal("def f(x):\\n    return x.tolist()\\n", "user")
    "TypeError: Unknown attribute 'tolist'"
    """
    write_record(path, refused=numba_said(error), numba=_numba_version())
    refusal.cache_clear()


@functools.cache
def _numba_version() -> str | None:
    try:  # (without importing it)
        return importlib.metadata.version("numba")
    except importlib.metadata.PackageNotFoundError:
        return None


def compiled_before(text: str, kind: str) -> bool:
    """Whether the store module of ``text`` was compiled once (it has a record).

    Examples
    --------
    >>> compiled_before("VALUE = 3\\n", "diagram")
    False
    """
    return record(folder() / f"{name_of(text, kind)}.py") is not None


def write_record(path: Path, **values) -> None:
    """Write the record of the store module at ``path`` (whole or not at all).

    Examples
    --------
    >>> path = module_file("VALUE = 2\\n", "diagram")
    >>> write_record(path, seconds=1.5)
    >>> record(path)["seconds"]
    1.5
    """
    target = path.with_suffix(".json")
    tmp = target.with_name(f".{target.stem}.{os.getpid()}.tmp")
    try:
        tmp.write_text(json.dumps(values))
        os.replace(tmp, target)
    except OSError:
        pass
    _TIMES.clear()  # (read again by compile_times)


def numba_said(error) -> str:
    """The line of a compiler's error that says what went wrong.

    Examples
    --------
    >>> numba_said(TypeError("Failed in nopython mode\\nNo implementation of f"))
    'TypeError: No implementation of f'
    """
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    useful = [line for line in lines if not line.startswith(("Failed in", "During:"))]
    # an implementation's own refusal (controlkit.kernels.user_calls) says more than
    # numba's "No implementation of function ..." around it
    useful = [after.removeprefix("TypingError: ")
              for before, after in zip(lines, lines[1:], strict=False)
              if before.endswith("raised a specific error:")] + useful
    return f"{type(error).__name__}: {(useful or lines or [''])[0][:200]}"


def compile_entry(function, args, path: Path, blocks: int = 1):
    """``function`` compiled by numba for the types of ``args`` and kept in ``path``'s
    cache (loaded from it when it is there), its first compile recorded.

    Examples
    --------
    >>> path = module_file("def double(x):\\n    return 2 * x\\n", "diagram")
    >>> fn = compile_entry(import_module(path).double, (1.0,), path) if _jit.available() else 0
    >>> float(fn(2.0)) if fn else 4.0
    4.0
    """
    numba = numba_checked()
    dispatcher = numba.njit(cache=True, nogil=True)(function)
    start = time.perf_counter()
    dispatcher.compile(tuple(numba.typeof(a) for a in args))
    _record_compile(path, time.perf_counter() - start, blocks, function.__name__)
    return dispatcher


def _record_compile(path: Path, seconds: float, blocks: int, entry: str) -> None:
    """The record of a module's first compile (a diagram's read by :func:`compile_times`)."""
    if record(path) is None:
        write_record(path, seconds=round(seconds, 3), blocks=blocks, entry=entry)


def compile_functions(functions, signatures, path: Path, blocks: int = 1,
                      entry: str = "continuous"):
    """Each of ``functions`` (of the module at ``path``) compiled for its one signature
    as a C function (:func:`numba.cfunc`: the loop calls it by its address, and no
    Python wrapper is built, a fifth of a compile) and kept in ``path``'s cache (loaded
    from it when there): a diagram's evaluator as the instants' loop takes it. Like
    :func:`compile_entry` otherwise (``entry`` names the kind in the record).

    Examples
    --------
    >>> path = module_file("def twice(x):\\n    return 2.0 * x\\n", "diagram")
    >>> if _jit.available():
    ...     (twice,) = compile_functions([import_module(path).twice], ["float64(float64)"],
    ...                                  path, entry="twice")
    >>> float(twice(1.5)) if _jit.available() else 3.0
    3.0
    """
    numba = numba_checked()
    start = time.perf_counter()
    with _first_class_functions(numba):
        compiled = tuple(numba.cfunc(signature, cache=True, nogil=True)(
            _jit.python_function(f)) for f, signature in zip(functions, signatures,
                                                             strict=True))
    _record_compile(path, time.perf_counter() - start, blocks, entry)
    return compiled


#: Compile times per block read from the store's records, by entry point.
_TIMES: dict = {}


def compile_times(entry: str, more: int = 0) -> list[float]:
    """Seconds per block of the diagrams' modules compiled in this store for ``entry``
    (the latest 50): ``run_discrete`` (the discrete loop pasted in) or ``continuous``
    (the four functions the instants' loop takes), which differ per block; or seconds per
    line of the user's kernels (``kernel``), each counted ``more`` lines longer.

    Examples
    --------
    >>> all(t > 0 for t in compile_times("run_discrete"))
    True
    """
    if not _TIMES:
        try:
            paths = sorted(folder().glob("*.json"), key=os.path.getmtime)
        except (StoreRefused, OSError):
            paths = []
        for path in paths:
            kept = record(path.with_suffix(".py")) or {}
            seconds, size = kept.get("seconds"), kept.get("blocks", kept.get("lines"))
            if type(seconds) is float and type(size) is int and seconds > 0 and size > 0:
                _TIMES.setdefault(str(kept.get("entry")), []).append((seconds, size))
        _TIMES[None] = []  # read (an empty store included)
    return [seconds / (size + more) for seconds, size in _TIMES.get(entry, [])[-50:]]


_MACHINE: list = []

_MACHINE_TEXT = '''\
# generated by controlkit.engines.fast.store: the Runge-Kutta step machine, kept compiled
from controlkit.engines.fast.rk.machine import machine as _machine


def machine(t_eval_at, m, y_eval_at, floats_at, floats_size, stages_at, n, ints_at):
    return _machine(t_eval_at, m, y_eval_at, floats_at, floats_size, stages_at, n, ints_at)
'''


#: The step machine's C signature: the row to evaluate (or FINISHED) from the addresses and
#: sizes of its arrays (see :func:`controlkit.engines.fast.rk.machine.machine`).
MACHINE_SIGNATURE = "intp(uintp, intp, uintp, uintp, intp, uintp, intp, uintp)"


def step_machine():
    """The integrator's step machine (:func:`controlkit.engines.fast.rk.machine.machine`)
    as a C function, kept in the store: a diagram's module calls it through its address,
    so that compiling a module never compiles, nor links, the machine again.

    Examples
    --------
    >>> step_machine() is step_machine() if _jit.available() else True
    True
    """
    with LOCK:
        if not _MACHINE:
            numba = numba_checked()
            _MACHINE.append(_kept_once(
                _MACHINE_TEXT, "machine", "the integrator's step machine",
                MACHINE_COMPILE_SECONDS,
                lambda module: numba.cfunc(MACHINE_SIGNATURE, cache=True,
                                           nogil=True)(module.machine)))
    return _MACHINE[0]


def _kept_once(text: str, kind: str, what: str, seconds: float, compile_it):
    """``compile_it(module)`` of the store module ``text``: loaded from numba's cache, or
    compiled now, said first and recorded after."""
    path = module_file(text, kind)
    module = import_module(path)
    if record(path) is None:
        _say(f"compiling {what} (once after an install or an upgrade: about {seconds:.0f} s)")
    start = time.perf_counter()
    compiled = compile_it(module)
    _record_compile(path, time.perf_counter() - start, 1, kind)
    return compiled


_LOOPS: dict = {}

_LOOP_TEXT = '''\
# generated by controlkit.engines.fast.store: the instants' loop, kept compiled
from controlkit.engines.fast.loops import instants_loop as _loop


def instants_loop(evaluate, update, outputs, derivatives, machine, rhs_args, times, results,
                  state, buffers, solver, ctrl, status):
    _loop(evaluate, update, outputs, derivatives, machine, rhs_args, times, results, state,
          buffers, solver, ctrl, status)
'''


def instants_loop(argument_types):
    """The instants' loop of a run with continuous states
    (:func:`controlkit.engines.fast.loops.instants_loop`) compiled for
    ``argument_types`` (the diagram's four functions among them as numba's
    ``FunctionType``, see :func:`~controlkit.engines.fast.loops.evaluator_signatures`),
    kept in the store: every diagram's functions are handed to the same compiled loop.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit import input_output_response
    >>> loop = ct.interconnect([ct.ss(-1, 1, 1, 0, name="lag", inputs="u", outputs="y")],
    ...                        inputs="u", outputs="y")  # (a continuous run compiled)
    >>> response = input_output_response(loop, [0.0, 0.5, 1.0], 1.0, compile=True)
    >>> bool(_LOOPS) == (response.engine_mode == "compiled")
    True
    """
    with LOCK:
        if argument_types not in _LOOPS:
            numba = numba_checked()

            def compile_it(module):
                with _first_class_functions(numba):
                    return numba.njit(numba.types.none(*argument_types), cache=True,
                                      nogil=True)(module.instants_loop)

            _LOOPS[argument_types] = _kept_once(_LOOP_TEXT, "loop", "the integrator's loop",
                                                LOOP_COMPILE_SECONDS, compile_it)
    return _LOOPS[argument_types]


@contextlib.contextmanager
def _first_class_functions(numba):
    """numba's warning that its first-class functions (how one compiled loop serves every
    diagram) are experimental, kept from the user: it is about our choice, not their code."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", numba.NumbaExperimentalFeatureWarning)
        yield


#: About how long the instants' loop takes to compile (measured: 5-13 s on 2 cores).
LOOP_COMPILE_SECONDS = 8.0
#: About how long the step machine takes to compile (measured: 30 s on 2 cores).
MACHINE_COMPILE_SECONDS = 30.0


def integrator_to_compile() -> float:
    """About how long compiling the step machine and the instants' loop takes, where not
    compiled yet (in this process, or in the store).

    Examples
    --------
    >>> integrator_to_compile() in (0.0, MACHINE_COMPILE_SECONDS, LOOP_COMPILE_SECONDS,
    ...                             MACHINE_COMPILE_SECONDS + LOOP_COMPILE_SECONDS)
    True
    """
    return sum(seconds for done, text, kind, seconds in (
        (_MACHINE, _MACHINE_TEXT, "machine", MACHINE_COMPILE_SECONDS),
        (_LOOPS, _LOOP_TEXT, "loop", LOOP_COMPILE_SECONDS))
        if not done and not compiled_before(text, kind))


def _say(message: str) -> None:
    """One line on standard error for a wait of seconds the user did not ask for."""
    print(f"controlkit: {message}", file=pysys.stderr, flush=True)
