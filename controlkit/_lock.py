"""One writer per folder: a lock file that names its holder and dies with it.

:class:`FolderLock` guards a folder (a sweep's store, an output folder) against a second
process writing into it at the same time, as ``make`` and ``snakemake`` lock their
working directories. The lock is an exclusive :func:`fcntl.flock` on a file in the folder;
the kernel releases it when the holder ends, however it ends (SIGKILL included), so a lock
left by a dead process is taken over at once and never has to be removed by hand. The file
holds the holder's pid, host, command and start time, so that a refused second process can
say which one holds the folder.

Where :mod:`fcntl` is missing (Windows), the file is created exclusively instead and a lock
whose process no longer runs on this host is taken over.

A second guard catches file systems on which ``flock`` does nothing (some network mounts):
a lock file naming a live process on this host is never taken over.
"""

from __future__ import annotations

import datetime
import json
import os
import socket
import sys
from pathlib import Path

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None


class LockHeld(ValueError):
    """The folder is locked by another process (:attr:`holder` says which).

    Examples
    --------
    >>> error = LockHeld("in use", {"pid": 12})
    >>> error.holder["pid"], isinstance(error, ValueError)
    (12, True)
    """

    def __init__(self, message: str, holder: dict):
        super().__init__(message)
        self.holder = holder


