"""``controlkit reproduce``: run studies and write their CSV, metrics, figures and manifest.

Each study is one :class:`~controlkit.studies.registry.Study` entry of
:data:`controlkit.studies.STUDIES`; each case is one entry of its scenario's
``CASES``. Adding a study or a case adds no code here.

Under faults (see ``docs/sweeps.md``, "When things go wrong"):

- **One run per output folder.** The folder is locked
  (:class:`controlkit._lock.FolderLock`, file ``OUT/.lock``) while a run writes into it;
  a second run is refused with the holder's pid, command and start time. A lock left by
  a killed run is taken over at once.
- **run.json tells the truth.** Each study's manifest says, per case, ``done``,
  ``failed`` (with its ``error``), ``interrupted`` or ``skipped``; ``files`` lists the
  files of this run that exist, ``missing_files`` those that should have been written and
  are not (a figure that failed is in ``failed_figures``); ``complete`` is true only when
  every case is done and every file written.
- **Leftovers are cleaned at the next start.** A killed run leaves temporary files
  (``.NAME.PID.TOKEN.partial``) and a manifest with cases still ``pending`` or
  ``running``; the next run in the folder removes the former and corrects the latter
  (``interrupted``), in every study's folder.
"""

from __future__ import annotations

import contextlib
import sys
import time
from pathlib import Path

from ..blocks.spacecraft import SingularDecouplingError
from ..outputs.export import write_csv, write_json
from ..outputs.workers import FigureError, FigureWorkers
from . import STUDIES
from .registry import Study, UsageError


def _progress_printer(label: str, stream=None):
    stream = stream or sys.stderr
    start = time.perf_counter()

    def report(fraction):
        elapsed = time.perf_counter() - start
        stream.write(f"\r  {label}: {100 * fraction:5.1f} %  ({elapsed:6.1f} s)")
        if fraction >= 1:
            stream.write("\n")
        stream.flush()

    return report


#: Memory a run may hold (bytes); a request that needs more is refused before it starts.
MEMORY_LIMIT = 4_000_000_000


#: Samples per curve the figures are drawn from (independent of the CSV's --stride).
FIGURE_POINTS = 20_000


#: The manifest of a study's folder: what this run wrote, with its settings.
MANIFEST = "run.json"


#: Errors that end one case (its loop diverged or met a singular point) but not the run.
#: Any other error of a case ends its case too, and the run goes on, unless
#: ``raise_errors`` (the command line's ``--debug``) asks for it to be raised.
CASE_FAILURES = (FloatingPointError, ArithmeticError, SingularDecouplingError)


#: The lock file of an output folder (see the module's notes).
LOCK_FILE = ".lock"


#: Keywords of a case's run that reproduce sets itself, and where they are given instead.
OWN_OPTIONS = {
    "case": "choose cases with --case (cases=)",
    "horizon": "give it with --horizon (horizon=)",
    "engine": "choose it with --engine (engine=)",
    "progress": "reproduce reports progress itself",
    "record_every": "reproduce thins the figures' samples itself; --stride thins the CSV",
    "on_chunk": "reproduce streams the CSV rows itself",
}


#: About how many bytes a CSV row takes per signal of the run (the spacecraft's rows of
#: its 60 signals: 145 bytes), to refuse a run whose CSV cannot fit on the disk.
CSV_BYTES_PER_SIGNAL = 2


def _steps(s: Study, horizon, options=None) -> int:
    """Samples of a ``s`` run over ``horizon`` seconds (``None``: its published horizon),
    at the sampling period ``options["Ts"]`` if that is given (and a number > 0)."""
    Ts = (options or {}).get("Ts", s.Ts)
    if isinstance(Ts, bool) or not isinstance(Ts, int | float) or not Ts > 0:
        Ts = s.Ts  # the run refuses it, naming it
    return round((horizon or s.horizon) / Ts) + 1


