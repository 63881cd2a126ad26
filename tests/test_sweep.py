"""Sweeps: documented rows for grids and draws, the same rows on every executor,
failing runs as rows, and interrupted sweeps resumed without repeating runs."""

import concurrent.futures as cf
import json
import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from controlkit.blocks.spacecraft import pointing_error_deg, quaternion_from_axis_angle
from controlkit.studies import robustness
from controlkit.studies.spacecraft import robustness as sc_robustness
from controlkit.studies.spacecraft import scenario
from controlkit.sweep import draw_points, plan, sweep, wilson_interval

CALLS = []


def damped(F, Ts=0.1, case="a"):
    """A tiny model: the sampled loop e[k+1] = (1 - F Ts) e[k] is stable for 0 < F Ts < 2."""
    CALLS.append((case, F))
    if F < 0:
        raise ValueError("F must be >= 0")
    pole = 1 - F * Ts
    return {"pole": pole, "stable": bool(abs(pole) < 1), "e_100": float(pole ** 100)}


def test_grid_rows_are_every_combination_in_order():
    table = sweep(damped, grid={"F": [1.0, 5.0, 30.0], "Ts": [0.1, 0.01]}, executor="serial",
                  progress=False)
    assert list(table["run"]) == list(range(6))
    assert table[["F", "Ts"]].values.tolist() == [[1.0, 0.1], [1.0, 0.01], [5.0, 0.1],
                                                  [5.0, 0.01], [30.0, 0.1], [30.0, 0.01]]
    assert table["stable"].tolist() == [True, True, True, True, False, True]
    assert table.loc[0, "pole"] == pytest.approx(0.9)
    assert (table["error"] == "").all()
    assert "case" not in table and "seed" not in table


def test_draws_are_seeded_per_run_and_crossed_with_cases():
    table = sweep(damped, draws={"F": (0.0, 20.0)}, samples=4, seed=7, cases=["a", "b"],
                  executor="serial", progress=False)
    assert len(table) == 8 and table["case"].tolist() == ["a", "b"] * 4
    # the same draw for both cases; draw i does not depend on how many were drawn
    assert (table["F"].to_numpy()[::2] == table["F"].to_numpy()[1::2]).all()
    again = draw_points({"F": (0.0, 20.0)}, 2, seed=7)
    assert [p["F"] for _, p in again] == table["F"].tolist()[:4:2]
    assert table["seed"].tolist()[:4:2] == [s for s, _ in again]
    assert ((table["F"] >= 0) & (table["F"] <= 20)).all()
    other = sweep(damped, draws={"F": (0.0, 20.0)}, samples=4, seed=8, executor="serial",
                  progress=False)
    assert not np.allclose(other["F"], table["F"].to_numpy()[::2])


def test_grid_crossed_with_draws():
    runs = plan(grid={"Ts": [0.1, 0.2]}, draws={"F": (0, 1)}, samples=3, seed=0)
    assert len(runs) == 6 and [r.params["Ts"] for r in runs] == [0.1] * 3 + [0.2] * 3
    assert [r.params["F"] for r in runs[:3]] == [r.params["F"] for r in runs[3:]]


def test_a_failing_run_is_a_row_with_its_error():
    table = sweep(damped, grid={"F": [1.0, -1.0, 2.0]}, executor="serial", progress=False)
    assert table["error"].tolist() == ["", "ValueError: F must be >= 0", ""]
    assert np.isnan(table.loc[1, "pole"]) and table.loc[2, "pole"] == pytest.approx(0.8)


INTERRUPT = {"after": None}


def interrupt_after(F, Ts=0.1, case="a"):
    """``damped``, but a Ctrl-C arrives once ``INTERRUPT["after"]`` runs have been made."""
    if INTERRUPT["after"] is not None and len(CALLS) >= INTERRUPT["after"]:
        raise KeyboardInterrupt
    return damped(F, Ts, case)


def test_interrupted_sweep_resumes_without_repeating_finished_runs(tmp_path):
    CALLS.clear()
    INTERRUPT["after"] = 2
    grid = {"F": [1.0, 2.0, 3.0, 4.0, 5.0]}
    with pytest.raises(KeyboardInterrupt):
        sweep(interrupt_after, grid=grid, executor="serial", store=tmp_path, progress=False)
    stored = [json.loads(line) for line in (tmp_path / "runs.jsonl").read_text().splitlines()]
    assert [row["run"] for row in stored] == [0, 1]
    INTERRUPT["after"] = None
    with pytest.raises(ValueError, match="already holds a sweep; pass resume=True"):
        sweep(interrupt_after, grid=grid, executor="serial", store=tmp_path, progress=False)
    CALLS.clear()
    table = sweep(interrupt_after, grid=grid, executor="serial", store=tmp_path, resume=True,
                  progress=False)
    assert [F for _, F in CALLS] == [3.0, 4.0, 5.0]  # runs 0 and 1 are not run again
    assert table["F"].tolist() == grid["F"] and (table["error"] == "").all()
    with pytest.raises(ValueError, match="holds a different sweep"):
        sweep(interrupt_after, grid={"F": [9.0]}, executor="serial", store=tmp_path,
              resume=True, progress=False)


