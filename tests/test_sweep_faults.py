"""Sweeps under faults (issue 23): interrupted and killed sweeps, two writers on one store,
damaged stores, killed workers and parents, runs that hang, functions that misbehave,
bad arguments. Each test checks what is on disk (or in the process table) afterwards.

The sweeps that are interrupted or killed run in a process of their own
(tests/sweep_faults_helpers.py), started in a session of its own so that every process it
starts can be found again in /proc.
"""

import concurrent.futures as cf
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from processes import children_of, session_processes, wait_for
from sweep_faults_helpers import GATE, PID_FOLDER, imported_before, misbehave, sleepy, square

from controlkit import _lock
from controlkit import sweep as sweep_module
from controlkit._lock import FolderLock, LockHeld, process_alive
from controlkit.outputs.export import atomic
from controlkit.sweep import StoreWarning, sweep

HELPERS = Path(__file__).with_name("sweep_faults_helpers.py")
ROOT = Path(__file__).parent.parent


# --- tools -----------------------------------------------------------------------------------

def start_script(store, executor, runs, pause, *extra, pid_folder=None, held_from=None):
    """The script's sweep in a session of its own; with ``held_from`` N its runs x >= N
    wait until :func:`open_gate` (so a test acts while the sweep is surely running)."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    if pid_folder is not None:
        env[PID_FOLDER] = str(pid_folder)
    if held_from is not None:
        env[GATE] = f"{gate_file(store)}:{held_from}"
    return subprocess.Popen([sys.executable, str(HELPERS), str(store), executor, str(runs),
                             str(pause), *extra], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True, env=env)


def gate_file(store) -> Path:
    return Path(store).parent / f"{Path(store).name}.gate"


def open_gate(store) -> None:
    gate_file(store).touch()


def run_script(*args, **kwargs):
    process = start_script(*args, **kwargs)
    out, err = process.communicate(timeout=120)
    return process.returncode, out, err


def lines(store) -> list[bytes]:
    try:
        return (Path(store) / "runs.jsonl").read_bytes().splitlines()
    except FileNotFoundError:
        return []


def expected_table(runs, pause):
    return {"run": list(range(runs)), "pause": [pause] * runs, "x": list(range(runs)),
            "y": [x * x for x in range(runs)], "error": [""] * runs}


needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")


# --- killed at chosen moments, then resumed -------------------------------------------------

@needs_proc
@pytest.mark.parametrize(("sig", "executor", "after_rows"), [
    (signal.SIGINT, "processes", 3),
    (signal.SIGKILL, "processes", 3),
    (signal.SIGKILL, "serial", 0),  # as soon as the store exists, before any run is stored
    pytest.param(signal.SIGTERM, "processes", 6, marks=pytest.mark.slow),
    pytest.param(signal.SIGKILL, "threads", 5, marks=pytest.mark.slow),
    pytest.param(signal.SIGINT, "serial", 1, marks=pytest.mark.slow),
], ids=lambda value: value.name if isinstance(value, signal.Signals) else None)
def test_killed_sweep_resumes_to_the_uninterrupted_table(tmp_path, sig, executor, after_rows):
    store, runs, pause = tmp_path / "store", 30, 0.1
    # the runs from after_rows on wait: the signal finds the sweep running, however busy
    # the machine (the resumed sweep below is not held)
    process = start_script(store, executor, runs, pause, held_from=after_rows)
    wait_for(lambda: (store / "sweep.json").exists() and len(lines(store)) >= after_rows,
             60, f"{after_rows} stored rows")
    process.send_signal(sig)
    process.communicate(timeout=60)
    assert process.returncode == (130 if sig == signal.SIGINT else -sig)
    rows = [json.loads(line) for line in lines(store)]  # every stored line is whole
    assert after_rows <= len(rows) < runs
    assert len({r["run"] for r in rows}) == len(rows)
    assert not list(store.glob(".*partial"))
    wait_for(lambda: not session_processes(process.pid), 10, "the sweep's processes to end")
    code, out, err = run_script(store, executor, runs, pause, "--resume")
    assert code == 0, err
    assert json.loads(out) == expected_table(runs, pause)
    assert len(lines(store)) == runs  # the finished runs were not made again
    assert not (store / ".lock").exists()


# --- one writer per store -------------------------------------------------------------------

def test_second_sweep_on_a_store_in_use_is_refused_naming_the_holder(tmp_path):
    store, runs, pause = tmp_path / "store", 40, 0.1
    # the first sweep stores two rows, then waits at run 2 until it is killed: it holds the
    # store for as long as the second sweep takes to start, however busy the machine
    first = start_script(store, "serial", runs, pause, held_from=2)
    try:
        wait_for(lambda: len(lines(store)) >= 2, 60, "the first sweep's rows")
        code, _, err = run_script(store, "serial", runs, pause, "--resume")
        assert code == 1 and f"in use by another sweep: process {first.pid} on" in err
        with pytest.raises(LockHeld, match=rf"in use by another sweep: process {first.pid} "
                                           r"on .*sweep_faults_helpers\.py"):
            sweep(square, grid={"x": list(range(runs))}, fixed={"pause": pause},
                  executor="serial", store=store, resume=True, progress=False)
    finally:
        first.kill()
        first.communicate()
    kept = lines(store)
    assert len(kept) == 2
    # the dead holder's lock is taken over at once, and its rows are kept
    with pytest.warns(StoreWarning, match=rf"process {first.pid}\) ended without letting go"):
        table = sweep(square, grid={"x": list(range(runs))}, fixed={"pause": pause},
                      executor="threads", workers=8, store=store, resume=True,
                      progress=False)
    assert table["y"].tolist() == [x * x for x in range(runs)]
    assert lines(store)[:len(kept)] == kept and len(lines(store)) == runs


def test_two_sweeps_started_together_on_one_store(tmp_path):
    store, runs = tmp_path / "store", 12
    # whichever takes the store waits at run 2 until the other has ended: the two overlap
    # however busy the machine (unheld, 12 short runs could end before the other starts)
    both = [start_script(store, "serial", runs, 0.05, held_from=2) for _ in range(2)]
    try:
        wait_for(lambda: any(p.poll() is not None for p in both), 120, "one sweep to end")
    finally:
        open_gate(store)
    results = [p.communicate(timeout=120) + (p.returncode,) for p in both]
    codes = sorted(code for _, _, code in results)
    assert codes == [0, 1], results
    refused = next(err for _, err, code in results if code == 1)
    assert "in use by another sweep" in refused or "already holds a sweep" in refused
    assert len(lines(store)) == runs  # each run made and stored once


def _refuses_a_live_holder(folder):
    import socket

    live = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        (folder / ".lock").write_text(json.dumps({
            "pid": live.pid, "host": socket.gethostname(),
            "start_ticks": _lock.process_start_ticks(live.pid)}))
        with pytest.raises(LockHeld, match=rf"process {live.pid} on .*kill {live.pid}"):
            FolderLock(folder).acquire()
        assert json.loads((folder / ".lock").read_text())["pid"] == live.pid
    finally:
        live.kill()
        live.wait()
    assert process_alive(live.pid) is False


def test_lock_of_a_dead_process_is_taken_over_and_a_live_one_refused(tmp_path, monkeypatch):
    import socket

    dead = int(subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                              capture_output=True, text=True).stdout)
    for flock in (True, False):  # without flock (Windows): from the pid and host in the file
        if not flock:
            monkeypatch.setattr(_lock, "fcntl", None)
        (tmp_path / ".lock").write_text(json.dumps({"pid": dead,
                                                    "host": socket.gethostname()}))
        with FolderLock(tmp_path, purpose="a test") as lock:
            assert lock.taken_over["pid"] == dead
            assert json.loads((tmp_path / ".lock").read_text())["pid"] == os.getpid()
            with pytest.raises(LockHeld, match=rf"in use by a test: process {os.getpid()} "):
                FolderLock(tmp_path).acquire()
        assert not (tmp_path / ".lock").exists()
        # a live process named in the file is never taken over (flock or not)
        _refuses_a_live_holder(tmp_path)


def lock_thief(x, store):
    """Run 1 removes the store's lock file by hand; run 2 tries to lock the store."""
    if x == 1:
        (Path(store) / ".lock").unlink()
    if x == 2:
        try:
            FolderLock(store).acquire().release()
        except LockHeld:
            return {"stolen": False}
        return {"stolen": True}
    return {"stolen": None}