def _proc_stat(pid: int):
    """``(state, start time in clock ticks)`` of a process from ``/proc``; None if absent."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except (FileNotFoundError, ProcessLookupError, PermissionError, NotADirectoryError):
        return None
    # fields after the command name (which may hold spaces and parentheses): state is
    # field 3 of proc(5), the start time field 22
    fields = text[text.rindex(")") + 2:].split()
    return fields[0], int(fields[19])


def process_start_ticks(pid: int) -> int | None:
    """When process ``pid`` started, in clock ticks since boot (Linux), else None.

    With the pid it identifies a process even after the pid is reused.

    Examples
    --------
    >>> import os
    >>> process_start_ticks(os.getpid()) == process_start_ticks(os.getpid())
    True
    """
    stat = _proc_stat(pid)
    return None if stat is None else stat[1]


def process_alive(pid: int, start_ticks: int | None = None) -> bool:
    """Whether process ``pid`` (started at ``start_ticks``, if given) still runs on this host.

    A zombie (ended, not yet reaped by its parent) counts as ended; a pid now used by a
    later process (another start time) too.

    Examples
    --------
    >>> import os
    >>> process_alive(os.getpid()), process_alive(os.getpid(), start_ticks=-1)
    (True, False)
    """
    if not isinstance(pid, int) or isinstance(pid, bool) or pid <= 0:
        return False
    stat = _proc_stat(pid)
    if stat is not None:
        state, ticks = stat
        return state not in ("Z", "X", "x") and (start_ticks is None or ticks == start_ticks)
    if os.path.isdir("/proc/self"):  # Linux, and no such process
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, owned by someone else
        return True
    except OSError:  # Windows: no signal 0; assume alive rather than take a live lock
        return True
    return True


def _holder_text(holder: dict) -> str:
    if not holder.get("pid"):
        return ("another process, which has not written its details (one that is starting "
                "now, or a program other than controlkit holding the lock)")
    mine = holder["pid"] == os.getpid() and holder.get("host") == socket.gethostname()
    text = f"process {holder['pid']}{' (this one)' if mine else ''} on {holder.get('host', '?')}"
    if holder.get("started"):
        text += f", started {holder['started']}"
    if holder.get("command"):
        text += f" ({holder['command']})"
    return text


class FolderLock:
    """An exclusive lock on a folder, held by one process at a time.

    Parameters
    ----------
    folder : str or pathlib.Path
        The folder to guard (created if missing).
    name : str
        The lock file's name inside ``folder``.
    purpose : str
        What the holder does there, for messages (e.g. ``"a sweep"``).

    Attributes
    ----------
    taken_over : dict or None
        After :meth:`acquire`: the details of a previous holder that ended without
        releasing the lock (its file was still there), else None.

    Examples
    --------
    >>> import tempfile
    >>> folder = tempfile.mkdtemp()
    >>> with FolderLock(folder, purpose="an example"):
    ...     try:
    ...         FolderLock(folder).acquire()
    ...     except LockHeld as error:
    ...         print("refused:", error.holder["pid"] == os.getpid())
    refused: True
    >>> sorted(os.listdir(folder))  # released: the lock file is gone
    []
    """

    def __init__(self, folder, *, name: str = ".lock", purpose: str = "another run"):
        self.folder = Path(folder)
        self.path = self.folder / name
        self.purpose = purpose
        self.taken_over = None
        self._fd = None

    def _me(self) -> dict:
        pid = os.getpid()
        command = " ".join([Path(sys.argv[0]).name, *sys.argv[1:]]) if sys.argv else ""
        return {"pid": pid, "host": socket.gethostname(),
                "started": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
                "start_ticks": process_start_ticks(pid), "command": command[:200],
                "purpose": self.purpose}

    @staticmethod
    def _read(fd) -> dict:
        try:
            data = json.loads(os.pread(fd, 65536, 0).decode() or "{}")
        except (ValueError, UnicodeDecodeError):
            return {}
        return data if isinstance(data, dict) else {}

    def _alive_elsewhere(self, holder: dict) -> bool:
        """The file names a live process on this host other than the lock's new owner."""
        return (holder.get("host") == socket.gethostname() and holder.get("pid") != os.getpid()
                and process_alive(holder.get("pid"), holder.get("start_ticks")))

    def _refuse(self, holder: dict):
        raise LockHeld(f"{self.folder} is in use by {holder.get('purpose') or self.purpose}: "
                       f"{_holder_text(holder)}; wait for it to end, or stop it"
                       f"{' (kill ' + str(holder['pid']) + ')' if holder.get('pid') else ''}"
                       f" and run again (lock file {self.path})", holder)

    def acquire(self) -> FolderLock:
        """Take the lock, or raise :class:`LockHeld` naming the process that holds it."""
        if self._fd is not None:
            raise RuntimeError(f"{self.path} is already held by this FolderLock")
        self.folder.mkdir(parents=True, exist_ok=True)
        if fcntl is None:
            return self._acquire_exclusive_create()
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                holder = self._read(fd)
                os.close(fd)
                self._refuse(holder)
            # a holder releasing the lock removes the file: the file locked must still be
            # the one under the name, else lock the new one
            try:
                mine, named = os.fstat(fd), os.stat(self.path)
                same = (mine.st_ino, mine.st_dev) == (named.st_ino, named.st_dev)
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        previous = self._read(fd)
        if self._alive_elsewhere(previous):  # flock without effect here: trust the file
            os.close(fd)
            self._refuse(previous)
        self.taken_over = previous or None
        os.ftruncate(fd, 0)
        os.pwrite(fd, json.dumps(self._me()).encode(), 0)
        os.fsync(fd)
        self._fd = fd
        return self

    def _acquire_exclusive_create(self) -> FolderLock:
        for _ in range(100):
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                try:
                    fd = os.open(self.path, os.O_RDONLY)
                except FileNotFoundError:
                    continue
                holder = self._read(fd)
                os.close(fd)
                if not holder or holder.get("host") != socket.gethostname() or \
                        process_alive(holder.get("pid"), holder.get("start_ticks")):
                    self._refuse(holder)  # this process's own lock too: no flock to tell
                # its process has ended: take it over (one taker wins the rename)
                stale = self.path.with_name(f"{self.path.name}.{os.getpid()}.stale")
                try:
                    os.replace(self.path, stale)
                except FileNotFoundError:
                    continue
                os.unlink(stale)
                self.taken_over = holder
                continue
            os.write(fd, json.dumps(self._me()).encode())
            os.fsync(fd)
            self._fd = fd
            return self
        raise RuntimeError(f"could not create the lock file {self.path}")

    def still_held(self) -> bool:
        """Whether the lock file is still the one this lock holds (someone may have removed
        it by hand, letting a second process lock a new file under the same name)."""
        if self._fd is None:
            return False
        try:
            mine, named = os.fstat(self._fd), os.stat(self.path)
        except FileNotFoundError:
            return False
        return (mine.st_ino, mine.st_dev) == (named.st_ino, named.st_dev)

    def release(self) -> None:
        """Remove the lock file and let go of the lock (nothing if not held)."""
        if self._fd is None:
            return
        try:
            if self.still_held():  # not another process's file under the same name
                os.unlink(self.path)  # before letting go: no one locks a file being removed
        except FileNotFoundError:
            pass
        finally:
            os.close(self._fd)
            self._fd = None

    def __enter__(self) -> FolderLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()
