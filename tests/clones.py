"""A fresh clone of this tree and a fresh virtual environment, for the tests that follow the
README as a reader would (tests/test_docs.py, tests/test_course.py)."""

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def fresh_clone(target: Path) -> Path:
    """Copy the files a clone of this tree would hold (tracked, or new and not ignored)."""
    listed = subprocess.run(["git", "ls-files", "-z", "--cached", "--others",
                             "--exclude-standard"], cwd=ROOT, capture_output=True, check=True)
    for name in listed.stdout.decode().split("\0"):
        source = ROOT / name
        if name and source.is_file():  # a file deleted but not yet committed is skipped
            (target / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(source, target / name)
    return target


def clean_environment(venv: Path | None = None) -> dict:
    """This process's environment without what would leak the test's own installation (its
    virtual environment, ``PYTHONPATH``, the tests' short horizons and plotting backend); with
    ``venv``, that environment's ``bin`` first on the ``PATH``, as after activating it."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("VIRTUAL_ENV", "PYTHONPATH", "CONTROLKIT_QUICK", "MPLBACKEND")}
    if venv is not None:
        env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
        env["VIRTUAL_ENV"] = str(venv)
    return env


def new_venv(venv: Path) -> Path:
    """A fresh virtual environment at ``venv``."""
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    return venv