def _study(executor, **kwargs):
    table, summary = robustness.study("spacecraft",
        samples=3, seed=11, cases=["without_mec", "proposed"], horizon=200.0,
        executor=executor, progress=False, **kwargs)
    return table.drop(columns="wall_time_s"), summary


def test_same_seed_same_rows_serial_processes_threads_and_dask():
    serial, summary = _study("serial")
    assert len(serial) == 6 and (serial["error"] == "").all()
    processes, _ = _study("processes", workers=2)
    pd.testing.assert_frame_equal(serial, processes)
    default, _ = _study(None, workers=2)  # threads where numba compiles, else processes
    pd.testing.assert_frame_equal(serial, default)
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        on_dask, _ = _study(client.get_executor())
    pd.testing.assert_frame_equal(serial, on_dask)
    assert summary["proposed"]["runs"] == 3


def test_a_study_runs_on_threads_where_numba_compiles_its_loops(monkeypatch):
    pytest.importorskip("numba")
    assert robustness.default_executor() == "threads"
    monkeypatch.setenv("CONTROLKIT_DISABLE_NUMBA", "1")  # runs in Python hold the lock
    assert robustness.default_executor() == "processes"


def test_user_executor_is_used_and_not_closed():
    with cf.ThreadPoolExecutor(2) as pool:
        first = sweep(damped, grid={"F": [1.0, 2.0]}, executor=pool, progress=False)
        second = sweep(damped, grid={"F": [1.0, 2.0]}, executor=pool, progress=False)
    pd.testing.assert_frame_equal(first.drop(columns="wall_time_s"),
                                  second.drop(columns="wall_time_s"))


def test_study_rows_and_summary_are_consistent(tmp_path):
    table, summary = robustness.study("spacecraft",
        samples=2, seed=3, cases=["without_mec"], horizon=100.0, executor="serial",
        out=tmp_path, progress=False)
    assert set(sc_robustness.RANGES) <= set(table.columns)
    assert ((table["inertia_error_x"] >= 0) & (table["inertia_error_x"] <= 3)).all()
    assert ((table["angle_deg"] >= 10) & (table["angle_deg"] <= 60)).all()
    s = summary["without_mec"]
    assert s["runs"] == 2 and s["requirement_met"] == int(
        table["requirement_met_last_half"].sum())
    written = json.loads((tmp_path / "summary.json").read_text())
    assert written["cases"]["without_mec"]["runs"] == 2
    assert len(pd.read_csv(tmp_path / "sweep.csv")) == 2
    for stem in ("robustness_errors", "robustness_success_vs_inertia"):
        assert (tmp_path / f"{stem}.png").stat().st_size > 10_000


def test_cases_at_the_same_success_rate_are_each_visible_in_the_figure():
    """Notebook 6: three cases meet the requirement in every run of most bins; as curves
    their 100 % points lay on one another and only one case showed."""
    import matplotlib.pyplot as plt

    edges = np.linspace(0.0, 3.0, 7)
    rates = {"without_mec": [1, 0.6, 0.2, 0, 0, float("nan")], "mec_fixed": [1] * 6,
             "proposed": [1, 1, 1, 1, 1, 0.8], "safeguarded": [1] * 6}
    summary = {case: {"success_rate": 1.0, "runs": 30, "success_by_inertia_error": [
        {"mean_factor_low": a, "mean_factor_high": b, "runs": 5, "success_rate": r}
        for a, b, r in zip(edges[:-1], edges[1:], rate, strict=True)]}
        for case, rate in rates.items()}
    table = pd.DataFrame({"case": list(rates), "error": "",
                          "max_pointing_error_last_half_deg": 0.01})
    fig = sc_robustness.figures(table, summary)["robustness_success_vs_inertia"]
    ax = fig.axes[0]
    # each case's bars (matplotlib labels a case's container of bars, not each bar)
    bars = {group.get_label(): list(group) for group in ax.containers}
    assert sorted(bars) == sorted(rates)
    assert [len(bars[c]) for c in rates] == [5, 6, 6, 6]  # no bar for a bin without runs
    heights = {c: [round(b.get_height()) for b in bars[c]] for c in rates}
    assert heights["proposed"][-1] == 80 and heights["without_mec"][3] == 0
    spans = [(b.get_x(), b.get_x() + b.get_width()) for c in rates for b in bars[c]]
    for i, (a0, a1) in enumerate(spans):  # side by side: no two bars share any width
        for b0, b1 in spans[i + 1:]:
            assert a1 <= b0 + 1e-12 or b1 <= a0 + 1e-12
    looks = {(tuple(bars[c][0].get_facecolor()), bars[c][0].get_hatch()) for c in rates}
    assert len(looks) == 4  # each case its colour and hatching
    assert min(b.get_linewidth() for c in rates for b in bars[c]) > 1  # 0 % still a stroke
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert set(rates) <= set(legend) and "Table 2's error" in legend
    plt.close(fig)