def test_a_lock_file_removed_by_hand_is_locked_again_at_the_next_row(tmp_path):
    store = tmp_path / "store"
    table = sweep(lock_thief, grid={"x": [0, 1, 2]}, fixed={"store": str(store)},
                  executor="serial", store=store, progress=False)
    assert table["stolen"].tolist()[2] is False and (table["error"] == "").all()
    assert not (store / ".lock").exists()


def store_remover(x, store):
    """Run 2 removes the whole store, as `rm -rf` by hand would."""
    if x == 2:
        import shutil

        shutil.rmtree(store)
    return {"y": x * x}


def test_a_store_removed_while_the_sweep_runs_gets_the_rows_from_then_on(tmp_path):
    store = tmp_path / "store"
    with pytest.warns(StoreWarning, match=r"runs.jsonl was removed or replaced while this "
                                          r"sweep ran; its rows go to the file now"):
        table = sweep(store_remover, grid={"x": list(range(5))}, fixed={"store": str(store)},
                      executor="serial", store=store, progress=False)
    assert table["y"].tolist() == [0, 1, 4, 9, 16]  # the table has every run
    assert [json.loads(line)["x"] for line in lines(store)] == [2, 3, 4]  # not a lost file
    assert (store / "sweep.json").exists() and not (store / ".lock").exists()
    made = []
    resumed = sweep(store_remover, grid={"x": list(range(5))}, fixed={"store": str(store)},
                    executor="serial", store=store, resume=True, progress=False,
                    warmup=lambda: made.append(len(lines(store))))
    assert resumed.drop(columns="wall_time_s").equals(table.drop(columns="wall_time_s"))
    assert made == [3] and len(lines(store)) == 5  # only the two removed runs made again


