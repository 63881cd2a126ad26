"""``python -m controlkit.engines.fast.background PATH ENTRY``: compile a diagram's module.

Started by :func:`.loader.compile_in_background`: it imports the module at ``PATH``,
compiles its entry point ``ENTRY`` (``run_discrete`` or ``run_continuous``) for the
argument types the engine passes (:func:`.run.prime`), which numba writes into its disk
cache, and exits. The process that started it loads the compiled code from the cache at
its next run of that wiring.
"""

from __future__ import annotations

import sys
from pathlib import Path


def main(argv=None) -> int:
    """Compile the entry ``argv[1]`` of the module at ``argv[0]``; 0 when it compiled.

    Examples
    --------
    >>> main(["/nonexistent/diagram.py", "run_discrete"])
    1
    """
    path, entry = (argv if argv is not None else sys.argv[1:])[:2]
    try:
        from .loader import compiled, import_module
        from .run import prime
        from .usercode.compiling import USER_MODULE_PREFIX, import_user_module

        for line in Path(path).read_text().splitlines():  # its user kernels, compiled first
            if line.startswith(f"from {USER_MODULE_PREFIX}"):
                import_user_module(Path(path).parent / f"{line.split()[1]}.py")
        module = compiled(import_module(Path(path)))
        prime(getattr(module, entry), entry)
    except Exception:  # noqa: BLE001 - the caller keeps running on the driver
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
