"""Loading a generated loop: the disk cache, numba, and the Python loop meanwhile.

The loop's source is written into the cache folder (:func:`cache_folder`: :data:`CACHE_DIR`
when it is the user's own) under a name made from its text and the kernels' source,
imported from there and compiled with numba (``cache=True``: a later process loads the
machine code). A loop not compiled yet
runs as plain Python for its first :data:`COMPILE_AFTER_STEPS` steps.
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.util
import os
import shutil
import stat
import sys as pysys
import tempfile
import warnings
from pathlib import Path

from ... import _jit
from ...kernels import common

#: Where generated simulation loops and compiled user functions are written (and numba
#: caches them). Code is imported from there, so it is used only when it is the user's own:
#: see :func:`cache_folder`.
CACHE_DIR = Path(os.environ.get("CONTROLKIT_CACHE_DIR",
                                Path.home() / ".cache" / "controlkit" / "engine"))

#: Loops loaded in this process, by generated source (the kernels imported here are fixed).
_LOADED: dict[str, object] = {}

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


#: A diagram's loop that is not compiled yet (neither in this process nor in the disk cache)
#: runs as plain Python, calling the compiled kernels, for its first this-many steps in a
#: process: compiling a loop costs 1-3 s, the Python loop 5-40 us a step (measured in
#: benchmarks/bench_user_diagrams.py), so short exploratory runs of a newly wired diagram
#: start at once and the loop is compiled once the runs grow long.
COMPILE_AFTER_STEPS = 50_000


#: Steps run as Python so far, per loop source (see :data:`COMPILE_AFTER_STEPS`).
_PYTHON_STEPS: dict[str, int] = {}


def _python_loop(source: str, injected=None):
    """The generated loop run as plain Python, calling the (compiled) kernels it imports.

    The RK4 helper is swapped for its Python version: handed a kernel from Python, numba
    would compile a new, uncacheable specialisation of it for every kernel.
    """
    namespace = {}
    exec(compile(source, "<controlkit loop>", "exec"), namespace)
    namespace.update(injected or {})
    if "rk4_step" in namespace:
        namespace["rk4_step"] = _jit.python_function(common.rk4_step)
    return namespace["run"]


def load(source: str, injected=None, steps=None):
    """The ``run`` function of a generated loop: compiled, loaded from the cache, or Python.

    With ``injected`` (kernels that cannot be imported: Python functions) the loop runs as
    Python, handed them. With ``steps`` (the run's length), a loop not compiled yet runs
    as Python while the runs are short (:data:`COMPILE_AFTER_STEPS`).

    Examples
    --------
    >>> run = load("def run(T, X0, U, P, Y, X, status, k0, k1):\\n    return X0\\n",
    ...            injected={"unused": print})
    >>> run(None, 1.5, None, None, None, None, None, 0, 0)
    1.5
    """
    if injected:  # Python kernels in the loop: run it as plain Python, handed those kernels
        return _python_loop(source, injected)
    if source in _LOADED:  # no need to read and hash the kernels' files again
        return _LOADED[source]
    # numba caches the loop with the kernels inlined but keys on the loop's file alone:
    # the kernels' source goes into the file name so that editing them recompiles
    folder = cache_folder()
    if str(folder) not in pysys.path:  # compiled user kernels are modules there
        pysys.path.append(str(folder))
    modules = sorted({line.split()[1] for line in source.splitlines()
                      if line.startswith("from ")})
    kernel_sources = "".join(Path(importlib.util.find_spec(m).origin).read_text()
                             for m in modules)
    key = hashlib.sha256((source + kernel_sources + str(_jit.HAVE_NUMBA)
                          + str(_jit.CACHE_FORMAT)).encode()).hexdigest()[:20]
    path = folder / f"loop_{key}.py"
    if not path.exists():  # keep the file's date: numba's cache keys on it
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(f"controlkit_loop_{key}", path)
    module = importlib.util.module_from_spec(spec)
    pysys.modules[spec.name] = module  # numba's disk cache re-imports it by name
    spec.loader.exec_module(module)
    run = module.run
    if _jit.HAVE_NUMBA:
        run = _jit.numba.njit(cache=True)(run)  # compiled or loaded at its first call
        if steps is not None and not _in_disk_cache(run) \
                and _PYTHON_STEPS.get(source, 0) + steps < COMPILE_AFTER_STEPS:
            _PYTHON_STEPS[source] = _PYTHON_STEPS.get(source, 0) + steps
            return _python_loop(source)
    _LOADED[source] = run
    return run


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