def test_temporary_names_are_unique_per_writer(tmp_path):
    target = tmp_path / "table.csv"
    errors = []

    def write(text):
        try:
            for _ in range(50):
                with atomic(target) as partial:
                    partial.write_text(text * 1000)
        except Exception as exc:  # the old shared name: FileNotFoundError on replace
            errors.append(exc)

    threads = [threading.Thread(target=write, args=(c,)) for c in "ab"]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert errors == []
    assert target.read_text() in ("a" * 1000, "b" * 1000)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table.csv"]


# --- damaged stores ---------------------------------------------------------------------------

CALLS = []


def counted(x):
    CALLS.append(x)
    return {"y": x * x}


def stored_sweep(store, **kwargs):
    return sweep(counted, grid={"x": list(range(6))}, executor="serial", store=store,
                 progress=False, **kwargs)


@pytest.fixture
def full_store(tmp_path):
    store = tmp_path / "store"
    reference = stored_sweep(store).drop(columns="wall_time_s")
    CALLS.clear()
    return store, reference


def _rewrite_runs(store, edit):
    runs_file = store / "runs.jsonl"
    runs_file.write_bytes(edit(runs_file.read_bytes()))
    return runs_file.read_bytes()


def _resumed(store, reference, rerun, match=None):
    before = (store / "runs.jsonl").read_bytes()
    if match is None:
        table = stored_sweep(store, resume=True)
    else:
        with pytest.warns(StoreWarning, match=match):
            table = stored_sweep(store, resume=True)
    assert CALLS == rerun
    assert (store / "runs.jsonl").read_bytes().startswith(before)  # only appended to
    assert table.drop(columns="wall_time_s").equals(reference)
    return table


def test_missing_spec_is_rebuilt_from_matching_rows_never_emptied(full_store):
    store, reference = full_store
    (store / "sweep.json").unlink()
    with pytest.raises(ValueError, match=r"already holds finished runs \(.*runs.jsonl\); "
                                         "pass resume=True"):
        stored_sweep(store)
    assert len(lines(store)) == 6
    _resumed(store, reference, [], match=r"sweep.json was missing; rebuilt from the 6 row")
    assert json.loads((store / "sweep.json").read_text())["key"]


def test_missing_spec_and_an_incomplete_row_still_rebuilds(full_store):
    store, reference = full_store
    (store / "sweep.json").unlink()
    _rewrite_runs(store, lambda b: b + b'{"run": 4}\n')  # incomplete, not another sweep's
    with pytest.warns(StoreWarning, match=r"line 7: run 4 lacks"):
        _resumed(store, reference, [], match=r"sweep.json was missing; rebuilt")