def _select_cases(studies: list[Study], requested) -> dict[str, list[str]]:
    if requested is None:
        return {s.name: list(s.default_cases) for s in studies}
    if isinstance(requested, str):  # one case given as a string, not its letters
        requested = [requested]
    requested = list(requested)
    if not requested:
        raise UsageError("cases must name at least one case (or be None for the defaults)")
    repeated = sorted({c for c in requested if requested.count(c) > 1}, key=str)
    if repeated:
        raise UsageError(f"case {repeated} is given more than once; name each case once")
    known = {c for s in studies for c in s.cases}
    unknown = [c for c in requested if c not in known]
    if unknown:
        allowed = {s.name: list(s.cases) for s in studies}
        raise UsageError(f"unknown case {unknown}; known cases: {allowed}")
    return {s.name: [c for c in requested if c in s.cases] for s in studies}


def _horizons(studies, horizon) -> dict[str, float | None]:
    """``horizon`` as one value for all studies, or ``{study: seconds}`` (checked now)."""
    from ..blocks.sampling import time_grid

    if horizon is None or isinstance(horizon, dict):
        given = dict(horizon or {})
        unknown = sorted(set(given) - {s.name for s in STUDIES.values()})
        if unknown:
            raise UsageError(f"horizon names unknown studies {unknown}; studies: "
                             f"{list(STUDIES)}")
    else:
        given = {s.name: horizon for s in studies}
    out = {}
    for s in studies:
        value = given.get(s.name)
        if value is None:
            out[s.name] = None
            continue
        if isinstance(value, bool):
            raise UsageError(f"horizon must be a number of seconds, got {value!r}")
        try:
            time_grid(value, s.Ts, lazy=True)  # checked without making its samples
        except ValueError as error:
            raise UsageError(f"horizon for {s.name}: {error}") from None
        out[s.name] = float(value)
    return out


