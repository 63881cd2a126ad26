"""Every argument of a run checked before anything is simulated: studies, cases, horizons,
options, the output folder, and the memory and disk the run would take."""

from __future__ import annotations

from pathlib import Path

from .. import STUDIES
from ..registry import Study, UsageError

MEMORY_LIMIT = 4_000_000_000


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
    from ...blocks.sampling import time_grid

    if horizon is None or isinstance(horizon, dict):
        given = dict(horizon or {})
        unknown = sorted(set(given) - {s.name for s in STUDIES.values()})
        if unknown:
            raise UsageError(f"horizon names unknown studies {unknown}; studies: "
                             f"{list(STUDIES)}")
        unused = sorted(set(given) - {s.name for s in studies})
        if unused:  # a horizon for a study this run leaves out would be dropped unseen
            raise UsageError(f"horizon names {unused}, which this run does not include (it "
                             f"runs {[s.name for s in studies]}); add the study or drop "
                             f"its horizon")
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
    from ... import _checks

    try:
        return _checks.folder("out", out)
    except ValueError as error:
        raise UsageError(str(error)) from None


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