def test_missing_spec_with_rows_of_another_sweep_is_refused(full_store):
    store, _ = full_store
    (store / "sweep.json").unlink()
    before = (store / "runs.jsonl").read_bytes()
    with pytest.raises(ValueError, match=r"sweep.json is missing and .*runs.jsonl does not "
                                         r"hold this sweep \(line 1: run 0 has x=0, this "
                                         r"sweep's run 0 has x=10\)"):
        sweep(counted, grid={"x": list(range(10, 16))}, executor="serial", store=store,
              resume=True, progress=False)
    assert (store / "runs.jsonl").read_bytes() == before
    assert not (store / "sweep.json").exists() and not (store / ".lock").exists()


def test_damaged_spec_is_kept_aside_and_rebuilt(full_store):
    store, reference = full_store
    (store / "sweep.json").write_text('{"key": ')
    _resumed(store, reference, [], match=r"sweep.json was damaged \(line 1: Expecting value")
    assert (store / "sweep.json.damaged").read_text() == '{"key": '


def test_a_runs_file_that_cannot_be_read_is_named_and_left_alone(tmp_path):
    store = tmp_path / "store"
    (store / "runs.jsonl").mkdir(parents=True)
    with pytest.raises(ValueError, match=r"runs.jsonl cannot be read \(\[Errno 21\] Is a "
                                         r"directory.*it is never removed here"):
        stored_sweep(store, resume=True)
    assert (store / "runs.jsonl").is_dir() and not (store / ".lock").exists()


def test_spec_without_runs_file_starts_the_runs(full_store):
    store, reference = full_store
    (store / "runs.jsonl").unlink()
    table = stored_sweep(store, resume=True)
    assert CALLS == list(range(6)) and table.drop(columns="wall_time_s").equals(reference)


@pytest.mark.parametrize(("edit", "rerun", "match"), [
    # the last line cut by an interruption: the next row starts on a fresh line
    (lambda b: b[:-20], [5], r"line 6: cut \(no end of line"),
    # a cut row glued to the next one (as the old writer left them): the whole one is kept
    (lambda b: b.split(b"\n", 1)[0][:25] + b.split(b"\n", 1)[1], [0],
     r"line 1: a cut row glued to the next one"),
    (lambda b: b.replace(b'{"run": 2', b'{run 2', 1), [2], r"line 3: not JSON \(Expecting"),
    (lambda b: b.replace(b'{"run": 3', b'\xff\xfe{"run": 3', 1), [3], r"line 4: not text"),
    (lambda b: b.replace(b'"y": 16, "error": "", ', b"", 1), [4],
     r"line 5: run 4 lacks \['error'\]"),
    (lambda b: b + b'{"run": 47}\n', [], r"line 7: run 47 is not in this sweep"),
    (lambda b: b.replace(b'"x": 1, "y": 1', b'"x": 7, "y": 1', 1), [1],
     r"line 2: run 1 has x=7, this sweep's run 1 has x=1"),
    (lambda b: b + b.splitlines()[0] + b"\n", [], r"line 7: run 0 again"),
    (lambda b: b + b"[1, 2]\n", [], r"line 7: not a row \(a JSON list\)"),
    (lambda b: b + b"null\n", [], r"line 7: not a row \(a JSON null\)"),
], ids=["cut", "glued", "bad_json", "not_utf8", "missing_fields", "unknown_run",
        "wrong_parameter", "duplicate", "not_a_row", "null"])
def test_damaged_rows_are_skipped_named_and_rerun(full_store, edit, rerun, match):
    store, reference = full_store
    _rewrite_runs(store, edit)
    _resumed(store, reference, rerun, match=rf"runs.jsonl: \d line\(s\) skipped - .*{match}")
    if rerun:  # the rerun rows are whole lines of their own
        assert [json.loads(line)["run"] for line in lines(store)[-len(rerun):]] == rerun


def test_a_row_missing_its_fields_is_not_a_finished_run(full_store):
    # the audit's case: a line {"run": 47} was read as a finished run (a blank CSV row)
    store, reference = full_store
    _rewrite_runs(store, lambda b: b"\n".join(b.splitlines()[:4]) + b'\n{"run": 4}\n')
    _resumed(store, reference, [4, 5], match=r"line 5: run 4 lacks \['error', 'wall_time_s', "
                                             r"'x'\]")


# --- workers that die, parents that die, runs that hang ---------------------------------------

