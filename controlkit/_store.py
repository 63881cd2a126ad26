"""A sweep's store: one folder, a spec naming the sweep and its finished runs, one per line.

What it promises (the ones a database makes, for one table of rows):

- **Only appended to.** ``runs.jsonl`` is never truncated or rewritten. A missing or
  damaged ``sweep.json`` is rebuilt from the rows when every row matches the sweep being
  resumed (a damaged one is kept beside it as ``sweep.json.damaged``), or the resume is
  refused with the file named; the rows stay.
- **Rows whole.** Each row is one ``write`` of one complete line; a row always starts on a
  fresh line (a line cut by an interruption is closed first), so no row is glued to
  another. Rows glued by an earlier version are taken apart when read.
- **Rows checked when read back.** A line that is not JSON, or a row that lacks a field,
  names a run outside the sweep, or disagrees with the sweep's parameters for its run, is
  skipped with a warning naming the file and line; its run is made again.
- **One writer.** The store is locked (:class:`controlkit._lock.FolderLock`) from opening
  to closing; a second sweep, or a resume started while the sweep still runs, is refused
  with the holder named.
- **Rows go where a resume reads them.** A runs file removed while the sweep runs (the
  store deleted by hand) is made again at the next row, with a warning, instead of rows
  being appended to a removed file.
"""

from __future__ import annotations

import json
import math
import os
import re
from pathlib import Path

from ._checks import warn_caller
from ._lock import FolderLock, LockHeld
from .outputs.export import atomic, json_default

#: Where finished runs are appended, inside the store.
RUNS_FILE = "runs.jsonl"
#: What identifies a sweep inside the store (so ``resume`` never mixes two sweeps).
SPEC_FILE = "sweep.json"
#: The lock file inside the store.
LOCK_FILE = ".lock"
#: Fields every stored row has, besides its parameters.
ROW_FIELDS = ("run", "error", "wall_time_s")
#: How many problems a warning lists before "and N more".
SHOWN_PROBLEMS = 5

_ROW_START = re.compile(r'\{"run": ')


class StoreWarning(UserWarning):
    """Something in a store was skipped or rebuilt; the warning says what and where.

    Examples
    --------
    >>> issubclass(StoreWarning, UserWarning)
    True
    """


def plain(value):
    """``value`` as it reads back from JSON (tuples as lists, numpy scalars as numbers).

    Examples
    --------
    >>> import numpy as np
    >>> plain({"a": (1, np.float64(2.5))})
    {'a': [1, 2.5]}
    """
    return json.loads(json.dumps(value, default=json_default))


def same_value(a, b) -> bool:
    """Equal as stored values: numbers by value (1 == 1.0, nan == nan), the rest as JSON.

    Examples
    --------
    >>> same_value(1, 1.0), same_value(float("nan"), float("nan")), same_value([1], [2])
    (True, True, False)
    """
    numbers = (int, float)
    if isinstance(a, numbers) and isinstance(b, numbers) and not isinstance(a, bool) \
            and not isinstance(b, bool):
        return a == b or (math.isnan(a) and math.isnan(b))
    try:
        return json.dumps(a, sort_keys=True, default=json_default) == \
            json.dumps(b, sort_keys=True, default=json_default)
    except (TypeError, ValueError):
        return a == b


def _split_glued(line: str):
    """Rows in one line: normally one; a cut row followed by whole ones (glued by an older
    writer) gives the whole ones. Yields ``(row or None, problem)``."""
    try:
        yield json.loads(line), ""
        return
    except json.JSONDecodeError as exc:
        first_error = exc
    decoder = json.JSONDecoder()
    starts = [m.start() for m in _ROW_START.finditer(line)]
    found = False
    for start in starts:
        try:
            row, end = decoder.raw_decode(line, start)
        except json.JSONDecodeError:
            continue
        if end == len(line) or _ROW_START.match(line, end):
            found = True
            yield row, ""
    if not found:
        yield None, f"not JSON ({first_error.msg} at column {first_error.colno})"
    else:
        yield None, "a cut row glued to the next one(s); the whole ones are kept"


