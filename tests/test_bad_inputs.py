"""Bad input gets a clear error naming the argument, through the API and the command line.

Each case is a call and the message it must raise (or, for the command line, print on one
line of stderr with exit status 2): the same wrong input always gives the same words.
"""

import dataclasses
import math

import numpy as np
import pytest

from controlkit import cli
from controlkit.blocks import cmg, frit, mec
from controlkit.blocks import spacecraft as sc
from controlkit.blocks.sampling import time_grid
from controlkit.simulation import initial_state, input_output_response, simulate
from controlkit.studies import STUDIES
from controlkit.studies.frit import scenario as frit_study
from controlkit.studies.registry import UsageError
from controlkit.studies.reproduce import reproduce as run_reproduce
from controlkit.studies.spacecraft import scenario as scenario
from controlkit.studies.spacecraft.diagrams import output_zeroing_loop


def reproduce(**kwargs):
    import io
    import tempfile

    kwargs.setdefault("out", tempfile.mkdtemp())
    return run_reproduce(log=io.StringIO(), **kwargs)


def a_file():
    import tempfile

    handle = tempfile.NamedTemporaryFile(delete=False)
    return handle.name


API_CASES = {
    # reproduce(): every argument checked before anything runs
    "unknown study": (lambda: reproduce(study="moon"), r"unknown study 'moon'; choose from"),
    "no cases": (lambda: reproduce(cases=[]), r"cases must name at least one case"),
    "unknown case": (lambda: reproduce(cases=["nope"]), r"unknown case \['nope'\]; known"),
    "horizon 0": (lambda: reproduce(horizon=0), r"horizon must be finite and > 0, got 0"),
    "horizon < 0": (lambda: reproduce(horizon=-1.0), r"horizon must be finite and > 0"),
    "horizon nan": (lambda: reproduce(horizon=math.nan), r"horizon must be finite and > 0"),
    "horizon inf": (lambda: reproduce(horizon=math.inf), r"horizon must be finite and > 0"),
    "horizon off grid": (lambda: reproduce(study="spacecraft", horizon=0.05),
                         r"horizon for spacecraft: horizon must be a positive multiple of Ts"),
    "horizon text": (lambda: reproduce(horizon="long"),
                     r"horizon must be a real number, got 'long'"),
    "horizon bool": (lambda: reproduce(horizon=True), r"horizon must be a number of seconds"),
    "horizon unknown study": (lambda: reproduce(horizon={"moon": 5.0}),
                              r"horizon names unknown studies \['moon'\]"),
    "horizon study not run": (lambda: reproduce(study="cmg", horizon={"spacecraft": 5.0}),
                              r"horizon names \['spacecraft'\], which this run does not "
                              r"include \(it runs \['cmg'\]\)"),
    "stride 0": (lambda: reproduce(stride=0), r"stride must be an integer >= 1, got 0"),
    "stride float": (lambda: reproduce(stride=2.5), r"stride must be an integer >= 1, got 2.5"),
    "stride bool": (lambda: reproduce(stride=True), r"stride must be an integer >= 1"),
    "stride too long": (lambda: reproduce(study="spacecraft", horizon=10.0, stride=1000),
                        r"stride 1000 keeps 1 sample\(s\) of the 101 of a spacecraft run"),
    "engine": (lambda: reproduce(engine="gpu"), r"engine must be one of \('fast'"),
    "out is a file": (lambda: reproduce(out=a_file()), r"out '.*' is a file, not a folder"),
    "out under a file": (lambda: reproduce(out=a_file() + "/results"),
                         r"cannot write to out '.*/results': .* is a file"),
    "unknown option": (lambda: reproduce(study="spacecraft", cases=["ideal"], horizon=1.0,
                                         options={"G": 1.0}),
                       r"unknown option \['G'\] for controlkit.studies.spacecraft.scenario.run"),
    "cmg too long": (lambda: reproduce(study="cmg", horizon=1e6),
                     r"a cmg run of 1000000001 steps would hold about 768.0 GB in memory"),
    # blocks: the wrong number of signals is refused, never read past
    "linearizer inputs": (lambda: sc.io_linearizer().output(0, [], [1e-3, 0, 1]),
                          r"block 'linearizer': the input u must have 6 values"),
    "plant inputs": (lambda: sc.spacecraft_plant().dynamics(0, [1, 0, 0, 0], [1.0]),
                     r"block 'plant': the input u must have 2 values"),
    "plant states": (lambda: sc.spacecraft_plant().dynamics(0, [1, 0, 0], [0.0, 0.0]),
                     r"block 'plant': the state x must have 4 values"),
    "axis-angle nan": (lambda: sc.quaternion_from_axis_angle([1, 0, 0], math.nan),
                       r"angle_deg must be"),
    "axis-angle zero axis": (lambda: sc.quaternion_from_axis_angle([0, 0, 0], 10.0),
                             r"axis"),
    "cmg reference nan": (lambda: cmg.reference(math.nan), r"t must be"),
    "smc state": (lambda: cmg.smc_law([0.1, 0.2, 0.3], np.zeros(6), np.zeros(4),
                                      cmg.Inertias(), {}),
                  r"x must be a vector of length 6, got shape \(3,\)"),
    "accelerations state": (lambda: cmg.accelerations([0.1, 0.2, 0.3], [0.0, 0.0],
                                                      cmg.Inertias()),
                            r"x must be a vector of length 6, got shape \(3,\)"),
    # scenarios
    "q not unit": (lambda: scenario.run("ideal", horizon=1.0, q_initial=[2, 0, 0, 0]),
                   r"q_initial"),
    "q zero": (lambda: scenario.run("ideal", horizon=1.0, q_initial=[0, 0, 0, 0]),
               r"q_initial"),
    "q nan": (lambda: scenario.run("ideal", horizon=1.0, q_initial=[math.nan, 0, 0, 0]),
              r"q_initial"),
    "unknown spacecraft case": (lambda: scenario.run("nope"), r"case must be one of"),
    "unknown tuner option": (lambda: scenario.run("proposed", horizon=1.0,
                                                  tuner_options={"gama": 1.0}),
                             r"tuner_options has unknown keys \['gama'\]; allowed: "),
    "unknown plant option": (lambda: scenario.run("proposed", horizon=1.0,
                                                  plant_options={"mass": 1.0}),
                             r"plant_options has unknown keys \['mass'\]"),
    "negative inertia error": (lambda: scenario.true_plant(True, inertia_error_scale=-1.0),
                               r"inertia_error_scale must be one factor or three"),
    "horizon API 0": (lambda: scenario.run("ideal", horizon=0.0),
                      r"horizon must be finite and > 0"),
    "time grid": (lambda: time_grid(0.05, 0.1), r"horizon must be a positive multiple of Ts"),
    "unknown cmg case": (lambda: __import__("controlkit.studies.cmg.scenario", fromlist=["run"])
                         .run("nope"), r"case must be one of"),
    # the FRIT tuner's options
    "lambda 0": (lambda: frit.frit_tuner(lambda_=0.0), r"lambda_"),
    "kappa 2": (lambda: frit.frit_tuner(kappa=2.0), r"kappa"),
    "gamma < 0": (lambda: frit.frit_tuner(gamma=-1.0), r"gamma must be finite and > 0"),
    "psi < 0": (lambda: frit.frit_tuner(psi=-1.0), r"psi must be >= 0"),
    "F 0": (lambda: frit.frit_tuner(F=0.0), r"F must be > 0 for the FRIT tuner"),
    "filter": (lambda: frit.frit_tuner(filter="tustin"), r"filter must be one of"),
    "units": (lambda: frit.frit_tuner(units="rad"), r"units must be one of"),
    "safeguard key": (lambda: frit.frit_tuner(safeguard={"rate": 1}),
                      r"safeguard has unknown keys \['rate'\]"),
    "reading key": (lambda: frit_study.run_reading("paper", {"filters": "zoh"}, horizon=1.0),
                    r"reading has unknown keys \['filters'\]"),
    "gain text": (lambda: mec.constant_gain("big"),
                  r"K must be a number or a 2x2 matrix of numbers, got 'big'"),
    # diagrams and simulation
    "initial state block": (lambda: initial_state(output_zeroing_loop(), nope=[1.0]),
                            r"no block named \['nope'\]"),
    "initial state size": (lambda: initial_state(output_zeroing_loop(), plant=[1, 0]),
                           r"initial state of block 'plant' must have 4 values"),
    "engine name": (lambda: simulate(output_zeroing_loop(), [0.0, 0.1], X0=[1, 0, 0, 0],
                                     engine="gpu"), r"engine must be one of"),
    "compile word": (lambda: input_output_response(output_zeroing_loop(), [0.0, 0.1],
                                                   initial_state=[1, 0, 0, 0], compile="yes"),
                     r"compile must be True, False or None \(decided by the run's length\), "
                     r"got 'yes'"),
    # an initial state the block refuses, and text where numbers are expected
    "initial quaternion not unit": (lambda: initial_state(output_zeroing_loop(),
                                                          plant=[2, 0, 0, 0]),
                                    r"initial state of block 'plant' must be a unit "
                                    r"quaternion .* got norm 2"),
    "initial quaternion nan": (lambda: initial_state(output_zeroing_loop(),
                                                     plant=[math.nan, 0, 0, 0]),
                               r"initial state of block 'plant' must be finite"),
    "X0 quaternion not unit": (lambda: simulate(output_zeroing_loop(), [0.0, 0.1],
                                                X0=[0.5, 0, 0, 0], engine="fast"),
                               r"initial state of block 'plant' must be a unit quaternion"),
    "initial state text": (lambda: initial_state(output_zeroing_loop(), plant="abc"),
                           r"initial state of block 'plant' must be numbers, got 'abc'"),
    "T text": (lambda: simulate(output_zeroing_loop(), ["0", "abc"], X0=[1, 0, 0, 0]),
               r"T must be numbers, got \['0', 'abc'\]"),
    "X0 text": (lambda: simulate(output_zeroing_loop(), [0.0, 0.1], X0=["abc", 0, 0, 0]),
                r"X0 must be numbers, got \['abc', 0, 0, 0\]"),
    "U text": (lambda: simulate(output_zeroing_loop(), [0.0, 0.1], X0=[1, 0, 0, 0], U="abc"),
               r"U must be numbers, got 'abc'"),
    "inertia text": (lambda: sc.spacecraft_plant(J_b="abc"),
                     r"J_b must be numbers, got 'abc'"),
    "wheel axis text": (lambda: sc.spacecraft_plant(v1=["x", 0, 0]),
                        r"v1 must be numbers, got \['x', 0, 0\]"),
    "block input text": (lambda: sc.spacecraft_plant().dynamics(0, [1, 0, 0, 0], ["a", 0]),
                         r"block 'plant': the input u must be numbers, got "),
    "record_every": (lambda: scenario.run("ideal", horizon=1.0, record_every=0),
                     r"record_every must be an integer >= 1"),
}