def test_a_killed_worker_fails_its_run_and_the_sweep_goes_on(tmp_path):
    doomed = tmp_path / "600.0.pid"  # a run far longer than the test: killed while it runs

    def kill_it():
        wait_for(doomed.exists, 60, "the run to start")
        os.kill(int(doomed.read_text()), signal.SIGKILL)

    killer = threading.Thread(target=kill_it)
    killer.start()
    grid = {"seconds": [0.1, 0.11, 600.0, 0.12, 0.13, 0.14]}
    fixed = {"pid_folder": str(tmp_path)}
    table = sweep(sleepy, grid=grid, fixed=fixed, workers=2, store=tmp_path / "store",
                  progress=False)
    killer.join()
    assert table["error"].tolist()[2] == ("WorkerDied: the worker process making this run "
                                          "was killed by SIGKILL")
    assert (table["error"] == "").sum() == 5 and table["slept"].count() == 5
    assert len(lines(tmp_path / "store")) == 6
    # a failed run is finished: a resume makes nothing again
    again = sweep(sleepy, grid=grid, fixed=fixed, workers=2, store=tmp_path / "store",
                  resume=True, progress=False)
    assert again["error"].tolist() == table["error"].tolist()


@needs_proc
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM,
                                 pytest.param(signal.SIGINT, marks=pytest.mark.slow)],
                         ids=lambda value: value.name)
def test_no_worker_outlives_a_killed_sweep(tmp_path, sig):
    # the runs never end and hold the GIL, so only a process outside the worker can end it
    process = start_script(tmp_path / "store", "processes", 2, 0, "--hog",
                           pid_folder=tmp_path)
    wait_for(lambda: len(list(tmp_path.glob("*.pid"))) == 2, 60, "both runs to start")
    workers = [int(p.read_text()) for p in tmp_path.glob("*.pid")]
    assert len(session_processes(process.pid)) >= 4  # sweep, reaper, forkserver, workers
    process.send_signal(sig)
    process.communicate(timeout=30)
    # the runs never end by themselves: a bound on the wait tells "ended" from "left behind"
    # (a busy machine may take seconds to reap them: no tighter bound is asserted)
    wait_for(lambda: not session_processes(process.pid), 60, "every process of the sweep "
                                                              "to end")
    assert not any(process_alive(pid) for pid in workers)


@pytest.mark.parametrize("executor", ["processes", "threads", "serial", "thread_pool",
                                      pytest.param("dask", marks=pytest.mark.slow)])
def test_timeout_ends_a_run_as_a_failed_row_on_every_executor(tmp_path, executor):
    pool = cf.ThreadPoolExecutor(2) if executor == "thread_pool" else None
    try:
        table = sweep(sleepy, grid={"seconds": [0.0, 60.0, 0.01]},
                      fixed={"pid_folder": str(tmp_path)}, executor=pool or executor,
                      timeout=1.5, progress=False, store=tmp_path / "store")
    finally:
        if pool is not None:
            pool.shutdown()
    assert table["error"].tolist()[0] == table["error"].tolist()[2] == ""
    assert table["error"].tolist()[1].startswith("TimeoutError: the run took longer than "
                                                 "timeout=1.5 s; its ")
    # stopped after its timeout, before its own end (60 s): no tighter bound, which a busy
    # machine could break
    assert 1.5 <= table["wall_time_s"].tolist()[1] < 60
    hung = int((tmp_path / "60.0.pid").read_text())
    wait_for(lambda: not process_alive(hung), 5, "the hung run's process to end")
    assert hung != os.getpid()
    assert sorted(json.loads(line)["run"] for line in lines(tmp_path / "store")) == [0, 1, 2]


# --- functions that misbehave -----------------------------------------------------------------

EVERY_WAY = {
    "raise": "ValueError: boom",
    "sys_exit": "SystemExit: the function called sys.exit(3)",
    "os_exit": "WorkerDied: the worker process making this run ended with exit code 4",
    "segfault": "WorkerDied: the worker process making this run was killed by SIGSEGV",
    "sigkill_self": "WorkerDied: the worker process making this run was killed by SIGKILL",
    "unpicklable": "TypeError: metric 'y' = <function misbehave.<locals>.<lambda>",
    "object": "TypeError: metric 'y' = <object object at",
    "reserved_run": "ValueError: the function returned ['run']: names of the sweep's own "
                    "columns (run, case, seed, error, wall_time_s); rename these metrics",
    "reserved_error": "ValueError: the function returned ['error']",
    "other_parameter_value": "ValueError: the function returned kind='something else', but "
                             "this run's kind is 'other_parameter_value'; a metric cannot "
                             "take the name of a parameter",
    "same_parameter_value": "",
    "not_a_dict": "TypeError: the swept function must return a dict of metrics, got list",
    "interrupt": "KeyboardInterrupt: raised by the function",
    "unprintable": "Unprintable: (its message cannot be shown: RuntimeError)",
    "generator_exit": "GeneratorExit: closed",
    "cancelled": "CancelledError: the task was cancelled",
    "fine": "",
}