def test_trajectories_are_kept_per_run():
    table = sweep(sc_robustness.run, grid={"angle_deg": [10.0, 20.0]},
                  cases=["ideal"], fixed={"horizon": 10.0, "keep_every": 10},
                  executor="serial", progress=False)
    assert sorted(table.attrs["trajectories"]) == [0, 1]
    assert len(table.attrs["trajectories"][0]["time"]) == 11
    assert "trajectory" not in table


@pytest.mark.parametrize("case", ["without_mec", "proposed"])
def test_streamed_metrics_equal_those_of_the_whole_response(case):
    # the study's run sees its outputs chunk by chunk; its numbers must be those of the
    # run's full response, bit for bit (a long run is cut into 20 chunks)
    options = dict(inertia_error_x=2.5, momentum_scale=3.0, axis_x=-1.0, angle_deg=50.0)
    metrics = sc_robustness.run(case, horizon=2500.0, keep_every=9, **options)
    resp = scenario.run(case, horizon=2500.0, q_initial=quaternion_from_axis_angle(
        [-1.0, 2.0, 3.0], 50.0), plant_options={"inertia_error_scale": [2.5, 1.0, 1.0],
                                               "momentum_scale": 3.0})
    labels = list(resp.output_labels)
    q = resp.outputs[[labels.index(f"q[{i}]") for i in range(4)]]
    error = pointing_error_deg(q)
    K = [labels.index(f"K[{i}]") for i in range(4) if f"K[{i}]" in labels]
    u = resp.outputs[[labels.index("u[0]"), labels.index("u[1]")]]
    assert metrics.pop("trajectory")["error_deg"].tolist() == error[::9].tolist()
    assert metrics == {
        "max_pointing_error_last_half_deg": float(error[resp.time >= 1250.0].max()),
        "final_pointing_error_deg": float(error[-1]),
        "requirement_met_last_half": bool(error[resp.time >= 1250.0].max() <= 0.05),
        "peak_abs_u_rad_s": float(np.abs(u).max()),
        "max_abs_K": float(np.abs(resp.outputs[K]).max()) if K else 0.0}
    assert len(resp.time) == 25_001 and (case == "proposed") == bool(K)


def test_wilson_interval():
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=1e-4)
    assert wilson_interval(10, 10) == pytest.approx((0.7225, 1.0), abs=1e-4)


@pytest.mark.parametrize(("kwargs", "message"), [
    ({}, r"give grid= \(named values\), draws="),
    ({"draws": {"F": (0, 1)}}, r"draws= needs samples="),
    ({"grid": {"F": [1]}, "samples": 3}, r"samples= goes with draws="),
    ({"draws": {"F": (1, 0)}, "samples": 2}, r"needs finite low <= high"),
    ({"draws": {"F": "wide"}, "samples": 2}, r"draws\['F'\] must be a \(low, high\) tuple"),
    ({"draws": {"F": (0, 1)}, "samples": 0}, r"samples must be an integer >= 1"),
    ({"draws": {"F": (0, 1)}, "samples": 2, "seed": -1}, r"seed must be an integer >= 0"),
    ({"grid": {"F": []}}, r"grid\['F'\] has no values"),
    ({"grid": {"F": [1]}, "cases": []}, r"cases must not be empty"),
    ({"grid": {"F": [1]}, "executor": "gpu"}, r"executor must be one of"),
    ({"grid": {"F": [1]}, "executor": "threads", "workers": 0}, r"workers must be an integer"),
    ({"grid": {"F": [1]}, "resume": True}, r"resume=True needs store="),
    ({"grid": {"F": [1]}, "draws": {"F": (0, 1)}, "samples": 1},
     r"'F' is both in grid= and in draws="),
])
def test_bad_sweep_arguments_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        sweep(damped, progress=False, **kwargs)


def test_cli_sweep_refuses_a_horizon_of_more_steps_than_a_float_holds(tmp_path, capsys):
    # 1e308 s at 0.1 s: horizon / Ts overflowed to inf, and the command failed with an
    # OverflowError, leaving its empty folder behind
    from controlkit.cli import main

    out = tmp_path / "out"
    assert main(["sweep", "spacecraft", "--samples", "1", "--horizon", "1e308", "--out",
                 str(out)]) == 2
    assert "horizon / Ts must be a finite number of steps, got 1e+308 / 0.1" in \
        capsys.readouterr().err
    assert not out.exists()


