"""numba's start, paid while a person is still typing: a warm-up thread for notebooks.

The first compiled call in a process pays numba's own start: its import (about 0.1 s on
the 2-core machine the benchmarks run on) and the first load of any compiled function,
which fills numba's typing and lowering tables (about 0.15 s, ``BaseContext.refresh``),
then the import of the fast engine's modules and the loading of its Runge-Kutta machine
(about 0.03 s). Together that is most of a notebook's first call, and more than
python-control's whole time for a short continuous run. In an interactive session (a
Jupyter kernel, IPython, ``python -i``) ``import controlkit`` does this in a daemon
thread, while the person builds the diagram in the next cells.

Importing from two threads at once is not safe in general: a package whose
``__init__`` imports its own modules, imported by one thread while another imports one
of those modules directly, ends in "cannot import name ... from partially initialized
module" (we saw it with ``controlkit.engines.fast``). So the thread imports only while no
other thread is importing anything: it takes Python's global import lock (which every
import takes to get its module's lock) and goes ahead only if no module lock exists at
that moment; otherwise it lets go and tries again 10 ms later. While it holds the lock,
another thread's first import of a module waits for it (at most the time of one phase
below); modules already imported are not affected. numba's compiler lock is taken first,
so a compile in another thread is never waited on from inside the import lock.

The work is done in four such phases: numba's import; its tables; the engine's modules
(python-control with them, if the person has not imported it yet) and RK machine; the
generic driver that runs a newly wired diagram, loaded from numba's disk cache if it is
there (never compiled here: a compile would hold numba's lock for seconds), so that the
first new wiring of a session does not pay its loading (about 35 ms), then the entries
of an LTI block's kernels the same way, then the modules of the diagrams run last
(:mod:`controlkit.engines.fast.recent`: a notebook opened again runs them first). Later,
:func:`later` runs work for the person's next call in the same manner (the entries of
a diagram's blocks after its call). A fork
waits for the thread (``os.register_at_fork``), and so does the interpreter's exit.
``CONTROLKIT_WARMUP=0`` turns it off, ``=1`` starts it outside interactive sessions as
well (the benchmarks use this to time a notebook's calls from a script).
"""

from __future__ import annotations

import atexit
import contextlib
import os
import sys
import threading
import time
import warnings

#: The warm-up thread once started (at most one per process).
_THREAD: threading.Thread | None = None
#: The thread of the last task handed to :func:`later` (each waits for the one before).
_LATER: threading.Thread | None = None
_LOCK = threading.Lock()

#: Seconds the thread keeps trying to find a moment when nobody imports, per phase.
QUIET_WAIT_S = 20.0
#: Seconds between two tries.
RETRY_S = 0.01

#: Seconds a fork or the interpreter's exit waits for the thread at most.
WAIT_LIMIT_S = 30.0


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


@contextlib.contextmanager
def alone(compiler_lock=None, *tried):
    """Hold numba's compiler lock (if given) and Python's import lock, at a moment when no
    other thread is importing, and the locks ``tried`` (taken only if free: their holder
    may be waiting for Python's import lock); yields False (holding nothing) if no such
    moment came in time.

    Examples
    --------
    >>> with alone() as quiet:  # nobody else imports in a doctest
    ...     quiet
    True
    """
    import _imp
    from importlib import _bootstrap

    deadline = time.monotonic() + QUIET_WAIT_S
    while True:
        if compiler_lock is not None:
            compiler_lock.acquire()
        _imp.acquire_lock()
        if not any(ref() is not None for ref in list(_bootstrap._module_locks.values())):
            taken = []
            for lock in tried:
                if not lock.acquire(blocking=False):
                    break
                taken.append(lock)
            else:
                break
            for lock in reversed(taken):
                lock.release()
        _imp.release_lock()
        if compiler_lock is not None:
            compiler_lock.release()
        if time.monotonic() > deadline or _GIVE_UP.is_set():
            yield False
            return
        time.sleep(RETRY_S)
    try:
        yield True
    finally:
        for lock in reversed(tried):
            lock.release()
        _imp.release_lock()
        if compiler_lock is not None:
            compiler_lock.release()


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
            from controlkit.engines.fast.loader import IMPORTING

            rk.machine_function()
        with alone(global_compiler_lock, IMPORTING) as quiet:
            if not quiet:
                return
            from controlkit.engines.fast.run import load_driver, preload_entries, warm_up_job

            load_driver()  # from the disk cache only: a new wiring's first call
            lag = warm_up_job()
        preload_entries(lag)  # an LTI block's entries, each loaded alone
        from controlkit.engines.fast import recent

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
    global _THREAD
    with _LOCK:
        if _THREAD is not None or not wanted():
            return False
        _THREAD = threading.Thread(target=_warm, name="controlkit-numba-warmup",
                                   daemon=True)
        _THREAD.start()
        return True


def later(task) -> bool:
    """Run ``task()`` in a daemon thread after the warm-up (and after the tasks handed in
    before it), if this process warmed up; True if it will run.

    For work a person's next call may need and this one did not, done between two cells
    (the entries of a diagram's blocks, for a new wiring of them). Its errors are
    swallowed: the call that needs the work does it (and reports it) itself.

    Examples
    --------
    >>> later(lambda: None)  # no warm-up in a doctest: nothing runs
    False
    """
    global _LATER
    with _LOCK:
        if _THREAD is None:
            return False
        before = _LATER

        def run():
            for thread in (_THREAD, before):
                if thread is not None:
                    thread.join()
            try:
                task()
            except Exception:  # noqa: BLE001 - see above
                pass

        _LATER = threading.Thread(target=run, name="controlkit-later", daemon=True)
        _LATER.start()
        return True


def wait() -> None:
    """Return once the warm-up thread and the tasks handed to :func:`later` (if any) have
    finished, or after ``WAIT_LIMIT_S`` each.

    Examples
    --------
    >>> wait()  # nothing started: returns at once
    """
    for thread in (_THREAD, _LATER):
        if thread is not None and thread is not threading.current_thread():
            thread.join(WAIT_LIMIT_S)


def _give_up() -> None:
    """Before a fork or the interpreter's exit: what has not started waiting for a quiet
    moment is not done (a thread inside an import, forking, would keep it waiting for
    ``QUIET_WAIT_S``), and what runs is waited for."""
    _GIVE_UP.set()
    wait()


#: Set before a fork (cleared after it in the parent) and at exit: :func:`alone` gives up.
_GIVE_UP = threading.Event()

if hasattr(os, "register_at_fork"):
    os.register_at_fork(before=_give_up, after_in_parent=_GIVE_UP.clear)
atexit.register(_give_up)
