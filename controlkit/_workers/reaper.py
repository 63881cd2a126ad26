"""No worker outlives its sweep: the reaper process that kills the workers once the
sweep's process ends, and the thread by which a worker checks on that process itself.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

from .._lock import process_alive, process_start_ticks

#: How often a worker process checks that the sweep's process still runs, s.
PARENT_POLL_S = 0.5


#: The reaper: reads ``PID START_TICKS`` lines until the pipe from the sweep's process ends,
#: then kills those processes that still run (the same pid and start time: not a process
#: that got a reused pid). Ctrl-C is for the sweep's process to handle, not for it.
REAPER = """
import os, signal, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
def ticks(pid):
    try:
        text = open(f"/proc/{pid}/stat").read()
    except OSError:
        return None
    return text[text.rindex(")") + 2:].split()[19]
pids = {}
for line in sys.stdin:
    pid, start = line.split()
    pids[int(pid)] = start
for pid, start in pids.items():
    if start == "-" or ticks(pid) == start:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
"""


class Reaper:
    """Kills the processes it is told about once this process ends (see :data:`REAPER`).

    Examples
    --------
    >>> import subprocess, sys
    >>> child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    >>> reaper = Reaper()
    >>> reaper.watch(child.pid)
    >>> reaper.close()  # as if this process had ended
    >>> child.wait(10) == -9
    True
    """

    def __init__(self):
        self.process = subprocess.Popen([sys.executable, "-I", "-S", "-c", REAPER],
                                        stdin=subprocess.PIPE, close_fds=True)

    def watch(self, pid: int) -> None:
        """Kill ``pid`` when this process (or :meth:`close`) ends the pipe."""
        ticks = process_start_ticks(pid)
        try:
            self.process.stdin.write(f"{pid} {'-' if ticks is None else ticks}\n".encode())
            self.process.stdin.flush()
        except OSError:  # the reaper is gone: the workers' own checks remain
            pass

    def close(self) -> None:
        """End the pipe: the reaper kills what is left and ends."""
        try:
            self.process.stdin.close()
        except OSError:
            pass
        self.process.wait(10)


def watch_parent(pid: int, start_ticks: int | None) -> None:
    while True:
        time.sleep(PARENT_POLL_S)
        if not process_alive(pid, start_ticks):
            os._exit(70)  # the sweep is gone: nobody will read this run's row
