"""Loading a generated loop: the disk cache, numba, and the Python loop meanwhile.

The loop's source is written into :data:`CACHE_DIR` under a name made from its
text and the kernels' source, imported from there and compiled with numba
(``cache=True``: a later process loads the machine code). A loop not compiled yet
runs as plain Python for its first :data:`COMPILE_AFTER_STEPS` steps.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys as pysys
import tempfile
from pathlib import Path

from ... import _jit
from ...kernels import common

#: Where generated simulation loops are written (and numba caches them).
CACHE_DIR = Path(os.environ.get("CONTROLKIT_CACHE_DIR",
                                Path.home() / ".cache" / "controlkit" / "engine"))

#: Loops loaded in this process, by generated source (the kernels imported here are fixed).
_LOADED: dict[str, object] = {}


def cache_folder() -> Path:
    """:data:`CACHE_DIR`, or a temporary folder when it cannot be written.

    Examples
    --------
    >>> cache_folder().is_dir()
    True
    """
    folder = CACHE_DIR
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # a read-only home: keep the loops for this machine's session only
        folder = Path(tempfile.gettempdir()) / "controlkit-engine"
        folder.mkdir(parents=True, exist_ok=True)
    return folder


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
