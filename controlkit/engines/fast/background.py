"""``python -m controlkit.engines.fast.background PATH ENTRY``: compile a diagram's module.

Started by :func:`.loader.compile_in_background`: it imports the module at ``PATH``,
compiles its entry point ``ENTRY`` (``run_discrete`` or ``run_continuous``) for the
argument types the engine passes (:func:`prime`), which numba writes into its disk
cache, and exits. The process that started it loads the compiled code from the cache at
its next run of that wiring.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from ... import _jit


def main(argv=None) -> int:
    """Compile the entry ``argv[1]`` of the module at ``argv[0]``; 0 when it compiled.

    Examples
    --------
    >>> main(["/nonexistent/diagram.py", "run_discrete"])
    1
    """
    path, entry = (argv if argv is not None else sys.argv[1:])[:2]
    try:
        module = import_diagram(Path(path))
        prime(getattr(module, entry), entry)
    except Exception:  # noqa: BLE001 - the caller keeps running on the driver
        return 1
    return 0


def import_diagram(path: Path):
    """The diagram module at ``path``, imported with its functions wrapped by numba, its
    user kernels imported first as the engine makes them (imported by its own
    ``from ... import`` lines, they would be plain Python functions numba cannot call).

    Examples
    --------
    >>> from controlkit.engines.fast.loader import module_path
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> hasattr(import_diagram(module_path(prepare(cmg_loop()).source)).run_discrete,
    ...         "py_func")
    True
    """
    from .loader import compiled, import_module
    from .usercode.compiling import USER_MODULE_PREFIX, import_user_module

    for line in path.read_text().splitlines():
        if line.startswith(f"from {USER_MODULE_PREFIX}"):
            import_user_module(path.parent / f"{line.split()[1]}.py")
    return compiled(import_module(path))



def prime(function, name: str):
    """Compile the entry point ``function`` (named ``name``) for the engine's argument
    types, running nothing (empty arrays, no step).

    Examples
    --------
    >>> prime(lambda *args: None, "run_discrete")
    """
    function(*empty_arguments(name))


def empty_arguments(name: str) -> tuple:
    """Arguments of the entry point ``name`` of the engine's types that run nothing (what
    a module is compiled for in the background, and loaded from the cache for).

    Examples
    --------
    >>> len(empty_arguments("run_discrete"))
    9
    """
    f, i = np.zeros(0), np.zeros(0, dtype=np.int64)
    m = np.zeros((0, 0))
    status = np.full(4, -1, dtype=np.int64)
    if name == "run_discrete":
        return (f, f, m, f, m, m, status, 0, 0)
    from . import rk

    machine = rk.machine_function() if _jit.HAVE_NUMBA else rk.machine
    return (machine, f, 0, 0, 0, 0.0, f, m, f, i, np.zeros(1, dtype=np.int64), m, m, m, f, f,
            f, 0, 1e-3, f, np.inf, 0.0, True, status)


if __name__ == "__main__":
    raise SystemExit(main())
