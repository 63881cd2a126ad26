"""controlkit reproduce: files, columns and argument errors."""

import csv
import json
import subprocess
import sys

import pytest

from controlkit.cli import main
from controlkit.outputs.spacecraft import COLUMNS

FIGS = ["fig05_h1", "fig06_h2", "fig07_pointing_error", "fig08_K", "fig09_u1", "fig10_u2"]


def test_reproduce_spacecraft_short_horizon_writes_files(tmp_path):
    assert main(["reproduce", "spacecraft", "--horizon", "20", "--out", str(tmp_path)]) == 0
    folder = tmp_path / "spacecraft"
    for case in ("ideal", "without_mec", "proposed"):
        with open(folder / f"{case}.csv") as f:
            rows = list(csv.reader(f))
        assert rows[0] == list(COLUMNS)
        assert len(rows) == 1 + 21  # 0..20 s every 1 s (stride 10 at 0.1 s)
        assert float(rows[-1][0]) == pytest.approx(20.0)
    m = json.loads((folder / "metrics.json").read_text())
    assert set(m) == {"ideal", "without_mec", "proposed"}
    for key in ("final_pointing_error_deg", "max_pointing_error_last_half_deg",
                "peak_abs_u1_rad_s", "peak_abs_u2_rad_s"):
        assert m["ideal"][key] > 0
    for stem in FIGS:
        assert (folder / f"{stem}.png").stat().st_size > 10_000


def test_case_and_stride_options(tmp_path):
    main(["reproduce", "spacecraft", "--case", "ideal", "--horizon", "2", "--stride", "1",
          "--out", str(tmp_path)])
    assert sorted(p.name for p in (tmp_path / "spacecraft").glob("*.csv")) == ["ideal.csv"]
    lines = (tmp_path / "spacecraft" / "ideal.csv").read_text().splitlines()
    assert len(lines) == 1 + 21


def test_unknown_case_names_the_known_ones(tmp_path, capsys):
    assert main(["reproduce", "spacecraft", "--case", "nope", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown case ['nope']; known cases: {'spacecraft': ['ideal'" in err
    assert len(err.strip().splitlines()) == 1 and not any(tmp_path.iterdir())


@pytest.mark.parametrize(("args", "message"), [
    (["--stride", "0"], "stride must be an integer >= 1, got 0"),
    (["--horizon", "-5"], "horizon must be finite and > 0, got -5.0"),
])
def test_bad_numbers_are_refused(args, message, capsys):
    assert main(["reproduce", "spacecraft", *args]) == 2
    assert message in capsys.readouterr().err


def test_console_script_runs_as_module(tmp_path):
    out = subprocess.run([sys.executable, "-m", "controlkit", "reproduce", "spacecraft",
                          "--case", "ideal", "--horizon", "1", "--out", str(tmp_path)],
                         capture_output=True, text=True, check=True)
    assert "spacecraft/ideal:" in out.stdout


def test_help_lists_every_case(capsys):
    with pytest.raises(SystemExit):
        main(["reproduce", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for case in ("ideal", "without_mec", "proposed", "mec_fixed", "proposed_literal", "thesis",
                 "strong_friction"):
        assert case in text