def test_cli_sweep_writes_table_summary_and_figures(tmp_path, capsys):
    from controlkit.cli import main

    assert main(["sweep", "spacecraft", "--samples", "2", "--horizon", "50", "--case",
                 "ideal", "--executor", "serial", "--vary", "angle_deg=20:30",
                 "--vary", "momentum_scale=1:2:2", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "sweep.csv")
    assert len(table) == 4 and sorted(set(table["momentum_scale"])) == [1.0, 2.0]
    assert table["angle_deg"].between(20, 30).all()
    assert "sweep/ideal: runs=4" in capsys.readouterr().out


@pytest.mark.parametrize(("vary", "message"), [
    ("spin=1:2", r"unknown parameter 'spin'"),
    ("angle_deg=3", r"expected NAME=LOW:HIGH"),
    ("angle_deg=a:b", r"LOW and HIGH must be numbers"),
    ("angle_deg=5:1", r"needs finite LOW <= HIGH"),
])
def test_cli_bad_vary_is_refused(vary, message, tmp_path, capsys):
    import re

    from controlkit.cli import main

    assert main(["sweep", "spacecraft", "--vary", vary, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and len(err.strip().splitlines()) == 1


def test_cmg_study_draws_friction_and_inertia_and_counts_tracking(tmp_path, capsys):
    from controlkit.cli import main

    assert main(["sweep", "cmg", "--samples", "3", "--horizon", "1.5", "--executor", "serial",
                 "--vary", "friction_scale=0:1", "--out", str(tmp_path)]) == 0
    table = pd.read_csv(tmp_path / "sweep.csv")
    assert len(table) == 3 and table["friction_scale"].between(0, 1).all()
    assert table["inertia_scale"].between(0.8, 1.2).all()
    # the thesis case tracks within 0.01 rad at up to its published friction
    assert table["tracking_met"].all()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["cases"]["thesis"]["requirement_met"] == 3
    assert (tmp_path / "cmg_tracking_vs_friction.png").stat().st_size > 10_000
    assert "sweep/thesis: runs=3, requirement_met=3" in capsys.readouterr().out


def test_cmg_plant_options_are_checked():
    from controlkit.studies.cmg import scenario as cmg

    with pytest.raises(ValueError, match=r"plant_options has unknown keys \['mass'\]"):
        cmg.build_loop(plant_options={"mass": 2.0})
    with pytest.raises(ValueError, match=r"inertia_scale must be finite and > 0"):
        cmg.true_plant(inertia_scale=0.0)


def test_a_killed_runs_half_written_outputs_are_removed_by_the_next_run(tmp_path):
    # what a SIGKILL during the writing leaves: temporary files of a process that is gone
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    out = tmp_path / "out"
    out.mkdir()
    stale = [out / f".sweep.csv.{gone.pid}.0123abcd.partial",
             out / f".robustness_errors.png.{gone.pid}.partial"]
    live = out / f".summary.json.{os.getpid()}.89abcdef.partial"  # a writer still at work
    for path in [*stale, live]:
        path.write_text("half")
    table, _ = robustness.study("spacecraft", samples=1, seed=1, cases=["without_mec"],
                                horizon=100.0, executor="serial", out=out, progress=False)
    assert (table["error"] == "").all() and (out / "sweep.csv").is_file()
    assert not any(path.exists() for path in stale) and live.exists()


def test_stored_metrics_of_the_wrong_kind_are_named_with_the_runs_and_the_store(tmp_path):
    args = dict(samples=2, seed=1, cases=["without_mec"], horizon=100.0, executor="serial",
                out=tmp_path, progress=False)
    table, _ = robustness.study("spacecraft", **args)
    store = tmp_path / "store" / "runs.jsonl"
    rows = [json.loads(line) for line in store.read_text().splitlines()]
    error = next(c for c in table.columns if c.startswith("max_") and c.endswith("_deg"))
    rows[1][error] = "0.0"  # edited by hand: a number written as text
    store.write_text("".join(json.dumps(row) + "\n" for row in rows))
    with pytest.raises(ValueError, match=rf"the finished runs \[1\] have a '{error}' that is "
                                         r"not a number \(e.g. '0.0'\): rows of the store"):
        robustness.study("spacecraft", resume=True, **args)


def test_a_folder_where_the_table_goes_is_refused_before_any_run(tmp_path):
    (tmp_path / "sweep.csv").mkdir()
    with pytest.raises(ValueError, match=r"out: .*sweep.csv is a folder, where the sweep "
                                         r"writes its sweep.csv"):
        robustness.study("spacecraft", samples=1, seed=1, cases=["without_mec"],
                         horizon=100.0, executor="serial", out=tmp_path, progress=False)
    assert not (tmp_path / "store").exists()
