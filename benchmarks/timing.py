"""What the benchmarks share: the median wall time of repeated calls, and running a child
process on one checkout of controlkit (this one, or an older one beside it)."""

import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
#: The switches of older engines, unset so that an older checkout runs as its users got it.
OLD_SWITCHES = ("CONTROLKIT_MODULES", "CONTROLKIT_WARMUP", "CONTROLKIT_BACKGROUND_COMPILE")


def median_seconds(function, repeats=5) -> float:
    """The median wall time, in seconds, of ``repeats`` calls of ``function()``."""
    samples = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        samples.append(time.perf_counter() - start)
    return statistics.median(samples)


def checkout_env(checkout=None, store=None, **extra) -> dict:
    """The environment of a child process that imports controlkit from ``checkout`` (None:
    the installed one) with its compiled code kept in ``store`` (None: the default).

    As on a user's install, Python writes and reads its ``.pyc`` files
    (``PYTHONDONTWRITEBYTECODE`` is removed: with it every fresh process compiles the
    package's sources again, about 0.1 s of a first call); the tests' diagram builders
    and this folder's modules are importable; an older engine's switches are left unset.
    """
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONDONTWRITEBYTECODE", *OLD_SWITCHES)}
    path = [str(checkout)] if checkout else []
    env["PYTHONPATH"] = os.pathsep.join(path + [str(ROOT / "tests"), str(HERE)])
    if store:
        env["CONTROLKIT_CACHE_DIR"] = str(store)
    env.update({k: str(v) for k, v in extra.items() if v is not None})
    return env


def add_checkout_arguments(parser) -> None:
    """The options naming the two checkouts timed and their stores: ``--before``,
    ``--after``, ``--store``, ``--before-store`` (read by :func:`checkout_env`'s callers)."""
    parser.add_argument("--before", metavar="DIR", help="another checkout, timed beside")
    parser.add_argument("--after", metavar="DIR",
                        help="the checkout timed as 'after' (default: the installed one)")
    parser.add_argument("--store", help="this checkout's store (default: the user's)")
    parser.add_argument("--before-store", default=str(Path.home() / ".cache" / "controlkit"
                                                      / "bench-before"))


def run_child(args, env, timeout=3600) -> tuple[dict, float, str]:
    """Run ``python args`` with ``env``: its last stdout line read as JSON, its wall time
    in seconds, and its stderr."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, *map(str, args)], env=env, capture_output=True,
                         text=True, timeout=timeout)
    wall = time.perf_counter() - start
    if out.returncode:
        raise RuntimeError(f"{' '.join(map(str, args))} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1]), wall, out.stderr


def load() -> str:
    """The load average over the last minute, as the tables print it."""
    return f"{os.getloadavg()[0]:.1f}"
