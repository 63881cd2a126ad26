"""Work beside the person's own, in a background thread, at moments when nothing imports.

controlkit's notebook warm-up (:mod:`controlkit._warmup`) and the work it hands on after a
call (:func:`later`: the entries of a diagram's blocks) run here. Importing from two
threads at once is not safe in general (a package half-imported by one thread, one of its
modules imported directly by another, ends in "cannot import name ... from partially
initialized module"), so each step is taken inside :func:`alone`: numba's compiler lock
first (a compile in another thread is never waited on from inside the import lock), then
Python's global import lock, at a moment when no module lock exists, and only then the
engine's own locks, which are only tried (their holder may be waiting for the import lock).
A fork or the interpreter's exit makes what still waits for such a moment give up, and
waits for what runs.

This module imports nothing of controlkit: the engine and the warm-up both build on it.
"""

from __future__ import annotations

import atexit
import contextlib
import gc
import os
import sys
import threading
import time

#: The session's first background thread (the warm-up), once started.
_THREAD: threading.Thread | None = None
#: The thread of the last task handed to :func:`later` (each waits for the one before).
_LATER: threading.Thread | None = None
_LOCK = threading.Lock()

#: Held while a module the engine wrote (a diagram's, the driver, a user kernel's, an
#: entry) is imported or wrapped: a module is in ``sys.modules`` before its code has run,
#: and another thread (the notebook's warm-up) must not find it half-made. The warm-up
#: only tries it (:func:`alone`), so a call never waits on a thread
#: that waits for a quiet moment.
IMPORTING = threading.RLock()

#: Seconds a step keeps trying to find a moment when nobody imports.
QUIET_WAIT_S = 20.0
#: Seconds between two tries.
RETRY_S = 0.01
#: Seconds a fork or the interpreter's exit waits for each thread at most.
WAIT_LIMIT_S = 30.0


def start(target, name: str) -> bool:
    """Start ``target`` as the session's background thread (a daemon), unless one was
    started already; True if started now.

    Examples
    --------
    >>> start(lambda: print("warm"), "controlkit-example")  # doctest: +SKIP
    True
    """
    global _THREAD
    with _LOCK:
        if _THREAD is not None:
            return False
        _THREAD = threading.Thread(target=_then_collect, args=(target,), name=name,
                                   daemon=True)
        _THREAD.start()
        return True


@contextlib.contextmanager
def alone(compiler_lock=None, *tried):
    """Hold numba's compiler lock (if given) and Python's import lock, at a moment when no
    other thread is importing, and the locks ``tried`` (taken only if free: their holder
    may be waiting for Python's import lock or the compiler lock; with the compiler lock,
    numba's lock on the making of its target context is one of them); yields False
    (holding nothing) if no such moment came in time.

    Examples
    --------
    >>> with alone() as quiet:  # nobody else imports in a doctest
    ...     quiet
    True
    """
    import _imp
    from importlib import _bootstrap

    if compiler_lock is not None:
        tried = (*_numba_context_lock(), *tried)
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


def _then_collect(target) -> None:
    try:
        target()
    finally:
        _collect()


def _collect() -> None:
    """Python's full garbage collection, made now, between the person's cells: loading
    compiled code from numba's cache leaves tens of thousands of new objects behind, and
    the next full collection (70-80 ms over the 200 000 objects of a process that has
    numba) would otherwise fall inside one of the person's calls (a new wiring of the
    cruise loop: 6 ms, or 95 ms when it did)."""
    if not _GIVE_UP.is_set():
        gc.collect()


def _numba_context_lock() -> tuple:
    """numba's lock on the making of its CPU target context, if numba's registry is
    imported: a thread that makes the context takes it before the compiler lock (numba's
    own order, ``CPUContext.init`` is compiled under the compiler lock), so a thread that
    holds the compiler lock only tries it."""
    registry = sys.modules.get("numba.core.registry")
    making = vars(getattr(registry, "CPUTarget", object)).get("_toplevel_target_context")
    lock = getattr(making, "_lock", None)
    return () if lock is None else (lock,)


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
            _collect()

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