def test_a_misbehaving_function_is_a_failed_row_whatever_it_does(tmp_path):
    table = sweep(misbehave, grid={"kind": list(EVERY_WAY)}, workers=2,
                  store=tmp_path / "store", progress=False)
    for expected, error in zip(EVERY_WAY.values(), table["error"], strict=True):
        assert error.startswith(expected) if expected else error == "", (expected, error)
    y = table["y"].tolist()
    assert y[list(EVERY_WAY).index("same_parameter_value")] == 1.0 and y[-1] == 0.0
    assert table["y"].isna().sum() == len(EVERY_WAY) - 2  # only two runs gave metrics
    stored = [json.loads(line) for line in lines(tmp_path / "store")]
    assert sorted(r["run"] for r in stored) == list(range(len(EVERY_WAY)))
    assert all(r["kind"] == kind for r in stored for kind in [list(EVERY_WAY)[r["run"]]])


def test_in_this_process_too_except_what_ends_the_process():
    safe = ["raise", "sys_exit", "unpicklable", "reserved_run", "other_parameter_value",
            "same_parameter_value", "not_a_dict", "unprintable", "generator_exit",
            "cancelled", "fine"]
    for executor in ("serial", "threads"):
        table = sweep(misbehave, grid={"kind": safe}, executor=executor, progress=False)
        for kind, error in zip(safe, table["error"], strict=True):
            assert error.startswith(EVERY_WAY[kind]) if EVERY_WAY[kind] else error == ""


# --- every argument checked before the store or a process is created --------------------------

def _lambda_function(x):
    return {"y": x}


def _shut_down_pool():
    """An executor object that was shut down: it takes no more work."""
    pool = cf.ThreadPoolExecutor(1)
    pool.shutdown()
    return pool


def _closure_over_a_lock():
    """A function neither importable by name nor picklable by value (it holds a lock)."""
    lock = threading.Lock()

    def under_lock(x):
        with lock:
            return {"y": x}

    return under_lock


@pytest.mark.parametrize(("kwargs", "message"), [
    ({"workers": 0}, r"workers must be an integer >= 1, got 0"),
    ({"workers": 10 ** 6}, r"workers must be <= \d+ for executor='processes' on this "
                           r"machine"),
    ({"workers": 2, "executor": "serial"}, r"workers= does not apply to executor='serial'"),
    ({"executor": "gpu"}, r"executor must be one of"),
    ({"executor": "dask", "scheduler": ""}, r"scheduler must be the address of a running "
                                            r"Dask scheduler.*got ''"),
    ({"scheduler": "tcp://127.0.0.1:1"}, r"scheduler= goes with executor='dask'"),
    ({"timeout": 0}, r"timeout must be a finite number of seconds > 0, got 0"),
    ({"timeout": float("nan")}, r"timeout must be a finite number"),
    ({"resume": "yes"}, r"resume must be True or False, got 'yes'"),
    ({"progress": "no"}, r"progress must be True or False"),
    ({"store": ""}, r"store must name a folder, got ''"),
    ({"grid": {"x": [1]}, "draws": None, "samples": None, "seed": 3},
     r"seed= goes with draws="),
    ({"samples": 10 ** 9}, r"1,000,000,000 runs is more than one sweep holds"),
    ({"cases": "ab"}, r"cases must be a list of case names \(in order\), got 'ab' "
                      r"\(write \['ab'\]"),
    ({"cases": {"a", "b"}}, r"cases must be a list of case names \(in order\)"),
    ({"grid": {"x": {1, 2}}}, r"grid\['x'\] is a set, which has no fixed order"),
    ({"executor": "dask", "scheduler": "foo"}, r"scheduler 'foo' is not an address: it "
                                               r"needs a host and a port"),
    ({"cases": ["a", "a"]}, r"cases \['a'\] are given more than once"),
    ({"fixed": {"x": 1}}, r"'x' is both in draws= and in fixed="),
    ({"grid": {"run": [1]}}, r"grid= names 'run', a column of the sweep's own"),
    ({"fixed": {"y": 1}}, r"_lambda_function\(\) takes no parameter \['y'\] \(it takes "
                          r"\['x'\]\)"),
    ({"cases": ["a"]}, r"takes no parameter \['case'\].*cases= passes case="),
    ({"draws": {"z": (0, 1)}}, r"takes no parameter \['z'\]"),
    ({"function": _closure_over_a_lock()}, r"executor='processes' makes the runs in other "
                                           r"processes, which cannot import .* by name, nor "
                                           r"send it by value \(TypeError: cannot pickle"),
    ({"function": _closure_over_a_lock(), "executor": "threads", "timeout": 5},
     r"timeout= makes each run in another process"),
    ({"function": sleepy}, r"sleepy\(\) takes no parameter \['x'\]"),
    ({"executor": _shut_down_pool()}, r"executor <concurrent.futures.thread.ThreadPoolExecutor "
                                      r"object at .*> takes no work \(RuntimeError: cannot "
                                      r"schedule new futures after shutdown\)"),
    ({"function": divmod}, r"divmod\(\) takes \['x'\] by position only"),
])
def test_bad_arguments_are_refused_before_anything_is_created(tmp_path, kwargs, message):
    arguments = {"function": _lambda_function, "draws": {"x": (0, 1)}, "samples": 3,
                 "store": tmp_path / "store", "progress": False, **kwargs}
    before = set(children_of(os.getpid()))
    with pytest.raises(ValueError, match=message):
        sweep(arguments.pop("function"), **arguments)
    assert not (tmp_path / "store").exists()
    assert set(children_of(os.getpid())) <= before