@pytest.mark.parametrize("case", sorted(API_CASES))
def test_api_refuses_with_a_clear_message(case):
    call, message = API_CASES[case]
    with pytest.raises(ValueError, match=message):
        call()


CLI_CASES = {
    "horizon text": (["reproduce", "--horizon", "abc"],
                     "argument --horizon: expected SECONDS or STUDY=SECONDS, got 'abc'"),
    "horizon nan": (["reproduce", "--horizon", "nan"], "horizon must be finite and > 0"),
    "horizon inf": (["reproduce", "--horizon", "inf"], "horizon must be finite and > 0"),
    "horizon off grid": (["reproduce", "spacecraft", "--horizon", "0.05"],
                         "horizon must be a positive multiple of Ts = 0.1"),
    "horizon unknown study": (["reproduce", "--horizon", "moon=5"],
                              "horizon names unknown studies ['moon']"),
    "horizon study not run": (["reproduce", "cmg", "--horizon", "spacecraft=5"],
                              "horizon names ['spacecraft'], which this run does not include"),
    "stride 0": (["reproduce", "--stride", "0"], "stride must be an integer >= 1, got 0"),
    "stride text": (["reproduce", "--stride", "x"], "argument --stride: invalid int value"),
    "unknown case": (["reproduce", "--case", "nope"], "unknown case ['nope']"),
    "unknown study": (["reproduce", "moon"], "argument study: invalid choice: 'moon'"),
    "engine": (["reproduce", "--engine", "gpu"], "argument --engine: invalid choice"),
    "set without value": (["reproduce", "--set", "F"], "expected NAME=VALUE, got 'F'"),
    "set text": (["reproduce", "--set", "F=abc"], "F: expected a number, got 'abc'"),
    "set unknown": (["reproduce", "spacecraft", "--case", "ideal", "--horizon", "1",
                     "--set", "G=1"], "unknown option ['G']"),
    "cmg too long": (["reproduce", "cmg", "--horizon", "1000000"],
                     "would hold about 768.0 GB in memory"),
    "no command": ([], "the following arguments are required: command"),
    "sweep samples": (["sweep", "spacecraft", "--samples", "0", "--out", "x"],
                      "--samples must be >= 1, got 0"),
    "sweep vary": (["sweep", "spacecraft", "--vary", "spin=1:2", "--out", "x"],
                   "unknown parameter 'spin'"),
    "sweep scheduler": (["sweep", "spacecraft", "--scheduler", "tcp://h:1", "--out", "x"],
                        "--scheduler goes with --executor dask"),
}