def _checked_folder(out) -> Path:
    """``out`` as a folder path (``~`` expanded), refused without creating anything when
    empty (it would mean the current folder), a file, or under a file or a place that
    cannot be written."""
    import os

    if not isinstance(out, str | os.PathLike):
        raise UsageError(f"out must be a folder path, got {out!r}")
    if not str(os.fspath(out)).strip():
        raise UsageError(f"out must name a folder, got {out!r}")
    folder = Path(out).expanduser()
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"out {str(folder)!r} is a file, not a folder")
    existing = folder.absolute()
    while not existing.exists():
        existing = existing.parent
    if not existing.is_dir():
        raise UsageError(f"cannot write to out {str(folder)!r}: {existing} is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise UsageError(f"cannot write to out {str(folder)!r}: {existing} is not writable")
    return folder


def _writable(out) -> Path:
    """Create ``out`` and prove it writable before anything is simulated."""
    import tempfile

    out = _checked_folder(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".write-test-"):
            pass
    except OSError as error:
        raise UsageError(f"cannot write to out {str(out)!r}: "
                         f"{error.strerror or error}") from None
    return out


def _read_manifest(folder: Path) -> dict | None:
    import json

    try:
        data = json.loads((folder / MANIFEST).read_text())
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def _stale(folder: Path, s: Study) -> None:
    """Remove the files of the run that wrote ``folder`` before this one: those its
    manifest lists, and the CSV of each case it did not finish (a run killed between
    writing a CSV and listing it)."""
    earlier = _read_manifest(folder)
    if earlier is None:
        return
    names = set(earlier.get("files", [])) | set(earlier.get("missing_files", []))
    cases = earlier.get("cases", {})
    if s.write is None and isinstance(cases, dict):
        names |= {f"{s.csv_stem(case)}.csv" for case, entry in cases.items()
                  if case in s.cases and isinstance(entry, dict)
                  and entry.get("status") != "done"}
    for name in names:
        if isinstance(name, str) and "/" not in name and (folder / name).is_file():
            (folder / name).unlink()


def _settle(folder: Path, log) -> None:
    """Clean what a killed run left in a study's folder (this process holds the lock, so
    no run is writing there): its temporary files, and a manifest that still says
    ``pending`` or ``running``, or lists files that were never written."""
    if not folder.is_dir():
        return
    removed, size = 0, 0
    for leftover in folder.glob(".*.partial"):
        with contextlib.suppress(OSError):
            size += leftover.stat().st_size
            leftover.unlink()
            removed += 1
    if removed:
        log.write(f"  {folder}: removed {removed} temporary file(s) of an unfinished run "
                  f"({size / 1e6:.1f} MB)\n")
    manifest = _read_manifest(folder)
    if manifest is None or not isinstance(manifest.get("cases"), dict):
        return
    unfinished = [c for c, e in manifest["cases"].items()
                  if isinstance(e, dict) and e.get("status") in ("pending", "running")]
    files = [f for f in manifest.get("files", []) if isinstance(f, str)]
    missing = [f for f in files if "/" in f or not (folder / f).is_file()]
    if not unfinished and not missing:
        return
    for case in unfinished:
        manifest["cases"][case] = {"status": "interrupted"}
    manifest["files"] = [f for f in files if f not in missing]
    manifest["missing_files"] = sorted(set(manifest.get("missing_files", [])) | set(missing))
    manifest["complete"], manifest["interrupted"] = False, True
    with contextlib.suppress(OSError):
        write_json(folder / MANIFEST, manifest)
    log.write(f"  {folder / MANIFEST}: the run that wrote it ended before finishing; "
              f"marked {len(unfinished)} case(s) interrupted and {len(missing)} file(s) "
              "missing\n")


def _finish(folder: Path, manifest: dict, interrupted: bool) -> None:
    """Write a study's manifest as the run leaves it: cases that never ended are
    ``interrupted`` (or ``skipped`` after an error), files are listed if they exist,
    ``complete`` only if every case is done and every file is there."""
    for entry in manifest["cases"].values():
        if entry["status"] in ("pending", "running"):
            if interrupted:
                entry["status"] = "interrupted"
            else:
                entry.update(status="skipped", reason="the run stopped at an earlier error")
    missing = [f for f in manifest["files"] if not (folder / f).is_file()]
    manifest["files"] = [f for f in manifest["files"] if f not in missing]
    if missing:
        manifest["missing_files"] = missing
    if interrupted:
        manifest["interrupted"] = True
    manifest["complete"] = (not missing and not interrupted and "error" not in manifest
                            and all(c["status"] == "done" for c in manifest["cases"].values()))
    with contextlib.suppress(OSError):  # the folder may have become unwritable meanwhile
        write_json(folder / MANIFEST, manifest)


def _check_options(s: Study, cases: list[str], options: dict) -> dict[str, list[str]]:
    """Refuse options a case's run does not take, that reproduce sets itself, or that no
    case of this run reads; return, per case, the options it does not read."""
    for name in options:
        if not isinstance(name, str):
            raise UsageError(f"option names must be texts, got {name!r}")
        if name in OWN_OPTIONS:
            raise UsageError(f"option {name!r} is set by reproduce itself ({OWN_OPTIONS[name]}); "
                             "it cannot be given with --set (options=)")
    if not options:
        return {}
    if hasattr(s.run, "check"):
        s.run.check(options)
    reads = getattr(s.run, "reads", None)
    if reads is None:  # every case reads every option its run takes
        return {}
    unread = {case: sorted(set(options) - set(reads(case))) for case in cases}
    for name in options:
        if all(name in unread[case] for case in cases):
            readers = [c for c in s.cases if name in reads(c)]
            raise UsageError(f"option {name!r} is read by none of the {s.name} cases run "
                             f"({', '.join(cases)}), so it would change nothing; it is read by "
                             + (", ".join(readers) + " (--case NAME)" if readers else "no case"))
    return {case: names for case, names in unread.items() if names}


def _disk_check(out, need: int, what: str) -> None:
    import shutil

    existing = Path(out).expanduser().absolute()
    while not existing.exists():
        existing = existing.parent
    try:
        usage = shutil.disk_usage(existing)
    except OSError:
        return
    free = usage.free
    if usage.total and need > free:  # (a pseudo file system, sysfs say, has no size)
        raise UsageError(f"{what} would take about {need / 1e9:.3g} GB; {existing} has "
                         f"{free / 1e9:.3g} GB free; shorten the horizon or raise the stride")


def reproduce(study="all", *, out="results", cases=None, horizon=None, stride=None,
              engine="fast", log=None, workers=None, options=None,
              raise_errors=False) -> dict:
    """Run studies and write their CSV, metrics and figures (the CLI's main job).

    Every argument is checked, and the output folder created, written to and locked,
    before anything is simulated. Each file is written under a temporary name and renamed
    when complete; each study's folder gets a manifest, ``run.json``, listing the files of
    this run with its settings and the status of every case (``done``, ``failed`` with
    its error, ``interrupted``, ``skipped``), and files that an earlier run listed there
    are removed. A case that fails (a loop that diverges, a value its run refuses) is
    recorded with its error while the other cases complete. ``complete`` is true only
    when every case is done and every listed file exists. What a killed run left behind
    is cleaned first (see the module's notes).

    Parameters
    ----------
    study : str
        A key of :data:`STUDIES` or ``"all"`` (the studies with ``in_all``).
    out : str or pathlib.Path
        Output folder; each study writes to ``out/<study>/``. Locked while the run
        writes (``out/.lock``).
    cases : str or list of str, optional
        Cases to run (default: each study's default cases); one text is one case.
    horizon : float or dict, optional
        Simulated time in seconds for every study, or ``{study: seconds}`` (default:
        each study's published horizon).
    stride : int, optional
        Keep every ``stride``-th sample in the CSV (default 10 for the spacecraft,
        i.e. 1 s; 1 for the CMG). The figures are drawn from enough samples whatever
        the stride, and the metrics from every sample. Refused for a study that writes
        no time series (``frit``).
    engine : {"fast", "python-control"}
        Simulator; both give the same numbers, the fast one in seconds.
    log : file-like, optional
        Where progress goes (default stderr).
    workers : int, optional
        Processes drawing the figures while the next study is simulated (default: one
        per CPU, at most 4; 0 draws them in this process).
    options : dict, optional
        Keyword arguments passed to every case's ``run`` (e.g. ``{"F": 0.002}``). One
        that no case run reads is refused; one that some cases do not read is noted in
        their manifest entry (``unused_options``).
    raise_errors : bool
        Raise a case's error (other than :data:`CASE_FAILURES`) instead of recording it
        and going on (the command line's ``--debug``); the manifest still records it.

    Returns
    -------
    dict
        ``{study: {case: metrics}}``; a failed case has ``{"error": message}``.

    Raises
    ------
    UsageError
        A bad argument, an unusable output folder, or a folder in use by another run
        (nothing simulated, nothing written).
    FigureError
        Figures that could not be written (the run's other files are kept; the manifest
        lists the figures and why).

    Examples
    --------
    >>> import io, tempfile
    >>> m = reproduce("spacecraft", out=tempfile.mkdtemp(), cases=["ideal"], horizon=1.0,
    ...               log=io.StringIO())
    >>> sorted(m["spacecraft"])
    ['ideal']
    """
    from .._lock import FolderLock, LockHeld
    from ..engines import ENGINES

    log = log or sys.stderr
    if study != "all" and study not in STUDIES:
        raise UsageError(f"unknown study {study!r}; choose from {['all', *STUDIES]}")
    studies = ([s for s in STUDIES.values() if s.in_all] if study == "all"
               else [STUDIES[study]])
    selection = _select_cases(studies, cases)
    horizons = _horizons(studies, horizon)
    if stride is not None and (isinstance(stride, bool) or not isinstance(stride, int)
                               or stride < 1):
        raise UsageError(f"stride must be an integer >= 1, got {stride!r}")
    if engine not in ENGINES:
        raise UsageError(f"engine must be one of {ENGINES}, got {engine!r}")
    if options is not None and not isinstance(options, dict):
        raise UsageError(f"options must be a dict of keyword -> value, got {options!r}")
    if not isinstance(raise_errors, bool):
        raise UsageError(f"raise_errors must be True or False, got {raise_errors!r}")
    options = dict(options or {})
    unread, csv_bytes = {}, 0
    for s in studies:
        if not selection[s.name]:
            continue
        unread[s.name] = _check_options(s, selection[s.name], options)
        if s.write is not None:
            if stride is not None:
                raise UsageError(f"stride does not apply to the {s.name} study: it writes "
                                 "tables of metrics, not time series; omit --stride")
            continue
        steps = _steps(s, horizons[s.name], options)
        step = stride if stride is not None else s.default_stride
        if stride is not None and steps // step < 2:
            raise UsageError(f"stride {step} keeps {1 + (steps - 1) // step} sample(s) of the "
                             f"{steps} of a {s.name} run; choose a stride below {steps // 2}")
        held = steps if s.streaming is None or engine != "fast" else FIGURE_POINTS
        need = held * s.signals * 8 * 3  # the run, its table and the CSV's copy
        if need > MEMORY_LIMIT:
            raise UsageError(
                f"a {s.name} run of {steps} steps would hold about {need / 1e9:.1f} GB in "
                f"memory (limit {MEMORY_LIMIT / 1e9:.0f} GB); shorten the horizon to at "
                f"most {MEMORY_LIMIT // (s.signals * 24) * s.Ts:g} s")
        csv_bytes += (1 + (steps - 1) // step) * s.signals * CSV_BYTES_PER_SIGNAL * len(
            selection[s.name])
    out = _checked_folder(out)
    for s in studies:
        manifest = out / s.name / MANIFEST
        if selection[s.name] and (manifest.is_dir() or manifest.is_symlink()
                                  and not manifest.is_file()):
            raise UsageError(f"{manifest} is not a file (a folder, or a broken link), so the "
                             "run's manifest cannot be written there; move it away")
    _disk_check(out, csv_bytes, "the CSV files of this run")
    out = _writable(out)
    summary, manifests = {}, {}
    # the workers are started before the lock is taken: a forked worker would otherwise
    # share it, and hold the folder for a moment after this process is killed
    pool = FigureWorkers(workers)
    try:
        lock = FolderLock(out, name=LOCK_FILE, purpose="controlkit reproduce").acquire()
    except LockHeld as error:
        pool.close()
        raise UsageError(str(error)) from None
    except OSError as error:  # e.g. a folder under the lock file's name
        pool.close()
        raise UsageError(f"cannot lock out {str(out)!r} ({out / LOCK_FILE}): "
                         f"{error.strerror or error}; move it away") from None
    except BaseException:
        pool.close()
        raise
    if lock.taken_over:
        log.write(f"  {out}: the run that held it (process {lock.taken_over.get('pid')}) "
                  "ended without finishing; what it left is cleaned\n")
    interrupted = False
    try:
        with pool:
            for name in STUDIES:
                _settle(out / name, log)
            for s in sorted(studies, key=lambda study: study.simulation_cost):
                if not selection[s.name]:
                    continue
                summary[s.name] = _run_study(s, selection[s.name], out / s.name,
                                             horizons[s.name], stride, engine, log, pool,
                                             options, unread.get(s.name, {}), manifests,
                                             raise_errors)
            try:
                for path in pool.results():
                    log.write(f"  wrote {path}\n")
            except FigureError as error:
                for folder, stem, why in error.failures:
                    if folder in manifests:
                        manifests[folder].setdefault("failed_figures", {})[stem] = why
                raise
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        for folder, manifest in manifests.items():
            _finish(Path(folder), manifest, interrupted)
        lock.release()
    return {s.name: summary[s.name] for s in studies if s.name in summary}


def _describe(error: BaseException) -> str:
    return f"{type(error).__name__}: {error}"


def _run_study(s, cases, folder, horizon, stride, engine, log, pool, options, unread,
               manifests, raise_errors) -> dict:
    """Run one study's cases, writing files and the manifest as each finishes.

    The manifest is registered in ``manifests`` (by folder) for :func:`reproduce` to
    finish once the figures are drawn.
    """
    folder.mkdir(parents=True, exist_ok=True)
    step = stride if stride is not None else s.default_stride
    manifest = {"study": s.name, "horizon_s": horizon or s.horizon, "stride": step,
                "engine": engine, "options": options, "complete": False,
                "cases": {case: {"status": "pending"} for case in cases}, "files": []}
    _stale(folder, s)
    write_json(folder / MANIFEST, manifest)
    manifests[str(folder)] = manifest

    def done(name, **entry):
        if unread.get(name):
            entry["unused_options"] = unread[name]
        manifest["cases"][name] = entry
        manifest["files"] = sorted({f for c in manifest["cases"].values()
                                    for f in c.get("files", [])} | set(manifest["files"]))
        write_json(folder / MANIFEST, manifest)

    for case, names in unread.items():
        log.write(f"  note: {s.name}/{case} does not read option(s) {names}; it runs "
                  "without them\n")
    study_metrics, tables, results = {}, {}, {}
    try:
        for case in cases:
            log.write(f"{s.name}/{case}\n")
            manifest["cases"][case] = {"status": "running"}
            write_json(folder / MANIFEST, manifest)
            started = time.perf_counter()
            progress = _progress_printer(f"{s.name}/{case}", log)
            csv_name = f"{s.csv_stem(case)}.csv"
            try:
                if s.write is not None:
                    results[case] = s.run(case, horizon, progress, engine, **options)
                    done(case, status="done")
                    continue
                if s.streaming is not None and engine == "fast":
                    columns, metrics = _streamed(s, case, horizon or s.horizon, step,
                                                 folder / csv_name, progress, options)
                else:
                    resp = s.run(case, horizon, progress, engine, **options)
                    columns = s.table(resp)
                    write_csv(folder / csv_name, s.csv_columns(columns), stride=step)
                    metrics = s.metrics(columns)
            except Exception as error:  # the case's own failure: recorded, the run goes on
                message = _describe(error)
                log.write(f"\n  {s.name}/{case} failed: {message}\n")
                study_metrics[case] = {"error": message}
                done(case, status="failed", error=message)
                if raise_errors and not isinstance(error, CASE_FAILURES):
                    raise
                continue
            elapsed = time.perf_counter() - started
            every = max(1, len(next(iter(columns.values()))) // FIGURE_POINTS)
            tables[case] = {name: values[::every] for name, values in columns.items()}
            study_metrics[case] = {**metrics, "wall_time_s": round(elapsed, 3)}
            done(case, status="done", files=[csv_name])
        if s.write is not None:
            written, paths = s.write(results, folder) if results else ({}, [])
            study_metrics = {**{c: m for c, m in study_metrics.items() if c not in written},
                             **written}
            log.writelines(f"  wrote {path}\n" for path in paths)
            manifest["files"] = sorted({p.name for p in paths})
        else:
            write_json(folder / "metrics.json", study_metrics)
            manifest["files"] = sorted(set(manifest["files"]) | {"metrics.json"})
            if tables:
                names = _figure_files(s, tables)
                manifest["files"] = sorted(set(manifest["files"]) | set(names))
                if s.figure_stems:  # drawn by the workers while the next study runs
                    pool.submit(s.figures, tables, folder, s.stems(tuple(tables)),
                                first=s.draw_first, columns=s.figure_columns)
                else:
                    for path in s.figures(tables, folder):
                        log.write(f"  wrote {path}\n")
    except KeyboardInterrupt:
        for entry in manifest["cases"].values():
            if entry["status"] in ("pending", "running"):
                entry["status"] = "interrupted"
        manifest["interrupted"] = True
        raise
    except Exception as error:  # writing the study's files failed
        if not any(c.get("error") == _describe(error) for c in manifest["cases"].values()):
            manifest["error"] = _describe(error)
        raise
    finally:
        with contextlib.suppress(OSError):
            write_json(folder / MANIFEST, manifest)
    return study_metrics


def _streamed(s, case, horizon, stride, csv_path, progress, options):
    """Run one case streamed: CSV rows written as computed, metrics from every sample.

    Returns the figures' columns (about :data:`FIGURE_POINTS` samples) and the metrics.
    """
    from types import SimpleNamespace

    import numpy as np

    from ..outputs.export import atomic, write_rows

    watch = s.streaming(case, horizon)
    steps = _steps(s, horizon)
    seen = [0]
    with atomic(csv_path) as partial, partial.open("w") as handle:
        header = None

        def on_chunk(t, y, x):
            nonlocal header
            watch(t, y, x)
            cols = s.csv_columns(s.table(SimpleNamespace(
                time=t, outputs=y, states=x, output_labels=watch.labels)))
            if header is None:
                header = ",".join(cols)
                handle.write(header + "\n")
            first = (-seen[0]) % stride  # rows 0, stride, 2 stride, ... of the whole run
            rows = np.column_stack([np.asarray(v, dtype=float) for v in cols.values()])
            write_rows(handle, rows[first::stride])
            seen[0] += t.size

        resp = s.run(case, horizon, progress, "fast", on_chunk=on_chunk,
                     record_every=max(1, steps // FIGURE_POINTS), **options)
    return s.table(resp), watch.metrics()


def _figure_files(s, tables) -> list[str]:
    """The figure files a study will write for these tables (PNG and vector copies)."""
    from ..outputs.style import VECTOR_FORMATS

    stems = s.stems(tuple(tables)) if s.figure_stems else ()
    return [f"{stem}.{ext}" for stem in stems for ext in ("png", *VECTOR_FORMATS)]
