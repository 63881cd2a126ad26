"""A study folder's manifest, ``run.json``, which tells the truth after every fault: the
files of the run that wrote it, the status of each case; and what a killed run left
behind, cleaned at the next start."""

from __future__ import annotations

import contextlib
from pathlib import Path

from ...outputs.export import write_json
from ..registry import Study

#: The manifest of a study's folder: what this run wrote, with its settings.
MANIFEST = "run.json"


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

