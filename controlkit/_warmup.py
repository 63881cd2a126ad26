"""numba's start, paid while a person is still typing: a warm-up thread for notebooks.

The first compiled call in a process pays numba's own start: its import (about 0.1 s on
the 2-core machine the benchmarks run on) and the first load of any compiled function,
which fills numba's typing and lowering tables (about 0.15 s, ``BaseContext.refresh``),
then the import of the fast engine's modules and the loading of its Runge-Kutta machine
(about 0.03 s). Together that is most of a notebook's first call, and more than
python-control's whole time for a short continuous run. In an interactive session (a
Jupyter kernel, IPython, ``python -i``) ``import controlkit`` does this in a daemon
thread, while the person builds the diagram in the next cells.

Each phase runs at a moment when no other thread imports (:func:`controlkit._quiet.alone`:
importing from two threads at once is not safe in general, as we saw with
``controlkit.engines.fast``); an import started meanwhile waits for it, at most the time
of one phase. Modules already imported are not affected.

The work is done in four such phases: numba's import; its tables; the engine's modules
(python-control with them, if the person has not imported it yet) and RK machine; the
generic driver that runs a newly wired diagram, loaded from numba's disk cache if it is
there (never compiled here: a compile would hold numba's lock for seconds), so that the
first new wiring of a session does not pay its loading (about 35 ms), then the entries
of an LTI block's kernels the same way, then the modules of the diagrams run last
(:mod:`controlkit.engines.fast.recent`: a notebook opened again runs them first). Later,
:func:`controlkit._quiet.later` runs work for the person's next call in the same manner
(the entries of a diagram's blocks after its call). A fork waits for the thread
(``os.register_at_fork``), and so does the interpreter's exit.
``CONTROLKIT_WARMUP=0`` turns it off, ``=1`` starts it outside interactive sessions as
well (the benchmarks use this to time a notebook's calls from a script).
"""

from __future__ import annotations

import os
import sys
import warnings

from . import _quiet
from ._quiet import IMPORTING, alone, wait

__all__ = ["interactive", "start", "wait", "wanted"]

def interactive() -> bool:
    """True in a Jupyter kernel, an IPython shell or ``python -i``.

    Examples
    --------
    >>> isinstance(interactive(), bool)
    True
    """
    ipython = sys.modules.get("IPython")  # imported by some libraries outside a shell too
    shell = getattr(ipython, "get_ipython", None)
    if shell is not None and shell() is not None:
        return True
    return bool(getattr(sys, "ps1", None) or sys.flags.interactive)


def wanted() -> bool:
    """Whether ``import controlkit`` starts the warm-up here.

    ``CONTROLKIT_WARMUP`` decides when set (``0`` off, ``1`` on; any other value is
    warned about and ignored); otherwise it runs in interactive sessions only, where
    there is time between cells to hide it in. Never when numba is disabled
    (``CONTROLKIT_DISABLE_NUMBA``) or already imported.

    Examples
    --------
    >>> import os
    >>> os.environ["CONTROLKIT_WARMUP"] = "0"
    >>> wanted()
    False
    >>> del os.environ["CONTROLKIT_WARMUP"]
    """
    if os.environ.get("CONTROLKIT_DISABLE_NUMBA", "") not in ("", "0"):
        return False
    if "numba" in sys.modules:  # already paid for (or being paid for by someone else)
        return False
    setting = os.environ.get("CONTROLKIT_WARMUP", "").strip()
    if setting in ("0", "1"):
        return setting == "1"
    if setting:  # an import is no place to fail over a setting that only saves time
        warnings.warn(f"CONTROLKIT_WARMUP must be '0' or '1', not {setting!r}; ignored",
                      RuntimeWarning, stacklevel=2)
    return interactive()


def _warm() -> None:
    """numba's import, its tables, then the engine: each while nobody else imports."""
    try:
        with alone() as quiet:
            if not quiet:
                return
            import numba  # noqa: F401
            from numba.core.compiler_lock import global_compiler_lock
            from numba.core.registry import cpu_target

        with alone(global_compiler_lock) as quiet:
            if not quiet:
                return
            cpu_target.target_context.refresh()
        with alone(global_compiler_lock) as quiet:
            if not quiet:
                return
            import controlkit.engines.fast.response  # noqa: F401
            import controlkit.simulation  # noqa: F401
            from controlkit.engines.fast import rk

            rk.machine_function()
        with alone(global_compiler_lock, IMPORTING) as quiet:
            if not quiet:
                return
            from controlkit.engines.fast import recent
            from controlkit.engines.fast.run import load_driver, preload_entries, warm_up_job

            load_driver()  # from the disk cache only: a new wiring's first call
            lag = warm_up_job()
        preload_entries(lag)  # an LTI block's entries, each loaded alone
        for path, entry in recent.modules():  # the diagrams of the last session
            with alone(global_compiler_lock, IMPORTING) as quiet:
                if not quiet:
                    return
                recent.load(path, entry)
    except Exception:  # noqa: BLE001 - the first call then does (and reports) it itself
        pass


def start() -> bool:
    """Start the warm-up thread if :func:`wanted` and not started yet; True if started.

    Examples
    --------
    >>> import os
    >>> os.environ["CONTROLKIT_WARMUP"] = "0"
    >>> start()
    False
    >>> del os.environ["CONTROLKIT_WARMUP"]
    """
    if _quiet._THREAD is not None or not wanted():
        return False
    return _quiet.start(_warm, "controlkit-numba-warmup")
