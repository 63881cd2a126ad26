"""Functions for tests/test_sweep_faults.py that worker processes must import by name, and
a script that runs one sweep in a process of its own (to be interrupted or killed).

    python tests/sweep_faults_helpers.py STORE EXECUTOR RUNS PAUSE [--resume] [--hog]

runs ``square`` over ``x = 0 .. RUNS-1`` (each run pausing PAUSE s) with two workers and
prints the table as JSON; with ``--hog`` it runs ``hog`` instead (runs that never end).
With the environment variable ``CONTROLKIT_TEST_GATE=FILE:N`` the runs ``x >= N`` wait
until FILE exists: a test holds a sweep at a chosen row for as long as it needs, whatever
the machine's load, instead of hoping that its pauses last long enough.
"""

import json
import os
import signal
import sys
import time
from pathlib import Path

#: Where runs of the script write their pid when they start (unset: nowhere).
PID_FOLDER = "CONTROLKIT_TEST_PID_FOLDER"
#: ``FILE:N``: the runs ``x >= N`` of ``square`` wait until FILE exists (unset: none wait).
GATE = "CONTROLKIT_TEST_GATE"


def _note_pid(x, folder=None) -> None:
    folder = folder or os.environ.get(PID_FOLDER)
    if folder:  # whole or not at all: a test reads the pid as soon as the file is there
        tmp = Path(folder) / f".{x}.{os.getpid()}.tmp"
        tmp.write_text(str(os.getpid()))
        os.replace(tmp, Path(folder) / f"{x}.pid")


def _wait_at_the_gate(x) -> None:
    gate = os.environ.get(GATE)
    if gate:
        path, first_held = gate.rsplit(":", 1)
        while x >= int(first_held) and not Path(path).exists():
            time.sleep(0.01)


def square(x, pause=0.0):
    """y = x^2, after ``pause`` s (and after the gate opens, see :data:`GATE`)."""
    _note_pid(x)
    _wait_at_the_gate(x)
    time.sleep(pause)
    return {"y": x * x}


def imported_before(x):
    """Which modules a worker had imported when its first run began (the sweep's function
    module is imported by then, whatever preloads)."""
    return {"numba": "numba" in sys.modules, "processes": "controlkit._workers.processes"
            in sys.modules, "pid": os.getpid()}


def hog(x):
    """Never ends, and holds the GIL while it goes (a long loop in C, like a compiled
    simulation): a thread of the same process cannot run meanwhile."""
    _note_pid(x)
    return {"y": sum(range(10 ** 13))}


def sleepy(seconds, pid_folder=None):
    """Sleeps ``seconds`` (writing its pid into ``pid_folder`` first)."""
    _note_pid(seconds, pid_folder)
    time.sleep(seconds)
    return {"slept": seconds}


class Unprintable(Exception):
    """An exception whose message itself fails."""

    def __str__(self):
        raise RuntimeError("no message")


def misbehave(kind):
    """Every way a run can go wrong, by name."""
    if kind == "raise":
        raise ValueError("boom")
    if kind == "sys_exit":
        sys.exit(3)
    if kind == "os_exit":
        os._exit(4)
    if kind == "segfault":
        import ctypes

        ctypes.string_at(0)
    if kind == "sigkill_self":
        os.kill(os.getpid(), signal.SIGKILL)
    if kind == "unpicklable":
        return {"y": lambda: 1}
    if kind == "object":
        return {"y": object()}
    if kind == "reserved_run":
        return {"run": 1, "y": 2}
    if kind == "reserved_error":
        return {"error": "not mine"}
    if kind == "other_parameter_value":
        return {"kind": "something else"}
    if kind == "same_parameter_value":
        return {"kind": kind, "y": 1.0}
    if kind == "not_a_dict":
        return [1, 2]
    if kind == "interrupt":
        raise KeyboardInterrupt
    if kind == "generator_exit":
        raise GeneratorExit("closed")
    if kind == "cancelled":
        import asyncio

        raise asyncio.CancelledError("the task was cancelled")
    if kind == "unprintable":
        raise Unprintable
    return {"y": 0.0}


def main(argv) -> int:
    import sweep_faults_helpers as helpers  # by its name, as in the tests (not __main__)

    from controlkit.sweep import sweep

    hog, square = helpers.hog, helpers.square
    store, executor, runs, pause = argv[0], argv[1], int(argv[2]), float(argv[3])
    if "--hog" in argv:
        function, fixed = hog, None
    else:
        function, fixed = square, {"pause": pause}
    table = sweep(function, grid={"x": list(range(runs))}, fixed=fixed, executor=executor,
                  workers=None if executor == "serial" else 2, store=store,
                  resume="--resume" in argv, progress=False)
    print(json.dumps(table.drop(columns="wall_time_s").to_dict("list")))
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv[1:]))
    except KeyboardInterrupt:
        sys.exit(130)