@pytest.mark.parametrize(("address", "message"), [
    ("tcp://127.0.0.1:9", r"scheduler 'tcp://127.0.0.1:9' cannot be reached "
                          r"\(ConnectionRefusedError: .*start one with `dask scheduler`"),
    ("tcp://no-such-host.invalid:8786", r"cannot be reached \(gaierror"),
    ("tcp://127.0.0.1:99999", r"is not an address \(Port out of range"),
    ("SILENT", r"did not answer within 5 s"),  # a port that accepts and says nothing
])
def test_an_unreachable_scheduler_is_refused_within_seconds(tmp_path, address, message):
    pytest.importorskip("distributed")
    import socket

    silent = socket.create_server(("127.0.0.1", 0))
    if address == "SILENT":
        address = f"tcp://127.0.0.1:{silent.getsockname()[1]}"
    started = time.monotonic()
    try:
        with pytest.raises(ValueError, match=message):
            sweep(square, grid={"x": [1]}, executor="dask", scheduler=address,
                  store=tmp_path / "store", progress=False)
    finally:
        silent.close()
    # refused by controlkit's own wait (SCHEDULER_TIMEOUT_S), not after Dask's connect
    # timeout (30 s) or never: the bound tells the two apart with room for a busy machine
    assert time.monotonic() - started < 30
    assert not (tmp_path / "store").exists()


def test_a_running_scheduler_is_used(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        table = sweep(square, grid={"x": [2, 3]}, executor="dask",
                      scheduler=cluster.scheduler_address, progress=False)
    assert table["y"].tolist() == [4, 9]


def test_store_that_cannot_be_written_is_refused(tmp_path):
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match=r"store '.*file' is a file, not a folder"):
        sweep(square, grid={"x": [1]}, executor="serial", store=tmp_path / "file")
    with pytest.raises(ValueError, match=r"cannot write to store '.*file/sub': .*file is a file"):
        sweep(square, grid={"x": [1]}, executor="serial", store=tmp_path / "file" / "sub")
    locked = tmp_path / "read-only"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        if os.access(locked, os.W_OK):
            pytest.skip("this user writes anywhere (root)")
        with pytest.raises(ValueError, match=r"cannot write to store '.*read-only/s': "
                                             r".*read-only is not writable"):
            sweep(square, grid={"x": [1]}, executor="serial", store=locked / "s")
    finally:
        locked.chmod(0o700)


def test_a_store_under_home_is_in_the_home_folder():
    assert sweep_module.check_folder("~/results/sweep") == Path.home() / "results" / "sweep"


