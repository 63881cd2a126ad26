"""The ``reproduce`` call: arguments checked, the output folder locked, leftovers of a
killed run cleaned, each study run, the figures awaited and every manifest finished."""

from __future__ import annotations

import sys
from pathlib import Path

from ...outputs.workers import FigureError, FigureWorkers
from .. import STUDIES
from ..registry import UsageError
from .checks import (
    CSV_BYTES_PER_SIGNAL,
    MEMORY_LIMIT,
    _check_options,
    _checked_folder,
    _disk_check,
    _horizons,
    _select_cases,
    _steps,
    _writable,
)
from .manifest import MANIFEST, _finish, _settle
from .study import FIGURE_POINTS, _run_study

#: The lock file of an output folder (see the module's notes).
LOCK_FILE = ".lock"


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
    from ..._lock import FolderLock, LockHeld
    from ...engines import ENGINES

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

