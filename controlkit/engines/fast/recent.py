"""The diagrams run last, loaded again by the next session's warm-up.

A person who opens a notebook again runs the diagrams of last time. The first call of
each loads its compiled module from numba's disk cache (about 10 ms: LLVM's bitcode
parsed and linked), most of a short run's first call once the rest is kept on disk. A
run on a diagram's own module leaves a mark (:func:`note`): an empty file named after
the module and its entry point, in ``recent/`` of the cache folder, its date the run's.
A notebook's warm-up (:mod:`controlkit._warmup`) loads the entry points of the
:data:`LIMIT` most recent ones from the cache (:func:`load`: never a compile), the
oldest first, while the person reads and types; the rest is done by the first call as
ever.
"""

from __future__ import annotations

import ast
import os
import sys
from pathlib import Path

from ... import _jit
from . import loader

#: How many of the diagrams run last the warm-up loads.
LIMIT = 8
#: Marks kept at most (the oldest are removed).
KEPT = 64


def _folder() -> Path:
    return loader.cache_folder() / "recent"


def note(source: str, entry: str) -> None:
    """Mark the module of ``source`` as run now through ``entry``; a failure is ignored.

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> note(prepare(cmg_loop()).source, "run_discrete")
    >>> any(entry == "run_discrete" for _, entry in modules())
    True
    """
    if entry not in loader.ENTRY_POINTS:
        raise ValueError(f"entry must be one of {loader.ENTRY_POINTS}, got {entry!r}")
    try:
        folder = _folder()
        folder.mkdir(exist_ok=True)
        (folder / f"{loader.module_path(source).stem}.{entry}").touch()
    except OSError:
        pass


def modules(limit: int = LIMIT) -> list[tuple[Path, str]]:
    """``(module path, entry point)`` of the ``limit`` diagrams run last, the oldest first.

    Marks beyond :data:`KEPT` are removed, and so are those whose module is gone.

    Examples
    --------
    >>> all(path.suffix == ".py" for path, _ in modules())
    True
    """
    if limit < 0:
        raise ValueError(f"limit must be 0 or more, got {limit}")
    dated = []
    try:
        for mark in _folder().iterdir():
            try:
                dated.append((mark.stat().st_mtime, mark))
            except OSError:
                continue
    except OSError:
        return []
    dated.sort(reverse=True)
    found = []
    for rank, (_, mark) in enumerate(dated):
        stem, _, entry = mark.name.partition(".")
        path = mark.parent.parent / f"{stem}.py"
        if rank >= KEPT or entry not in loader.ENTRY_POINTS or not path.exists():
            _remove(mark)
        elif len(found) < limit:
            found.append((path, entry))
    return found[::-1]


def _remove(mark: Path) -> None:
    try:
        os.remove(mark)
    except OSError:
        pass


def load(path: Path, entry: str) -> bool:
    """Load the entry point ``entry`` of the diagram module at ``path`` from numba's disk
    cache, compiling nothing; True if it is loaded now, False if not (not in the cache,
    or its module or a user kernel it imports no longer loads: the first call says why).

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> path = loader.module_path(prepare(cmg_loop()).source)
    >>> isinstance(load(path, "run_discrete"), bool)
    True
    """
    from .background import empty_arguments, import_diagram

    try:
        if not _imports_only_what_is_there(path):
            return False
        module = import_diagram(path)
    except Exception:  # noqa: BLE001 - see above
        return False
    return _jit.from_cache(getattr(module, entry), empty_arguments(entry))


def _imports_only_what_is_there(path: Path) -> bool:
    """Whether the module at ``path`` and the user kernels it imports import nothing but
    controlkit's modules, those already imported (numpy, numba) and the engine's own: a
    person's module that a kernel imports (a numba helper of theirs) is theirs to import,
    at the moment and from the folder they choose, not a thread's at the session's start."""
    files, seen = [path], set()
    while files:
        file = files.pop()
        if file in seen:
            continue
        seen.add(file)
        for node in ast.parse(file.read_text()).body:
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                module = sys.modules.get(node.module)
                names = [node.module] if module is None or all(
                    hasattr(module, alias.name) for alias in node.names) else [
                    f"{node.module}.{alias.name}" for alias in node.names]
            else:
                continue
            for name in names:
                if name.startswith("controlkit_"):  # written by the engine, next to it
                    files.append(file.parent / f"{name}.py")
                elif name.split(".")[0] != "controlkit" and name not in sys.modules:
                    return False
    return True