def test_cli_refuses_bad_out_and_workers_before_creating_the_store(tmp_path, capsys):
    from controlkit.cli import main

    assert main(["sweep", "spacecraft", "--samples", "2", "--out", ""]) == 2
    assert "controlkit: error: out must name a folder, got ''" in capsys.readouterr().err
    assert main(["sweep", "spacecraft", "--samples", "2", "--workers", "0",
                 "--out", str(tmp_path / "o")]) == 2
    assert "workers must be an integer >= 1, got 0" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("options", [{"executor": "processes", "workers": 2},
                                     {"executor": "threads", "timeout": 30}])
def test_a_function_of_a_notebook_goes_to_the_workers_by_value(tmp_path, options):
    # what a notebook cell defines: a function of __main__ reading a notebook variable
    scope = {"__name__": "__main__", "offset": 10.0}
    exec("def shifted(x):\n    return {'y': x + offset}\n", scope)
    table = sweep(scope["shifted"], grid={"x": [1.0, 2.0, 3.0]}, progress=False,
                  store=tmp_path / "store", **options)
    assert table["y"].tolist() == [11.0, 12.0, 13.0]
    assert (table["error"] == "").all()


def test_without_cloudpickle_the_message_says_what_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "cloudpickle", None)  # import cloudpickle fails
    with pytest.raises(ValueError, match=r"sending it by value needs cloudpickle: pip install "
                                         r"cloudpickle \(or, in the folder of your controlkit "
                                         r'clone, pip install "\.\[sweep\]"\); or use '
                                         r"executor='threads'"):
        sweep(lambda x: {"y": x}, grid={"x": [1]}, progress=False)


@pytest.mark.parametrize("missing, call, message", [
    ("pandas", lambda: __import__("controlkit.sweep.rows", fromlist=["_pandas"])._pandas(),
     r"controlkit.sweep returns a pandas DataFrame: pip install pandas \(or, in the folder of "
     r'your controlkit clone, pip install "\.\[sweep\]"\)'),
    ("distributed", lambda: __import__("controlkit.sweep.executors", fromlist=["x"])
     ._check_executor("dask", None, None, None),
     r'executor="dask" needs Dask: pip install "dask\[distributed\]" \(or, in the folder of '
     r'your controlkit clone, pip install "\.\[cluster\]"\)'),
])
def test_a_missing_optional_package_is_named_with_the_extra_run_in_the_clone(
        monkeypatch, missing, call, message):
    monkeypatch.setitem(sys.modules, missing, None)  # its import fails
    with pytest.raises((ImportError, ValueError), match=message):
        call()


def appends(x, seen):
    """Changes the list it is given (a notebook's accumulator)."""
    seen.append(x)
    return {"n": len(seen)}


@pytest.mark.parametrize("executor", ["serial", "threads", "processes"])
def test_a_function_that_changes_its_arguments_changes_no_other_run(tmp_path, executor):
    workers = {} if executor == "serial" else {"workers": 2}
    table = sweep(appends, grid={"x": [0, 1, 2]}, fixed={"seen": []}, executor=executor,
                  store=tmp_path / "store", progress=False, **workers)
    assert table["n"].tolist() == [1, 1, 1]  # each run is handed its own list
    assert table["seen"].tolist() == [[], [], []]  # the rows record what the runs were given
    again = sweep(appends, grid={"x": [0, 1, 2]}, fixed={"seen": []}, executor=executor,
                  store=tmp_path / "store", resume=True, progress=False, **workers)
    assert len(lines(tmp_path / "store")) == 3  # every run was kept, none made again
    assert again["n"].tolist() == [1, 1, 1]


def test_a_generator_as_grid_values_is_refused():
    with pytest.raises(ValueError, match=r"grid\['x'\] is a generator, which can be read only "
                                         r"once .* give a list"):
        sweep(_lambda_function, grid={"x": (v for v in [1, 2])}, progress=False)


@pytest.mark.skipif(sys.platform == "win32", reason="no forkserver on Windows")
def test_process_workers_start_from_a_forkserver_that_imported_numba_once():
    # each worker used to import python-control, scipy, numba... itself (1.5-2 s each);
    # the sweep now starts the forkserver with them imported, and workers are forked from it
    from controlkit import _jit

    table = sweep(imported_before, grid={"x": [0, 1, 2, 3]}, executor="processes",
                  workers=2)
    assert (table["pid"] != os.getpid()).all()  # the runs were made in workers
    assert table["processes"].all()
    assert table["numba"].all() == _jit.available()
