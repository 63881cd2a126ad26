"""`controlkit reproduce` and the `controlkit sweep` command under faults (issue 23): killed
and terminated runs, two runs on one folder, what a killed run leaves behind, run.json after
every fault, and arguments that were dropped or found late. Each test checks what is on
disk (or in the process table) afterwards.

Runs that are killed run in a process of their own (`python -m controlkit`), started in a
session of its own, so that its figure workers can be found in /proc.
"""

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from processes import alive, children_of, wait_for

from controlkit import cli
from controlkit._lock import FolderLock
from controlkit.studies.registry import UsageError
from controlkit.studies.reproduce import reproduce

ROOT = Path(__file__).parent.parent
FIGURES = ["fig05_h1", "fig06_h2", "fig07_pointing_error", "fig08_K", "fig09_u1", "fig10_u2"]
needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


def start(*args):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.Popen([sys.executable, "-m", "controlkit", *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True, env=env)


def manifest(folder) -> dict:
    return json.loads((Path(folder) / "run.json").read_text())


def hidden(folder) -> list[str]:
    return sorted(p.name for p in Path(folder).iterdir() if p.name.startswith("."))


# --- killed or terminated at chosen moments -------------------------------------------------

@needs_proc
@pytest.mark.parametrize(("sig", "moment"), [
    (signal.SIGKILL, r".without_mec.csv."),  # while the second case's CSV is written
    (signal.SIGKILL, r".fig0"),  # while the figure workers draw
    (signal.SIGTERM, r".fig0"),  # `kill PID`: stopped as Ctrl-C stops it
], ids=["SIGKILL-csv", "SIGKILL-figures", "SIGTERM-figures"])
def test_a_stopped_run_leaves_no_worker_and_the_next_run_tells_the_truth(tmp_path, sig,
                                                                         moment):
    folder = tmp_path / "spacecraft"
    horizon = "20000" if moment.endswith(".csv.") else "2000"  # a CSV long enough to catch
    process = start("reproduce", "spacecraft", "--horizon", horizon, "--out", str(tmp_path))
    wait_for(lambda: folder.exists() and any(p.name.startswith(moment) and
                                             p.name.endswith(".partial")
                                             for p in folder.iterdir()), 120, moment)
    workers = children_of(process.pid)
    assert workers  # the figure workers
    process.send_signal(sig)  # the parent only: its workers must notice
    _, err = process.communicate(timeout=60)
    wait_for(lambda: not any(alive(pid) for pid in workers), 5, "the workers to end")
    if sig == signal.SIGTERM:  # handled: temporary files removed, run.json written
        assert process.returncode == 143
        assert err.strip().splitlines()[-1].startswith("controlkit: interrupted;")
        assert hidden(folder) == [] and not (tmp_path / ".lock").exists()
        before = manifest(folder)
        assert before["interrupted"] is True and before["complete"] is False
    else:
        assert process.returncode == -signal.SIGKILL
    listed_before = manifest(folder)["files"]

    # the next run in the folder (another study) cleans what the killed one left
    log = __import__("io").StringIO()
    reproduce("cmg", out=tmp_path, horizon=0.5, log=log, workers=0)
    assert hidden(folder) == []  # no .partial, however big
    after = manifest(folder)
    assert after["complete"] is False and after["interrupted"] is True
    on_disk = {p.name for p in folder.iterdir()} - {"run.json"}
    assert set(after["files"]) == on_disk  # what is listed is there, and nothing else
    assert set(after.get("missing_files", [])).isdisjoint(on_disk)
    statuses = {case: entry["status"] for case, entry in after["cases"].items()}
    if moment == ".without_mec.csv.":
        assert statuses == {"ideal": "done", "without_mec": "interrupted",
                            "proposed": "interrupted"}
        assert on_disk == {"ideal.csv"}
    else:  # every case was done; some figures were never drawn
        assert statuses == dict.fromkeys(["ideal", "without_mec", "proposed"], "done")
        assert after["missing_files"] and all(f.startswith("fig") for f in
                                              after["missing_files"])
        assert set(after["files"]) | set(after["missing_files"]) >= set(listed_before)
    if sig == signal.SIGKILL:
        assert "ended without finishing" in log.getvalue()
    assert manifest(tmp_path / "cmg")["complete"] is True


# --- two runs on one folder --------------------------------------------------------------------

def test_a_second_run_on_a_folder_in_use_is_refused_naming_the_first(tmp_path, capsys):
    first = start("reproduce", "spacecraft", "--case", "ideal", "--horizon", "200", "--out",
                  str(tmp_path))
    wait_for(lambda: (tmp_path / ".lock").exists() and
             (tmp_path / "spacecraft" / "run.json").exists(), 60, "the first run's lock")
    assert cli.main(["reproduce", "spacecraft", "--horizon", "200", "--out",
                     str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert f"is in use by controlkit reproduce: process {first.pid} on" in err
    assert f"(kill {first.pid})" in err and "reproduce spacecraft --case ideal" in err
    _, first_err = first.communicate(timeout=120)
    assert first.returncode == 0, first_err
    after = manifest(tmp_path / "spacecraft")  # the first run's, whole, and only its files
    assert after["complete"] is True and list(after["cases"]) == ["ideal"]
    on_disk = {p.name for p in (tmp_path / "spacecraft").iterdir()} - {"run.json"}
    assert set(after["files"]) == on_disk
    assert {"ideal.csv", "metrics.json", "fig05_h1.png"} <= on_disk
    assert not any(name.startswith(("without_mec", "proposed")) for name in on_disk)
    assert not (tmp_path / ".lock").exists()


def test_a_lock_of_a_dead_run_is_taken_over(tmp_path):
    # a lock file left by a process that no longer runs, and its unfinished study
    (tmp_path / ".lock").write_text(json.dumps({"pid": 2 ** 22 + 7, "host": os.uname()[1]}))
    folder = tmp_path / "spacecraft"
    folder.mkdir()
    (folder / ".ideal.csv.4194311.0badc0de.partial").write_bytes(b"0" * 100_000)
    (folder / "without_mec.csv").write_text("time\n0\n")  # written, never listed
    (folder / "run.json").write_text(json.dumps({
        "study": "spacecraft", "complete": False, "files": ["fig05_h1.png"],
        "cases": {"ideal": {"status": "running"}, "without_mec": {"status": "pending"}}}))
    log = __import__("io").StringIO()
    reproduce("spacecraft", out=tmp_path, cases=["proposed"], horizon=1.0, log=log,
              workers=0)
    assert "removed 1 temporary file(s) of an unfinished run (0.1 MB)" in log.getvalue()
    after = manifest(folder)
    assert list(after["cases"]) == ["proposed"] and after["complete"] is True
    assert {p.name for p in folder.iterdir()} == {"run.json", *after["files"]}
    assert "without_mec.csv" not in after["files"]  # the killed run's, removed
    assert not (tmp_path / ".lock").exists()


def test_a_folder_locked_by_this_process_is_refused_before_anything_runs(tmp_path):
    with FolderLock(tmp_path, name=".lock", purpose="controlkit reproduce"):
        with pytest.raises(UsageError, match=rf"in use by controlkit reproduce: process "
                                             rf"{os.getpid()} \(this one\)"):
            reproduce("cmg", out=tmp_path, horizon=0.5, workers=0)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


# --- run.json after every fault ----------------------------------------------------------------

def test_a_failing_case_is_failed_with_its_error(tmp_path, capsys):
    assert cli.main(["reproduce", "spacecraft", "--case", "ideal", "--case", "without_mec",
                     "--set", "F=nan", "--horizon", "1", "--out", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "controlkit: 2 case(s) failed; spacecraft/ideal: ValueError: F must be finite" in err
    after = manifest(tmp_path / "spacecraft")
    for case in ("ideal", "without_mec"):
        assert after["cases"][case]["status"] == "failed"
        assert after["cases"][case]["error"].startswith("ValueError: F must be finite and >= 0")
    assert after["complete"] is False
    assert set(after["files"]) == {p.name for p in (tmp_path / "spacecraft").iterdir()} - {
        "run.json"} == {"metrics.json"}


def test_debug_stops_at_the_error_and_the_manifest_still_says_so(tmp_path):
    with pytest.raises(ValueError, match="F must be finite"):
        cli.main(["--debug", "reproduce", "spacecraft", "--case", "ideal", "--case",
                  "without_mec", "--set", "F=nan", "--horizon", "1", "--out", str(tmp_path)])
    after = manifest(tmp_path / "spacecraft")
    assert after["cases"]["ideal"]["status"] == "failed"
    assert after["cases"]["without_mec"]["status"] == "skipped"
    assert after["complete"] is False and "interrupted" not in after


def test_a_figure_that_cannot_be_written_is_not_complete(tmp_path, capsys):
    folder = tmp_path / "spacecraft"
    (folder / "fig06_h2.png").mkdir(parents=True)  # a folder where the figure goes
    assert cli.main(["reproduce", "spacecraft", "--horizon", "2", "--out",
                     str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert "controlkit: failed (FigureError): figure fig06_h2 in " in err
    assert "IsADirectoryError" in err
    after = manifest(folder)
    assert after["complete"] is False
    assert after["missing_files"] == ["fig06_h2.png", "fig06_h2.svg"]
    assert after["failed_figures"]["fig06_h2"].startswith("IsADirectoryError")
    assert set(after["files"]) == {p.name for p in folder.iterdir() if p.is_file()} - {
        "run.json"}
    assert {f"{stem}.png" for stem in FIGURES if stem != "fig06_h2"} <= set(after["files"])
    assert hidden(folder) == []


# --- arguments dropped or found late -------------------------------------------------------------

@pytest.mark.parametrize(("args", "message"), [
    (["spacecraft", "--case", "ideal", "--set", "K=nan"],
     "option 'K' is read by none of the spacecraft cases run (ideal), so it would change "
     "nothing; it is read by mec_fixed (--case NAME)"),
    (["spacecraft", "--set", "record_every=0"],
     "option 'record_every' is set by reproduce itself (reproduce thins the figures' "
     "samples itself; --stride thins the CSV)"),
    (["spacecraft", "--set", "on_chunk=1"], "option 'on_chunk' is set by reproduce itself"),
    (["spacecraft", "--set", "horizon=5"], "(give it with --horizon (horizon=))"),
    (["spacecraft", "--set", "F=1", "--set", "F=2"], "--set F is given more than once"),
    (["--horizon", "5", "--horizon", "20"], "--horizon for every study is given more than"),
    (["frit", "--stride", "5"], "stride does not apply to the frit study: it writes tables "
                                "of metrics, not time series; omit --stride"),
    (["spacecraft", "--out", ""], "out must name a folder, got ''"),
    (["spacecraft", "--horizon", "1e12"], "the CSV files of this run would take about"),
])
def test_reproduce_refuses_input_it_would_drop_or_find_late(tmp_path, monkeypatch, capsys,
                                                           args, message):
    from controlkit.studies.reproduce import command

    def ran(*args, **kwargs):
        raise AssertionError("a study ran before the input was refused")

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(command, "_run_study", ran)  # refused before any study runs
    assert cli.main(["reproduce", *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []  # nothing created


def test_an_option_some_cases_do_not_read_is_noted_per_case(tmp_path):
    log = __import__("io").StringIO()
    reproduce("spacecraft", out=tmp_path, cases=["ideal", "mec_fixed"], horizon=1.0,
              options={"K": 0.2}, log=log, workers=0)
    after = manifest(tmp_path / "spacecraft")
    assert after["cases"]["ideal"]["unused_options"] == ["K"]
    assert "unused_options" not in after["cases"]["mec_fixed"]
    assert "spacecraft/ideal does not read option(s) ['K']" in log.getvalue()


def test_one_text_is_one_case_for_every_api():
    from controlkit.studies import robustness

    with pytest.raises(UsageError, match=r"unknown case \['ab'\]"):
        reproduce("spacecraft", cases="ab")
    with pytest.raises(ValueError, match=r"unknown case \['ab'\]"):
        robustness.study("spacecraft", cases="ab", samples=1)


def test_gains_the_cmg_run_passes_on_are_options(tmp_path):
    error = {}
    for C1 in (3.0, 30.0):
        m = reproduce("cmg", out=tmp_path / str(C1), options={"C1": C1},  # 12 s
                      workers=0, log=__import__("io").StringIO())
        error[C1] = m["cmg"]["thesis"]["max_abs_q2_error_after_1s_rad"]
    assert error[3.0] > 0 and error[30.0] > 0
    assert error[3.0] > 2 * error[30.0]  # the gain reached the controller: a stiffer loop


@pytest.mark.parametrize("command", [["reproduce", "cmg"], ["sweep", "cmg", "--samples", "1"]])
def test_an_out_that_cannot_be_written_is_refused_alike(command, capsys):
    place = Path("/sys/controlkit-test")  # sysfs: no folder can be made there, even by root
    if not Path("/sys").is_dir() or _can_make(place):
        pytest.skip("no place that cannot be written here")
    assert cli.main([*command, "--out", str(place)]) == 2
    assert f"controlkit: error: cannot write to out '{place}'" in capsys.readouterr().err


def _can_make(place):
    try:
        place.mkdir()
    except OSError:
        return False
    place.rmdir()
    return True


def test_explain_and_simulate_name_the_bad_argument():
    import control as ct
    import numpy as np

    from controlkit.engines.fast import explain
    from controlkit.simulation import simulate

    with pytest.raises(ValueError, match=r"sys must be a python-control system \(a block or "
                                         r"an interconnect\), got int 42"):
        explain(42)
    system = ct.nlsys(lambda t, x, u, p: 0.5 * x, inputs=0, states=1, outputs=1, dt=1)
    for chunks in (-1, 0, 2.5, True):
        with pytest.raises(ValueError, match=rf"chunks must be an integer >= 1, got "
                                             rf"{chunks!r}"):
            simulate(system, np.arange(4), X0=[1.0], chunks=chunks)


# --- the sweep command -----------------------------------------------------------------------

@pytest.mark.parametrize(("args", "message"), [
    (["--horizon", "1e-9"], "horizon for spacecraft: horizon must be a positive multiple of "
                            "Ts = 0.1, got 1e-09"),
    (["--horizon", "1e12"], "horizon 1e+12 s: a spacecraft run of 10000000000001 steps would "
                            "hold about"),
    (["--vary", "inertia_error_x=-5:-4"],
     "a spacecraft run refuses the low end of the varied values (inertia_error_x=-5): "
     "inertia_error_scale must be one factor or three, each finite and >= 0"),
    (["--vary", "momentum_scale=1:2", "--vary", "momentum_scale=2:3:3"],
     "--vary momentum_scale is given twice ('momentum_scale=1:2' and "
     "'momentum_scale=2:3:3'); give each parameter once"),
    (["--workers", "0"], "workers must be an integer >= 1, got 0"),
    (["--scheduler", ""], "--scheduler goes with --executor dask"),
    (["--scheduler", "tcp://127.0.0.1:9"], "--scheduler goes with --executor dask"),
    (["--timeout", "0"], "timeout must be a finite number of seconds > 0, got 0.0"),
    (["--samples", "1000000000"], "1,000,000,000 runs is more than one sweep holds"),
])
def test_sweep_refuses_before_the_store_exists(tmp_path, capsys, args, message):
    out = tmp_path / "o"
    assert cli.main(["sweep", "spacecraft", "--samples", "2", "--case", "without_mec",
                     "--executor", "serial", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()  # refused before the store (made before any run) exists


def test_sweep_on_a_grid_alone_runs_each_point_once(tmp_path, capsys):
    grid = ["--vary", "friction_scale=0:5:3", "--vary", "inertia_scale=0.9:1.1:2"]
    for extra, message in ((["--samples", "5"], "samples=5 would draw nothing: every "
                                                "parameter of the cmg study is on the grid"),
                           (["--seed", "3"], "seed= goes with draws= (a grid is not random)")):
        assert cli.main(["sweep", "cmg", *grid, *extra, "--out", str(tmp_path / "o")]) == 2
        assert message in capsys.readouterr().err
    assert cli.main(["sweep", "cmg", *grid, "--horizon", "1.5", "--executor", "serial",
                     "--out", str(tmp_path / "o")]) == 0
    import pandas as pd

    table = pd.read_csv(tmp_path / "o" / "sweep.csv")
    assert sorted(zip(table["friction_scale"], table["inertia_scale"], strict=True)) == [
        (f, i) for f in (0.0, 2.5, 5.0) for i in (0.9, 1.1)]
    assert "seed" not in table


def test_sweep_whose_every_run_fails_shows_their_errors(tmp_path, capsys):
    out = tmp_path / "o"
    assert cli.main(["sweep", "spacecraft", "--case", "mec_fixed", "--samples", "2",
                     "--vary", "momentum_scale=1e6:1e7", "--horizon", "200",
                     "--executor", "serial", "--out", str(out)]) == 1
    captured = capsys.readouterr()
    assert "sweep/mec_fixed: runs=2, requirement_met=0" in captured.out
    # the plant's own words (python-control's path raises them too)
    assert "run(s) failed: SamplingError: block 'plant' blows up inside a sample" in captured.out
    assert "controlkit: every run failed (2 runs; e.g. SamplingError" in captured.err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["figures"] == "none: no run finished"
    assert sum(summary["cases"]["mec_fixed"]["errors"].values()) == 2
    rows = (out / "sweep.csv").read_text().splitlines()
    assert len(rows) == 3 and all("SamplingError" in row for row in rows[1:])


def test_sweep_timeout_ends_a_run_as_a_failed_row(tmp_path, capsys):
    assert cli.main(["sweep", "cmg", "--samples", "1", "--horizon", "0.5", "--timeout",
                     "0.001", "--executor", "serial", "--out", str(tmp_path / "o")]) == 1
    assert "1 run(s) failed: TimeoutError" in capsys.readouterr().out
    rows = (tmp_path / "o" / "sweep.csv").read_text().splitlines()
    assert len(rows) == 2 and "TimeoutError" in rows[1]
