"""Compare two output folders of ``controlkit reproduce`` (or ``sweep``): same results?

Used to show that a change of code leaves the results alone::

    python -m controlkit reproduce --out /tmp/before        # on the old checkout
    python -m controlkit reproduce --out /tmp/after         # on the new one
    python benchmarks/compare_outputs.py /tmp/before /tmp/after

What counts as the same:

- CSV and other text files: byte for byte;
- JSON (``metrics.json``, ``run.json``, ``summary.json``): equal once parsed, wall times
  (keys ``wall_time_s``) aside;
- PNG: the same pixels (decoded with Pillow) and the same dpi;
- SVG: the same text once the date in its metadata and matplotlib's random clip-path and
  glyph ids (``svg.hashsalt``) are blanked.

Prints one line per difference and exits 1 if there is any, 0 otherwise.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from pathlib import Path


def _without_wall_times(value):
    if isinstance(value, dict):
        return {k: _without_wall_times(v) for k, v in value.items() if k != "wall_time_s"}
    if isinstance(value, list):
        return [_without_wall_times(v) for v in value]
    return value


_SVG_VOLATILE = [
    (re.compile(r"<dc:date>[^<]*</dc:date>"), "<dc:date/>"),
    (re.compile(r"\b(p|m|DejaVu)[0-9a-f]{10}\b"), r"\1_"),  # hashed clip-path / glyph ids
]


def _svg_text(path: Path) -> str:
    text = path.read_text()
    for pattern, repl in _SVG_VOLATILE:
        text = pattern.sub(repl, text)
    return text


def differences(a: Path, b: Path) -> list[str]:
    """Every difference between folders ``a`` and ``b``, one line each."""
    import numpy as np
    from PIL import Image

    out = []
    names_a = {p.relative_to(a) for p in a.rglob("*") if p.is_file()}
    names_b = {p.relative_to(b) for p in b.rglob("*") if p.is_file()}
    skip = {"store"}  # a sweep's run store: its rows carry wall times and its key the path
    for name in sorted(names_a ^ names_b):
        if not skip & set(name.parts):
            out.append(f"only in {'first' if name in names_a else 'second'}: {name}")
    for name in sorted(names_a & names_b):
        if skip & set(name.parts):
            continue
        pa, pb = a / name, b / name
        if name.suffix == ".json":
            if _without_wall_times(json.loads(pa.read_text())) != _without_wall_times(
                    json.loads(pb.read_text())):
                out.append(f"differs: {name}")
        elif name.suffix == ".png":
            with Image.open(pa) as ia, Image.open(pb) as ib:
                same = (ia.size == ib.size and np.array_equal(np.asarray(ia), np.asarray(ib))
                        and ia.info.get("dpi") == ib.info.get("dpi"))
            if not same:
                out.append(f"differs (pixels or dpi): {name}")
        elif name.suffix == ".svg":
            if _svg_text(pa) != _svg_text(pb):
                out.append(f"differs: {name}")
        elif name.name == "sweep.csv":
            if _sweep_rows(pa) != _sweep_rows(pb):
                out.append(f"differs: {name}")
        elif pa.read_bytes() != pb.read_bytes():
            out.append(f"differs: {name}")
    return out


def _sweep_rows(path: Path) -> list[list[str]]:
    """A sweep table's cells, its ``wall_time_s`` column aside."""
    import csv

    with path.open() as handle:
        rows = list(csv.reader(handle))
    if not rows or "wall_time_s" not in rows[0]:
        return rows
    drop = rows[0].index("wall_time_s")
    return [row[:drop] + row[drop + 1:] for row in rows]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    args = parser.parse_args(argv)
    found = differences(args.first, args.second)
    for line in found:
        print(line)
    print(f"{len(found)} difference(s) between {args.first} and {args.second}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