class RunStore:
    """The store of one sweep; see the module's notes.

    Parameters
    ----------
    folder : pathlib.Path
        The store's folder.
    key : str
        What identifies the sweep (a hash of the function's name and of every run).
    runs : list of controlkit.sweep.Run
        The sweep's runs, to check rows against.
    resume : bool
        Complete the sweep already there; without it a store holding a sweep is refused.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> from controlkit.sweep import plan
    >>> runs = plan(grid={"F": [1.0, 2.0]})
    >>> store = RunStore(pathlib.Path(tempfile.mkdtemp()), "k", runs, resume=False)
    >>> store.check(); store.open()
    {}
    >>> store.append({"run": 0, "F": 1.0, "pole": 0.9, "error": "", "wall_time_s": 0.1})
    >>> store.close()
    >>> sorted(RunStore(store.folder, "k", runs, resume=True).open())
    [0]
    """

    def __init__(self, folder: Path, key: str, runs, *, resume: bool):
        self.folder = Path(folder).absolute()  # the same folder if the function changes cwd
        self.key, self.runs, self.resume = key, runs, resume
        self.spec, self.runs_file = self.folder / SPEC_FILE, self.folder / RUNS_FILE
        self._lock = None
        self._fd = None
        self._fresh_line = True  # the runs file ends with a newline (or is empty)

    # --- what is there -------------------------------------------------------------------

    def _spec_key(self):
        """``(key or None, problem)``: the spec's key, or why there is none."""
        try:
            text = self.spec.read_text()
        except FileNotFoundError:
            return None, "missing"
        except (OSError, UnicodeDecodeError) as exc:
            return None, f"unreadable ({exc})"
        try:
            data = json.loads(text)
        except json.JSONDecodeError as exc:
            return None, f"damaged (line {exc.lineno}: {exc.msg})"
        if not isinstance(data, dict) or not isinstance(data.get("key"), str):
            return None, 'damaged (line 1: no "key")'
        return data["key"], ""

    def _has_rows(self) -> bool:
        try:
            return self.runs_file.stat().st_size > 0
        except FileNotFoundError:
            return False

    def check(self) -> None:
        """Refuse, before anything is created, a store this sweep cannot use."""
        if self.folder.exists() and not self.folder.is_dir():
            raise ValueError(f"store {self.folder} is a file, not a folder")
        key, problem = self._spec_key()
        holds = key is not None or self._has_rows()
        if holds and not self.resume:
            what = "a sweep" if key is not None else f"finished runs ({self.runs_file})"
            raise ValueError(f"store {self.folder} already holds {what}; pass resume=True "
                             "(--resume) to complete it, or choose another folder")
        if key is not None and key != self.key:
            raise ValueError(f"store {self.folder} holds a different sweep (other function, "
                             "parameters, cases or seed); choose another folder")

    # --- opening ---------------------------------------------------------------------------

    def open(self) -> dict[int, dict]:
        """Lock the store, make it ready, and return its finished rows by run index."""
        self._lock = FolderLock(self.folder, name=LOCK_FILE, purpose="another sweep")
        try:
            self._lock.acquire()
        except OSError as exc:  # a folder that cannot be made or written (read-only, /proc)
            self._lock = None
            raise ValueError(f"store {self.folder} cannot be used: {exc}") from None
        try:
            if self._lock.taken_over:
                pid = self._lock.taken_over.get("pid")
                warn_caller(f"store {self.folder}: the sweep that held it (process {pid}) "
                            "ended without letting go; its finished runs are kept", StoreWarning)
            self.check()  # again, now that no one else can change it
            for leftover in self.folder.glob(f".{SPEC_FILE}.*.partial"):
                leftover.unlink(missing_ok=True)  # of a sweep killed while writing it
            finished, problems, foreign = self._read_rows()
            key, spec_problem = self._spec_key()
            if key is None:
                self._write_spec(spec_problem, finished, foreign)
            else:  # the spec vouches for the store: a row that disagrees is a damaged row
                problems = sorted(problems + foreign)
            if problems:
                shown = "; ".join(f"line {n}: {why}" for n, why in problems[:SHOWN_PROBLEMS])
                more = len(problems) - SHOWN_PROBLEMS
                warn_caller(f"{self.runs_file}: {len(problems)} line(s) skipped - {shown}"
                            + (f"; and {more} more" if more > 0 else "")
                            + " (they stay in the file; a run with no whole row is made "
                              "again)", StoreWarning)
            self._fd = os.open(self.runs_file, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
            size = os.fstat(self._fd).st_size
            self._fresh_line = size == 0 or os.pread(self._fd, 1, size - 1) == b"\n"
            return finished
        except BaseException:
            self.close()
            raise

    def _write_spec(self, problem, finished, foreign) -> None:
        if problem != "missing" or finished or foreign:
            if foreign:
                line, why = foreign[0]
                raise ValueError(f"store {self.folder}: {SPEC_FILE} is {problem} and "
                                 f"{self.runs_file} does not hold this sweep (line {line}: "
                                 f"{why}); choose another folder, or restore {SPEC_FILE}")
            if problem != "missing":
                kept = self.spec.with_name(f"{SPEC_FILE}.damaged")
                n = 1
                while kept.exists():
                    n += 1
                    kept = self.spec.with_name(f"{SPEC_FILE}.damaged.{n}")
                os.replace(self.spec, kept)
            if finished:
                warn_caller(f"store {self.folder}: {SPEC_FILE} was {problem}; rebuilt from "
                            f"the {len(finished)} row(s) of {RUNS_FILE}, which all match "
                            "this sweep's runs (the function itself cannot be checked "
                            "from rows)", StoreWarning)
        with atomic(self.spec) as partial:
            partial.write_text(json.dumps({"key": self.key}) + "\n")

    def _problem(self, row) -> tuple[str, bool]:
        """Why ``row`` cannot be kept (empty if it can), and whether it belongs to another
        sweep (rather than being incomplete)."""
        if not isinstance(row, dict):
            return f"not a row (a JSON {type(row).__name__})", False
        index = row.get("run")
        if isinstance(index, bool) or not isinstance(index, int):
            return f"no run index (run = {index!r})", False
        if not 0 <= index < len(self.runs):
            return f"run {index} is not in this sweep (it has {len(self.runs)} runs)", True
        run = self.runs[index]
        for name, value in (("case", run.case), ("seed", run.seed)):
            if name in row and row[name] != value:
                return (f"run {index} has {name} {row[name]!r}, this sweep's run {index} "
                        f"has {value!r}"), True
        for name, value in plain(run.params).items():
            if name in row and not same_value(row[name], value):
                return (f"run {index} has {name}={row[name]!r}, this sweep's run {index} "
                        f"has {name}={value!r}"), True
        own = [name for name, value in (("case", run.case), ("seed", run.seed))
               if value is not None]
        missing = [f for f in (*ROW_FIELDS, *own, *run.params) if f not in row]
        if missing:
            return f"run {index} lacks {missing}", False
        if not isinstance(row["error"], str):
            return f"run {index} has error {row['error']!r}, not a text", False
        wall = row["wall_time_s"]
        if isinstance(wall, bool) or not isinstance(wall, int | float):
            return f"run {index} has wall_time_s {wall!r}, not a number", False
        return "", False

    def _read_rows(self):
        """``(rows by run, [(line, problem)], [(line, why it is another sweep's)])``."""
        finished, problems, foreign = {}, [], []
        try:
            data = self.runs_file.read_bytes()
        except FileNotFoundError:
            return finished, problems, foreign
        except OSError as exc:  # a folder under that name, no permission, ...
            raise ValueError(f"{self.runs_file} cannot be read ({exc}); choose another "
                             "folder, or move it away (it is never removed here)") from None
        lines = data.split(b"\n")
        last = len(lines) - 1  # after the final newline: empty, or a cut line
        for number, raw in enumerate(lines, start=1):
            if not raw.strip():
                continue
            try:
                line = raw.decode()
            except UnicodeDecodeError as exc:
                problems.append((number, f"not text ({exc.reason})"))
                continue
            for row, problem in _split_glued(line):
                if row is None and not problem:  # the JSON value null: a line, not a row
                    problem = "not a row (a JSON null)"
                if row is None:
                    if number == last + 1:
                        problem = "cut (no end of line: a write interrupted)"
                    problems.append((number, problem))
                    continue
                problem, other_sweep = self._problem(row)
                if problem:
                    (foreign if other_sweep else problems).append((number, problem))
                elif row["run"] in finished:
                    problems.append((number, f"run {row['run']} again (the first is kept)"))
                else:
                    finished[row["run"]] = row
        return finished, problems, foreign

    # --- writing and closing ---------------------------------------------------------------

    def line(self, row: dict) -> str:
        """``row`` as the one line it is stored as (without its newline).

        Raises TypeError naming the value that JSON cannot hold.
        """
        try:
            return json.dumps(row, default=json_default)
        except (TypeError, ValueError):
            for name, value in row.items():
                try:
                    json.dumps(value, default=json_default)
                except (TypeError, ValueError) as exc:
                    raise TypeError(f"{name} = {value!r} cannot be stored as JSON ({exc})"
                                    ) from None
            raise

    def _keep_lock(self) -> None:
        """If the lock file was removed by hand, lock a new one, or stop: another process
        has locked the store meanwhile."""
        if self._lock.still_held():
            return
        replacement = FolderLock(self.folder, name=LOCK_FILE, purpose="another sweep")
        try:
            replacement.acquire()
        except LockHeld as exc:
            raise RuntimeError(f"the lock file {self._lock.path} was removed while this sweep "
                               f"ran, and another process has locked the store since ({exc}); "
                               "this sweep stops here, its finished runs are kept") from None
        self._lock.release()
        self._lock = replacement

    def _keep_runs_file(self) -> None:
        """If the runs file was removed or replaced while the sweep ran (the store deleted
        by hand, say), append to the file under its name rather than to one no one can
        read any more; the spec is written again if it went too. The rows of the removed
        file are gone with it (a resume makes those runs again): a warning says so."""
        try:
            mine, named = os.fstat(self._fd), os.stat(self.runs_file)
            if (mine.st_ino, mine.st_dev) == (named.st_ino, named.st_dev):
                return
        except FileNotFoundError:
            pass
        os.close(self._fd)
        self._fd = None
        self.folder.mkdir(parents=True, exist_ok=True)
        self._fd = os.open(self.runs_file, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        size = os.fstat(self._fd).st_size
        self._fresh_line = size == 0 or os.pread(self._fd, 1, size - 1) == b"\n"
        if not self.spec.exists():
            with atomic(self.spec) as partial:
                partial.write_text(json.dumps({"key": self.key}) + "\n")
        warn_caller(f"{self.runs_file} was removed or replaced while this sweep ran; its "
                    "rows go to the file now under that name (the rows of the removed "
                    "file are gone with it: a resume makes those runs again; the table "
                    "this sweep returns has them all)", StoreWarning)

    def append(self, row: dict, line: str | None = None) -> None:
        """Append ``row`` (or its ready ``line``): one write of one complete line, synced."""
        self._keep_lock()
        self._keep_runs_file()
        text = (self.line(row) if line is None else line) + "\n"
        data = (b"" if self._fresh_line else b"\n") + text.encode()
        self._fresh_line = False
        try:
            while data:
                written = os.write(self._fd, data)
                data = data[written:]
            self._fresh_line = True
            os.fsync(self._fd)
        except OSError as exc:  # a full disk, say: name the file and what is kept
            raise OSError(exc.errno, f"cannot append a row to {self.runs_file} "
                                     f"({exc.strerror}); the rows before it are kept: make "
                                     "room and resume") from None

    def close(self) -> None:
        """Close the runs file and let go of the lock (safe to call twice)."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if self._lock is not None:
            self._lock.release()
            self._lock = None
