"""Waiting for a condition, and the live processes read from /proc: for the tests that
interrupt or kill runs (test_sweep_faults.py, test_reproduce_faults.py)."""

import time
from pathlib import Path


def wait_for(condition, seconds, what):
    """Return once ``condition()`` holds; AssertionError naming ``what`` after ``seconds``."""
    deadline = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"waited {seconds} s for {what}")
        time.sleep(0.01)


def _stat(entry: Path) -> list[str] | None:
    """The fields of ``/proc/PID/stat`` after the command (state first, then the parent's
    pid, the group and the session), or None for a process that is gone."""
    try:
        text = (entry / "stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()


def _live(fields) -> bool:
    return fields is not None and fields[0] not in "ZX"  # not a zombie, not dead


def live_processes(keep) -> list[int]:
    """The pids of the live processes whose stat fields (see :func:`_stat`) ``keep`` takes."""
    found = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            fields = _stat(entry)
            if _live(fields) and keep(fields):
                found.append(int(entry.name))
    return found


def children_of(pid: int) -> list[int]:
    """Live processes whose parent is ``pid``."""
    return live_processes(lambda fields: fields[1] == str(pid))


def session_processes(session: int) -> list[int]:
    """Live processes of a session (field 6 of /proc/PID/stat)."""
    return live_processes(lambda fields: int(fields[3]) == session)


def alive(pid: int) -> bool:
    """Whether ``pid`` is a live process (not a zombie)."""
    return _live(_stat(Path(f"/proc/{pid}")))