@pytest.mark.parametrize("case", sorted(CLI_CASES))
def test_cli_refuses_in_one_line_with_status_2(case, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be written, and nothing is
    argv, message = CLI_CASES[case]
    try:
        status = cli.main(argv)
    except SystemExit as exit_:  # argparse's own usage errors
        status = exit_.code
    err = capsys.readouterr().err
    assert status == 2
    assert message in err
    assert len(err.strip().splitlines()) == 1, err
    assert not any(tmp_path.rglob("*.csv"))


def test_cli_out_is_a_file_is_refused_before_simulating(tmp_path, capsys):
    target = tmp_path / "results"
    target.write_text("not a folder")
    assert cli.main(["reproduce", "--out", str(target)]) == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert target.read_text() == "not a folder"


def test_cli_unwritable_location_fails_before_simulating(tmp_path, capsys, monkeypatch):
    calls = []
    for name, study in STUDIES.items():
        monkeypatch.setitem(STUDIES, name, dataclasses.replace(
            study, run=lambda *a, **k: calls.append(a)))
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert cli.main(["reproduce", "--out", str(blocker / "deeper")]) == 2
    assert "cannot write to out" in capsys.readouterr().err
    assert calls == []  # refused before any case was simulated


def test_one_string_is_one_case_not_its_letters(tmp_path):
    import io

    m = run_reproduce("spacecraft", out=tmp_path, cases="ideal", horizon=1.0,
                      log=io.StringIO())
    assert list(m["spacecraft"]) == ["ideal"]


def test_help_is_plain_text(capsys):
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    text = capsys.readouterr().out
    assert "controlkit reproduce" in text and "``" not in text and ":func:" not in text


def test_debug_shows_the_traceback():
    with pytest.raises(UsageError, match="unknown case"):
        cli.main(["--debug", "reproduce", "--case", "nope"])


def test_a_diverging_loop_is_called_divergence_on_both_engines():
    # the engines meet the first non-finite number in different places (inside the
    # plant's RK4 sample, or in the block it feeds), but both name divergence and when
    for engine in ("fast", "python-control"):
        with pytest.raises((FloatingPointError, ValueError),
                           match=r"(the loop diverged at t = (0.4|0.5|1) s: .*likely a gain "
                                 r"too high|blows up inside a sample at t = 0.4 s: either the "
                                 r"loop feeding it diverged \(a gain too high)"):
            scenario.run("without_mec", horizon=5.0, F=50.0, engine=engine)


def test_a_failing_case_is_in_the_manifest_and_the_others_complete(tmp_path, monkeypatch):
    import io
    import json

    study = STUDIES["spacecraft"]
    original = study.run

    def run(case, horizon, progress, engine, **options):  # F = 50: the loop diverges
        if case == "without_mec":
            options = {**options, "F": 50.0}
        return original(case, horizon, progress, engine, **options)

    monkeypatch.setitem(STUDIES, "spacecraft", dataclasses.replace(study, run=run))
    m = run_reproduce("spacecraft", out=tmp_path, cases=["ideal", "without_mec", "proposed"],
                      horizon=20.0, log=io.StringIO(), workers=0)
    # the plant's own words, as python-control's path raises them: the sample where it blew up
    assert "block 'plant' blows up inside a sample at t = " in m["spacecraft"]["without_mec"][
        "error"]
    manifest = json.loads((tmp_path / "spacecraft" / "run.json").read_text())
    assert manifest["cases"]["without_mec"]["status"] == "failed"
    assert manifest["cases"]["ideal"]["status"] == "done"
    assert manifest["cases"]["proposed"]["status"] == "done"
    assert manifest["complete"] is False
    files = set(manifest["files"])
    assert {"ideal.csv", "proposed.csv", "metrics.json", "fig07_pointing_error.png"} <= files
    assert "without_mec.csv" not in files
    assert files == {p.name for p in (tmp_path / "spacecraft").iterdir()} - {"run.json"}


# ------------------------------------------------- builders: timebases and the FRIT filter


def test_a_continuous_controller_in_a_sampled_builder_names_itself_and_the_remedy():
    import control as ct

    from controlkit.studies.spacecraft.diagrams import mec_loop

    def error(t, x, u, params):
        return u[0:2] - u[2:4]  # the integrator's input: r - h

    def pi_output(t, x, u, params):
        return params["kp"] * (u[0:2] - u[2:4]) + params["ki"] * x

    pid = ct.nlsys(error, pi_output, inputs=["r[0]", "r[1]", "h[0]", "h[1]"],
                   outputs=["mu_n[0]", "mu_n[1]"], states=2, params={"kp": 0.002, "ki": 1e-6},
                   name="my_pi")  # continuous: dt = 0
    with pytest.raises(ValueError, match=r"block 'my_pi' is continuous \(dt = 0\) but "
                       r"my_loop is sampled at Ts = 0.1 s: sample it first "
                       r"\(controlkit.sample_nlsys\(my_pi, 0.1\).*controlkit.interconnect"):
        mec_loop(controller=pid, K=0.1, name="my_loop")
    static = ct.nlsys(None, lambda t, x, u, p: 0.001 * (u[0:2] - u[2:4]),
                      inputs=["r[0]", "r[1]", "h[0]", "h[1]"], outputs=["mu_n[0]", "mu_n[1]"],
                      name="my_p")  # dt = 0: python-control's default
    with pytest.raises(ValueError, match=r"block 'my_p' has no states but is declared "
                       r"continuous \(dt = 0\), and mec_loop is sampled at Ts = 0.1 s: "
                       r"build it with dt=None"):
        mec_loop(controller=static, K=0.1)


def test_frit_with_a_users_controller_warns_which_filter_constant_it_used():
    import warnings

    import control as ct

    from controlkit.studies.spacecraft.diagrams import mec_loop

    mine = ct.nlsys(None, lambda t, x, u, p: 0.002 * (u[0:2] - u[2:4]),
                    inputs=["r[0]", "r[1]", "h[0]", "h[1]"], outputs=["mu_n[0]", "mu_n[1]"],
                    dt=None, name="mine")
    with pytest.warns(UserWarning, match=r"controller 'mine' has no attribute F, so the FRIT "
                      r"tuner's reference model M = F/\(s\+F\) uses the paper's F = 0.0009"):
        loop = mec_loop(controller=mine)
    assert np.all(loop.syslist[3].F == 0.0009)
    mine.F = 0.002  # a controller that says its F: used, without a warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.all(mec_loop(controller=mine).syslist[3].F == 0.002)
