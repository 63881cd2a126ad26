"""Loading a diagram's module: compiled from the disk cache, compiled anew, or as Python.

A diagram's module (:mod:`.codegen`) is written into :data:`CACHE_DIR` under a name
made from its text and its kernels' source, and imported from there; numba caches its
compiled code next to it, keyed by that file, so a later process loads it in
milliseconds. Compiling it takes a second or two, so a diagram whose module is not in
the cache yet runs on the generic driver (:mod:`.driver`) meanwhile, and a separate
process compiles the module into the cache (:func:`compile_in_background`): the
caller's runs go on at once, and later runs of the wiring (in this process or another)
load it compiled.

A module with a block on the python tier (a function that cannot be compiled) runs as
plain Python, calling the compiled kernels of the other blocks.
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.util
import os
import shutil
import stat
import subprocess
import sys as pysys
import tempfile
import warnings
from pathlib import Path
from types import FunctionType, SimpleNamespace

from ... import _jit
from ..._quiet import IMPORTING

#: Where diagrams' modules and compiled user functions are written (and numba caches
#: them). Code is imported from there, so it is used only when it is the user's own: see
#: :func:`cache_folder`.
CACHE_DIR = Path(os.environ.get("CONTROLKIT_CACHE_DIR",
                                Path.home() / ".cache" / "controlkit" / "engine"))

#: Whether a diagram's module is compiled by a background process while the driver runs
#: (environment variable ``CONTROLKIT_BACKGROUND_COMPILE=0`` switches it off: the module
#: is then compiled in the caller, the first time the wiring runs long enough).
BACKGROUND_COMPILE = os.environ.get("CONTROLKIT_BACKGROUND_COMPILE", "1") not in ("0", "")

#: The evaluator's functions and the entry points of a diagram's module.
EVALUATOR = ("evaluate", "outputs", "update", "derivatives", "rhs")
ENTRY_POINTS = ("run_discrete", "run_continuous")

#: Modules loaded in this process, by source text.
_LOADED: dict[str, object] = {}

#: Background compilations started in this process, by module path.
_BACKGROUND: dict[str, subprocess.Popen] = {}


#: Why each folder asked for was refused (None: it is the user's own), checked once.
_REFUSED: dict[Path, str | None] = {}

#: This process's private folder, made when the configured one is refused.
_PRIVATE: list[Path] = []


def cache_folder() -> Path:
    """:data:`CACHE_DIR` when it is the user's own, else a private folder for this process.

    The generated modules in this folder are imported and run, so whoever can write
    into it decides what code runs. It is used only if it is a folder owned by the
    user, that nobody else can write into, inside folders that nobody else can
    rename it out of (each owned by the user or root, and not writable by others
    unless sticky, as ``/tmp`` is). When it fails that check or cannot be created,
    compiled code is kept for this process only, in a folder made by
    :func:`tempfile.mkdtemp` (owner only, removed at exit), and a warning says why.

    Examples
    --------
    >>> folder = cache_folder()
    >>> folder.is_dir(), _not_own(folder) is None
    (True, True)
    """
    folder = Path(CACHE_DIR)
    if folder not in _REFUSED:
        try:
            folder.mkdir(mode=0o700, parents=True, exist_ok=True)
            _REFUSED[folder] = _not_own(folder)
        except OSError as error:
            _REFUSED[folder] = f"it cannot be created ({error.strerror or error})"
        if _REFUSED[folder] is not None:
            warnings.warn(f"controlkit does not use the compiled-code cache {folder}: "
                          f"{_REFUSED[folder]}; compiled code is kept for this process only "
                          f"(set CONTROLKIT_CACHE_DIR to a folder of your own)", stacklevel=2)
    if _REFUSED[folder] is None:
        return folder
    if not _PRIVATE:
        private = Path(tempfile.mkdtemp(prefix="controlkit-engine-"))
        atexit.register(shutil.rmtree, private, ignore_errors=True)
        _PRIVATE.append(private)
    return _PRIVATE[0]


def _not_own(folder: Path) -> str | None:
    """Why ``folder`` is not the user's own (None when it is), as :func:`cache_folder` asks.

    Group write is allowed where the group is the user's private group (the user's own
    primary group, with no other members), as a umask of 002 leaves folders.

    Examples
    --------
    >>> import tempfile
    >>> shared = Path(tempfile.mkdtemp())
    >>> shared.chmod(0o777)
    >>> _not_own(shared).endswith("can be written by others (mode 777)")
    True
    """
    if not hasattr(os, "getuid"):  # Windows: the profile folder's ACLs decide
        return None
    uid = os.getuid()
    link = os.lstat(folder)
    if stat.S_ISLNK(link.st_mode) and link.st_uid not in (uid, 0):
        return f"it is a link owned by another user (uid {link.st_uid})"
    info = os.stat(folder)
    if not stat.S_ISDIR(info.st_mode):
        return "it is not a folder"
    if info.st_uid != uid:
        return f"it is owned by another user (uid {info.st_uid})"
    if _writable_by_others(info):
        return f"it can be written by others (mode {stat.S_IMODE(info.st_mode):o})"
    for parent in Path(os.path.realpath(folder)).parents:
        info = os.stat(parent)
        if info.st_uid not in (uid, 0):
            return f"{parent} is owned by another user (uid {info.st_uid})"
        if _writable_by_others(info) and not info.st_mode & stat.S_ISVTX:
            return (f"{parent} can be written by others (mode "
                    f"{stat.S_IMODE(info.st_mode):o}), who could replace the folder")
    return None


def _writable_by_others(info) -> bool:
    if info.st_mode & stat.S_IWOTH:
        return True
    if not info.st_mode & stat.S_IWGRP:
        return False
    try:  # the user's private group (umask 002) is not "others"
        import grp

        group = grp.getgrgid(info.st_gid)
        return not (info.st_gid == os.getgid() and not group.gr_mem)
    except (ImportError, KeyError):
        return True


#: The engine's modules whose code numba pastes into a diagram's module or the driver:
#: their source goes into the compiled modules' names (numba's cache knows a function by
#: its own file only, and would load code compiled from an older version of these).
PASTED_IN = ("controlkit.engines.fast.loops", "controlkit.engines.fast.rk",
             "controlkit.engines.fast.views", "controlkit.engines.fast.entries",
             "controlkit.engines.fast.plan", "controlkit.kernels.common",
             "controlkit.engines.fast.loader")  # how compiled() wraps the module's functions


def _sources(modules) -> str:
    texts = []
    for name in modules:
        spec = importlib.util.find_spec(name)
        if spec.submodule_search_locations:  # a package: every module in it
            folder = Path(spec.origin).parent
            texts += [_text(p) for p in sorted(folder.glob("*.py"))]
        else:
            texts.append(_text(Path(spec.origin)))
    return "".join(texts)


#: Files' texts read by :func:`_sources`, by path, with the size and date they had.
_TEXTS: dict[Path, tuple] = {}


def _text(path: Path) -> str:
    """``path``'s text, read again only when its size or date changed (a new wiring's name
    reads some 16 files: 1 ms of a 5 ms first call)."""
    info = path.stat()
    stamp = (info.st_size, info.st_mtime_ns)
    kept = _TEXTS.get(path)
    if kept is None or kept[0] != stamp:
        kept = _TEXTS[path] = (stamp, path.read_text())
    return kept[1]


#: Hashed names of the modules' sources met in this process (see :func:`module_path`).
_KEYS: dict[str, str] = {}


def module_path(source: str, prefix: str = "diagram", *, write: bool = True) -> Path:
    """Where the module of ``source`` is written: a name hashed from its text and code
    (the file written there unless it exists, or ``write`` is False).

    numba keys its cache on the module's file alone, so the source of the kernels it
    imports and of the engine's modules it pastes in (:data:`PASTED_IN`) goes into the
    name: editing any of them makes a new module, compiled anew.

    Examples
    --------
    >>> module_path("import numpy as np\\n").name.startswith("diagram_")
    True
    """
    key = _KEYS.get(source)
    if key is None:  # read once a process: a call on the driver asks again (16 files, 1 ms)
        modules = sorted({line.split()[1] for line in source.splitlines()
                          if line.startswith("from ") and " import " in line}
                         - {"controlkit.engines.fast"})
        key = hashlib.sha256((source + _sources([*modules, *PASTED_IN])
                              + str(_jit.HAVE_NUMBA) + str(_jit.CACHE_FORMAT)
                              ).encode()).hexdigest()[:20]
        _KEYS[source] = key
    folder = cache_folder()
    path = folder / f"{prefix}_{key}.py"
    if write and not path.exists():  # keep the file's date: numba's cache index keys on it
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    return path


def import_module(path: Path):
    """Import the module at ``path`` by its file name (numba's cache re-imports it so).

    A module that fails to run is not left half-loaded in ``sys.modules``.

    Examples
    --------
    >>> path = module_path("VALUE = 3\\n")
    >>> import_module(path).VALUE
    3
    """
    folder = str(path.parent)
    if folder not in pysys.path:  # compiled user kernels are modules there too
        pysys.path.append(folder)
    name = f"controlkit_{path.stem}"
    with IMPORTING:
        if name in pysys.modules:
            return pysys.modules[name]
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        pysys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:  # never leave a half-loaded module behind
            del pysys.modules[name]
            raise
        return module


def compiled(module):
    """``module``'s functions wrapped by numba: kernels pasted in, the rest cached on disk.

    Each function is compiled (or loaded from the cache) at its first call.

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> module = compiled(import_module(module_path(prepare(cmg_loop()).source)))
    >>> hasattr(module.run_discrete, "py_func")
    True
    """
    with IMPORTING:
        if getattr(module, "_controlkit_compiled", False):
            return module
        numba = _jit.numba
        for name, value in list(vars(module).items()):
            if name.startswith("kernel_") and hasattr(value, "py_func"):
                setattr(module, name, numba.njit(inline="always")(value.py_func))
        for name in EVALUATOR:  # pasted into the entry points: one function for LLVM, whose
            # reference-count pruning then drops the slices' counting (0.27 -> x us a step)
            setattr(module, name, numba.njit(inline="always")(getattr(module, name)))
        for name in ENTRY_POINTS:
            if hasattr(module, name):
                setattr(module, name,
                        numba.njit(cache=True, nogil=True)(getattr(module, name)))
        module._controlkit_compiled = True
        return module


def load(source: str):
    """The compiled module of ``source`` (its functions compile or load at first call).

    Examples
    --------
    >>> m = load("import numpy as np\\n\\n\\ndef run_discrete(T, X0, U, P, Y, X, "
    ...          "status, k0, k1):\\n    return X0\\n")
    >>> hasattr(m, "run_discrete")
    True
    """
    module = _LOADED.get(source)
    if module is None:
        with IMPORTING:
            module = import_module(module_path(source))
            if _jit.HAVE_NUMBA:
                for name in EVALUATOR:  # a module with only entry points (tests) compiles
                    if not hasattr(module, name):
                        setattr(module, name, lambda *args: None)
                compiled(module)
        _LOADED[source] = module
    return module


_DRIVER: list = []


def driver():
    """The generic driver (:mod:`.driver`), as a copy named after its sources (see there).

    Examples
    --------
    >>> hasattr(driver(), "run_discrete")
    True
    """
    if not _DRIVER:
        from . import driver as package_driver

        with IMPORTING:
            if not _DRIVER:
                if not _jit.HAVE_NUMBA:
                    _DRIVER.append(package_driver)
                else:
                    source = Path(package_driver.__file__).read_text()
                    _DRIVER.append(import_module(module_path(source, prefix="driver")))
    return _DRIVER[0]


def load_python(source: str, injected: dict):
    """``source``'s functions run as plain Python, handed the kernels in ``injected``.

    The loops, the RK4 step and the integrator are swapped for their Python versions:
    handed a Python kernel, numba would compile a new specialisation for every one.

    Examples
    --------
    >>> ns = load_python("def run_discrete(*a):\\n    return kernel_0()\\n",
    ...                  {"kernel_0": lambda: 3})
    >>> ns.run_discrete()
    3
    """
    from ...kernels import common
    from . import loops, rk

    namespace = {}
    exec(compile(source, "<controlkit diagram>", "exec"), namespace)
    namespace.update(injected)
    py = _jit.python_function
    from .rk.interval import _solve_interval_python

    python_rk = SimpleNamespace(solve_interval=_solve_interval_python,
                                make_workspace=rk.make_workspace, SUCCESS=rk.SUCCESS,
                                set_horizon=py(rk.set_horizon),
                                PROJECTED_STEPS=rk.PROJECTED_STEPS)
    # the loops' own Python code, reading Python versions of what they call
    scope = dict(vars(loops), rk=python_rk)
    names = ("discrete_run", "continuous_run", "rhs_template", "interpolate", "_record")
    for name in names:
        function = py(getattr(loops, name))
        scope[name] = FunctionType(function.__code__, scope, name, function.__defaults__)
    namespace["loops"] = SimpleNamespace(**{name: scope[name] for name in names},
                                         INTEGRATOR_FAILED=loops.INTEGRATOR_FAILED)
    namespace["rk"] = python_rk
    namespace["rk4_step"] = py(common.rk4_step)
    return SimpleNamespace(**namespace)


def is_compiled(function) -> bool:
    """Whether ``function`` (an entry point) runs compiled now without compiling first:
    compiled in this process, or found in numba's disk cache.

    Examples
    --------
    >>> is_compiled(print)
    False
    """
    if getattr(function, "overloads", None):
        return True
    return hasattr(function, "py_func") and _in_disk_cache(function)


def compile_in_background(source: str, entry: str) -> None:
    """Start a process that compiles ``source``'s module entry ``entry`` into the disk cache.

    A process, not a thread: numba's compiler lock is global, and loading anything from
    the cache takes it too, so a compiling thread would stall the caller. One process per
    module and process; it primes the entry with empty arguments of the caller's types
    (:mod:`.background`) and exits.

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> compile_in_background(prepare(cmg_loop()).source, "run_discrete")  # doctest: +SKIP
    """
    path = str(module_path(source))
    if path in _BACKGROUND:  # running, or ran: the cache holds the module, or it failed
        return
    if any(process.poll() is None for process in _BACKGROUND.values()):
        return  # one at a time, on a machine of few cores: the next run asks again
    env = dict(os.environ, CONTROLKIT_BACKGROUND_COMPILE="0")
    _BACKGROUND[path] = subprocess.Popen(
        [pysys.executable, "-m", "controlkit.engines.fast.background", path, entry],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        env=env, start_new_session=True)


def background_done(source: str) -> bool | None:
    """Whether the background compilation of ``source`` finished (None: none started).

    Examples
    --------
    >>> background_done("nothing") is None
    True
    """
    process = _BACKGROUND.get(str(module_path(source, write=False))) if source != "nothing" \
        else None
    return None if process is None else process.poll() is not None


def _in_disk_cache(dispatcher) -> bool:
    """Whether numba's disk cache holds compiled code of ``dispatcher``'s function.

    Asked of numba's own cache object, which knows where the index is (next to the loop's
    file, or under ``NUMBA_CACHE_DIR`` when that is set: looking only next to the file,
    every run with ``NUMBA_CACHE_DIR`` ran the CMG loop as Python, 0.3 s slower).
    """
    try:
        return os.path.exists(dispatcher._cache._cache_file._index_path)
    except AttributeError:  # another numba's internals: compile, as for a long run
        return True
