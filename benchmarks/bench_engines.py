"""Every kind of call a user makes, timed against python-control: this engine, and another
checkout's beside it (issue 34's before/after table).

Run::

    python benchmarks/bench_engines.py SECTION [--before DIR] [--rounds 3] [--only ROW ...]

``--before DIR`` is another checkout of controlkit (``git worktree add /tmp/before
32d1571``): every measurement is then made for both, one process after the other, for
``--rounds`` rounds, and the tables give medians. Each checkout keeps its compiled code
in its own store (``--store``, ``--before-store``; a section that needs an empty one
makes it). Children run as on a user's install: ``.pyc`` files written and read, an
older engine's switches (``CONTROLKIT_MODULES``, ``CONTROLKIT_WARMUP``) unset.
python-control (``control.input_output_response``) is timed in the same process as
ours; a sampled-data diagram, which python-control refuses, is timed on controlkit's
plain-Python reference (``engine="python-control"``, marked "ref.").

Sections (the machine is shared: compare ratios; the load average is printed):

``steps``
    Warm speed: the papers' loops (spacecraft ``ideal``, ``without_mec``,
    ``proposed``, 200 000 steps; CMG, 12 000) and python-control's examples (the cruise
    PI discrete and continuous, ``tests/continuous_diagrams.py``,
    ``tests/user_diagrams.py``, ``tests/idiom_diagrams.py``). A discrete diagram: time
    per step compiled (median of 5 warm calls) against python-control's on 1 000-2 000
    steps. A continuous one: both over the same horizon, stretched (up to 100 times)
    until python-control takes about a second. ("primed": a short run asked
    ``compile=True`` ran as Python, compiling nothing; the module was compiled by a run
    10-1000 times longer first.)
    Also the time per step *as Python* (``compile=False``, this engine only), and, with
    ``--boundscheck``, compiled without numba's index checks of users' functions
    (``NUMBA_BOUNDSCHECK=0``, its own store): issue 33's cost of the checks.
``first``
    The first call in a fresh script (stores warm: a user's second session, after an
    untimed run of every row): the call
    alone, and the whole script's wall time (``python script.py``: interpreter, imports,
    building, the call, exit), against a script calling python-control instead. Rows:
    python-control's cruise PI (301 points over 30 s, continuous), a first-order PI loop
    (101 points), the short diagrams of the three test modules.
``rebuilt``
    A notebook cell re-run: in one process a diagram is built and called twice, built
    again and called twice, built a third time and called once; each call against
    python-control's time (median of 3).
``install``
    The first call after installing (an empty store and numba cache), then ``python -m
    controlkit warmup`` (this engine) and the first call after it.
``long``
    A long first run of a new wiring (a block renamed, so that its module was never
    compiled; everything else kept): the two-rate servo over 2e4 s, the DC motor over
    1e5 s; then the same wiring warm; python-control (or the reference) and this engine
    as Python estimated from the first 1 % of the horizon.
``processes``
    What is left running when a script that ran a new wiring ends: the processes of its
    session and those naming its store, polled for 30 s after its exit.

The notebook session is ``bench_session.py``; sweeps on 1 and 2 workers,
``bench_sweep.py``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np
from timing import ROOT, checkout_env, load, run_child

PAPERS = ("spacecraft ideal", "spacecraft without_mec", "spacecraft proposed", "cmg thesis")
CRUISE = ("cruise PI discrete", "cruise PI continuous")
FIRST_ROWS = ("cruise PI 301 points", "first-order PI 101 points",
              "lone nlsys 1500 points", "lone nlsys 10000 points")
#: Rows whose blocks are all python-control's LTI systems or controlkit's: nothing of a
#: user's for numba to check the indexes of.
WITHOUT_USER_FUNCTIONS = (*PAPERS, "pi_first_order", "dc_motor", "spacecraft_fig2",
                          "servo_pi_discrete", "spacecraft_fig2_zoh", "all-LTI loop",
                          "sampled LTI plant")


# --------------------------------------------------------------------------- the diagrams

def _test_modules():
    import continuous_diagrams
    import idiom_diagrams
    import user_diagrams

    return continuous_diagrams, user_diagrams, idiom_diagrams


def rows() -> dict:
    """Row name to its group: paper, cruise, continuous, mixed, user, idiom, first."""
    continuous, user, idiom = _test_modules()
    out = {name: "paper" for name in PAPERS}
    out.update({name: "cruise" for name in CRUISE})
    out.update({name: "continuous" for name in continuous.CONTINUOUS})
    out.update({name: "mixed" for name in continuous.MIXED})
    out.update({name: "user" for name in user.DIAGRAMS})
    out.update({name: "idiom" for name in idiom.DIAGRAMS})
    out.update({name: "first" for name in FIRST_ROWS})
    return out


def is_discrete(name) -> bool:
    return rows()[name] in ("paper", "user", "idiom") or name == "cruise PI discrete"


def build(name, size=None):
    """``(sys, T, X0, U, params)`` of row ``name``: a discrete one over ``size`` steps
    (None: its own), a continuous one over its own horizon times ``size`` (None: 1)."""
    if name in FIRST_ROWS:
        return _first_row(name)
    group = rows()[name]
    if group == "paper":
        return _paper(name, size)
    if name == "cruise PI discrete":
        from cruise import loop

        sys_, T, X0, U = loop(0.1, points=size or 20_000)
        return sys_, T, X0, U, None
    if group in ("user", "idiom"):
        _, user, idiom = _test_modules()
        builder = {**user.DIAGRAMS, **idiom.DIAGRAMS}[name]
        return builder(steps=size) if size else builder()
    if name == "cruise PI continuous":
        from cruise import loop

        sys_, T, X0, U = loop(None, points=2001)  # 20 s
    else:
        continuous, _, _ = _test_modules()
        sys_, T, X0, U = {**continuous.CONTINUOUS, **continuous.MIXED}[name]()
    return (*stretched(sys_, T, X0, U, size or 1), None)


def stretched(sys_, T, X0, U, factor):
    """The diagram over ``factor`` times its horizon, as many points per second, its
    input stretched in time."""
    U = np.atleast_2d(U) if np.ndim(U) else np.zeros((0, T.size))
    if factor == 1:
        return sys_, T, np.asarray(X0, dtype=float), U
    n = int(round(factor * (T.size - 1))) + 1
    T_new = np.linspace(0.0, factor * T[-1], n)
    U_new = np.array([np.interp(T_new / factor, T, row) for row in U]).reshape(len(U), n)
    return sys_, T_new, np.asarray(X0, dtype=float), U_new


def _paper(name, steps):
    from controlkit.simulation import initial_state

    study, case = name.split()
    if study == "spacecraft":
        from controlkit.studies.spacecraft import scenario

        loop = scenario.build_loop(case)
        X0 = initial_state(loop, plant=scenario.initial_attitude())
        dt, steps = 0.1, steps or 200_000
    else:
        from controlkit.studies.cmg import scenario

        loop = scenario.build_loop(case)
        X0 = initial_state(loop, cmg=scenario.X0_THESIS)
        dt, steps = 0.001, steps or 12_000
    T = np.arange(steps) * dt
    return loop, T, X0, np.zeros((loop.ninputs, steps)), None


def _first_row(name):
    """python-control only: the script timing python-control alone imports nothing else."""
    if name == "cruise PI 301 points":
        from cruise import loop

        sys_, T, X0, U = loop(None, points=301, horizon=30.0)
        return sys_, T, X0, U, None
    import control as ct

    if name.startswith("lone nlsys"):  # a block without an interconnect: Van der Pol's
        def vdp(t, x, u, params):
            mu = params.get("mu", 1.0)
            return np.array([x[1], mu * (1 - x[0] ** 2) * x[1] - x[0] + u[0]])

        block = ct.nlsys(vdp, None, inputs="u", outputs=["x0", "x1"], states=2, name="vdp",
                         params={"mu": 1.0})
        T = np.linspace(0.0, 20.0, int(name.split()[2]))
        return block, T, np.array([1.0, 0.0]), np.zeros_like(T), {"mu": 0.8}
    plant = ct.tf([1.0], [2.0, 1.0], name="plant", inputs="u", outputs="y")
    pi = ct.tf([1.5, 0.8], [1.0, 0.0], name="pi", inputs="e", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = ct.interconnect([plant, pi, error], inputs="r", outputs=["y", "u"])
    T = np.linspace(0.0, 10.0, 101)
    return loop, T, np.zeros(loop.nstates), np.where(T > 1.0, 1.0, 0.0), None


def renamed(sys_):
    """The same diagram with its first block renamed: a wiring whose module was never
    compiled (the block names are in the module's text)."""
    getattr(sys_, "syslist", [sys_])[0].name += f"_{uuid.uuid4().hex[:8]}"
    return sys_


# --------------------------------------------------------------------------- in a child

def _has_compile() -> bool:
    import inspect

    import controlkit

    return "compile" in inspect.signature(controlkit.input_output_response).parameters


def ours(sys_, T, U, X0, params=None, compile=None):
    """``controlkit.input_output_response`` (``compile`` passed to an engine that has it)."""
    import controlkit

    options = {"compile": compile} if compile is not None and _has_compile() else {}
    return controlkit.input_output_response(sys_, T, U, X0, params=params, **options)


def reference(sys_, T, U, X0, params=None):
    """python-control; controlkit's plain-Python reference for a sampled-data diagram."""
    import control as ct

    if type(sys_).__name__ == "SampledDataSystem":
        import controlkit

        return controlkit.input_output_response(sys_, T, U, X0, params=params,
                                                engine="python-control")
    return ct.input_output_response(sys_, T, U, X0, params=params)


def compiled_now(sys_, T, U, X0, params=None):
    """Make ``sys_``'s compiled module ready in this process: ``compile=True`` on an engine
    that has it; on an older one, a call and the end of the background compile it starts."""
    if _has_compile():
        return ours(sys_, T, U, X0, params, compile=True)
    result = ours(sys_, T, U, X0, params)
    try:
        from controlkit.engines.fast import switching
    except ImportError:
        return result
    switching.wait_for_compiles()
    return ours(sys_, T, U, X0, params)


def timed(function, *args, **kwargs):
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return time.perf_counter() - start, result


def mode(result) -> str:
    return getattr(result, "engine_mode", "?")


def child_steps(name):
    """Section ``steps`` for one row, in this process."""
    discrete = is_discrete(name)
    factor = 1
    if discrete:
        n_ref = 1_000 if rows()[name] in ("user", "idiom") else 2_000
        n_ours = {"user": 50_000, "idiom": 50_000}.get(rows()[name])  # None: the row's own
        sys_, T, X0, U, p = build(name, n_ref)
        ref_s, ref = timed(reference, sys_, T, U, X0, p)
    else:
        sys_, T, X0, U, p = build(name, 1)
        ref_s, ref = timed(reference, sys_, T, U, X0, p)
        factor = int(np.clip(round(1.0 / max(ref_s, 1e-3)), 1, 100))
        if factor > 1:
            sys_, T, X0, U, p = build(name, factor)
            ref_s, ref = timed(reference, sys_, T, U, X0, p)
    n_ref = T.size
    check = compiled_now(sys_, T, U, X0, p)
    primed = None
    for longer in (10, 100, 1000):  # a short run asked compiled may run as Python: a
        if discrete or mode(check) != "python":  # longer one compiles (and compares) it
            break
        primed = longer
        ours(*_args(build(name, factor * longer)), compile=True)
        check = ours(sys_, T, U, X0, p, compile=True)
    difference = float(np.max(np.abs(np.asarray(check.y) - np.asarray(ref.y)), initial=0.0))
    python_s = None
    if _has_compile():
        python_s, _ = timed(ours, sys_, T, U, X0, p, compile=False)
    if discrete:
        sys_, T, X0, U, p = build(name, n_ours)
    warm = [timed(ours, sys_, T, U, X0, p, compile=True) for _ in range(5)]
    return {"row": name, "discrete": discrete, "ref_s": ref_s, "ref_n": n_ref,
            "ours_s": statistics.median(s for s, _ in warm), "ours_n": T.size,
            "mode": mode(warm[-1][1]), "python_s": python_s, "difference": difference,
            "primed": primed}


def child_first(name, who):
    """Section ``first``: import, build and one call, timed in this fresh process."""
    start = time.perf_counter()
    if who == "pc":
        import control  # noqa: F401
    else:
        import controlkit  # noqa: F401
    imported = time.perf_counter()
    sys_, T, X0, U, p = build(name)
    built = time.perf_counter()
    call = reference if who == "pc" else ours
    result = call(sys_, T, U, X0, p)
    done = time.perf_counter()
    return {"row": name, "import_s": imported - start, "build_s": built - imported,
            "call_s": done - built, "mode": mode(result) if who != "pc" else "-"}


def child_rebuilt(name, who=None):
    """Section ``rebuilt``: calls 1-2 of a diagram, 3-4 of it built again, 5 of a third."""
    ref = statistics.median(timed(reference, *_args(build(name)))[0] for _ in range(3))
    calls = []
    for count in (2, 2, 1):
        args = _args(build(name))
        for _ in range(count):
            seconds, result = timed(ours, *args)
            calls.append((seconds, mode(result)))
    return {"row": name, "ref_s": ref, "calls": calls}


def _args(built):
    sys_, T, X0, U, p = built
    return sys_, T, U, X0, p


def child_install(name):
    seconds, result = timed(ours, *_args(build(name)))
    return {"row": name, "call_s": seconds, "mode": mode(result)}


LONG = {"two_rate_servo": 2e4, "dc_motor": 1e5}


def child_long(name):
    """Section ``long``: the first run of a new wiring over a long horizon, then warm; the
    reference and Python mode estimated on the first 1 % of the horizon."""
    sys_, T, X0, U, _ = build(name)
    factor = LONG[name] / T[-1]
    T_eval = np.linspace(0.0, LONG[name], 1001)
    U_eval = np.array([np.interp(T_eval / factor, T, row) for row in U]).reshape(len(U), -1)
    sys_ = renamed(sys_)
    first_s, result = timed(ours, sys_, T_eval, U_eval, X0)
    first_mode = mode(result)
    try:
        from controlkit.engines.fast import switching

        switching.wait_for_compiles()
    except ImportError:
        pass
    warm = [timed(ours, sys_, T_eval, U_eval, X0) for _ in range(2)]
    short = 11  # the first 1 % of the 1001 points
    ref_s = timed(reference, sys_, T_eval[:short], U_eval[:, :short], X0)[0] * 100
    python_s = None
    if _has_compile():
        python_s = timed(ours, sys_, T_eval[:short], U_eval[:, :short], X0,
                         compile=False)[0] * 100
    return {"row": name, "first_s": first_s, "first_mode": first_mode,
            "warm_s": statistics.median(s for s, _ in warm), "warm_mode": mode(warm[-1][1]),
            "ref_s": ref_s, "python_s": python_s}


def child_processes(name):
    sys_, T, X0, U, p = build(name)
    seconds, result = timed(ours, renamed(sys_), T, U, X0, p)
    return {"row": name, "call_s": seconds, "mode": mode(result), "pid": os.getpid()}


CHILDREN = {"steps": child_steps, "first": child_first, "rebuilt": child_rebuilt,
            "install": child_install, "long": child_long, "processes": child_processes}


# --------------------------------------------------------------------------- the parent

class Versions:
    """The checkouts measured: ``after`` (this one) and, with ``--before``, ``before``."""

    def __init__(self, args):
        self.stores = {"after": Path(args.store)}
        self.trees = {"after": Path(args.after).resolve() if args.after else None}
        if args.before:
            self.trees["before"] = Path(args.before).resolve()
            self.stores["before"] = Path(args.before_store)

    def names(self):
        return list(self.trees)[::-1]  # before, after

    def env(self, who, store=None, **extra):
        return checkout_env(self.trees[who], store or self.stores[who], **extra)


def _child(section, *args):
    return [__file__, "--child", section, *args]


def _ratio(a, b):
    if not b:
        return "-"
    r = a / b
    return f"{r:.2f}x" if r < 10 else f"{r:.0f}x"


def _med(values):
    values = [v for v in values if v is not None]
    return statistics.median(values) if values else None


def _range(values, scale=1.0, digits=3):
    """The median of ``values`` (times ``scale``), and their range when they differ."""
    values = sorted(v * scale for v in values if v is not None)
    if not values:
        return "-"
    middle = f"{statistics.median(values):.{digits}f}"
    if len(values) == 1 or f"{values[0]:.{digits}f}" == f"{values[-1]:.{digits}f}":
        return middle
    return f"{middle} ({values[0]:.{digits}f}-{values[-1]:.{digits}f})"


def _collect(args, jobs):
    """Run ``jobs`` (``(label, row, child arguments, env)``) for ``args.rounds`` rounds, each
    result logged on stderr as ``# label row: {json}``; with ``args.from_log``, read those
    lines from a log instead (an interrupted run's, or to print its tables again).
    Returns ``{(row, label): [result per round]}``."""
    results = {}
    if args.from_log:
        for line in Path(args.from_log).read_text().splitlines():
            if not line.startswith("# ") or ": {" not in line:
                continue
            out = json.loads(line[line.index(": {") + 2:])
            label = line[2:line.index(f" {out['row']}: {{")].strip()
            results.setdefault((out["row"], label), []).append(out)
        return results
    for _ in range(args.rounds):
        for label, name, child, env in jobs:
            out, wall, _ = run_child(child, env)
            out.update(wall=wall, load=load())
            results.setdefault((name, label), []).append(out)
            print(f"# {label:22s} {name}: {json.dumps(out)}", file=sys.stderr, flush=True)
    return results


def section_steps(args, versions, names):
    variants = [(who, who, {}) for who in versions.names()]
    if args.boundscheck:
        variants.append(("after, no boundscheck", "after",
                         {"store": str(versions.stores["after"]) + "-noboundscheck",
                          "NUMBA_BOUNDSCHECK": "0"}))
    results = _collect(args, [
        (label, name, _child("steps", name), versions.env(who, **extra))
        for name in names for label, who, extra in variants
        if not ("NUMBA_BOUNDSCHECK" in extra and name in WITHOUT_USER_FUNCTIONS)])
    labels = [label for label, _, _ in variants if any(k[1] == label for k in results)]
    names = [name for name in names if (name, "after") in results]
    print(f"\n{max(map(len, results.values()))} round(s); per step (discrete) or per call "
          f"(continuous, same horizon), median; ratio = python-control / ours in each process")
    head = "| diagram | python-control | " + " | ".join(
        f"{label} compiled | ratio" for label in labels) + " | after as Python | ratio |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for name in names:
        cells = []
        first = results[(name, "after")][0]
        unit = "us/step" if first["discrete"] else "ms/call"
        scale = 1e6 if first["discrete"] else 1e3
        ref = []
        for label in labels:
            runs = results.get((name, label))
            if runs is None:
                cells.append("- | -")
                continue
            per = [r["ours_s"] / r["ours_n"] if r["discrete"] else r["ours_s"] for r in runs]
            ref_per = [r["ref_s"] / r["ref_n"] if r["discrete"] else r["ref_s"] for r in runs]
            ref += ref_per
            ratios = [a / b for a, b in zip(ref_per, per, strict=True)]
            primed = "; primed" if runs[-1].get("primed") else ""
            cells.append(f"{_range(per, scale, 2)} {unit} ({runs[-1]['mode']}{primed}) | "
                         f"{_range(ratios, 1, 0)}x")
        after = results[(name, "after")]
        py = [r["python_s"] / (r["ref_n"] if r["discrete"] else 1) for r in after]
        py_ratio = [(r["ref_s"] / r["python_s"]) for r in after]
        marker = " (ref.)" if rows()[name] == "mixed" else ""
        print(f"| {name} | {_range(ref, scale, 0)} {unit}{marker} | " + " | ".join(cells)
              + f" | {_range(py, scale, 0)} {unit} | {_range(py_ratio, 1, 1)}x |")
    loads = [r["load"] for runs in results.values() for r in runs]
    print(f"\nload average (1 min) during the runs: {min(loads)}-{max(loads)}")
    diffs = max(r["difference"] for runs in results.values() for r in runs)
    print(f"largest output difference compiled vs python-control: {diffs:.1e}")


def _fill_stores(section, versions, names):
    """One untimed run of each row on each checkout: the stores then hold what a user's
    earlier session left (a module the rule compiled, an older engine's background
    compiles)."""
    for name in names:
        for who in versions.names():
            run_child(_child(section, name, who), versions.env(who))


def section_first(args, versions, names):
    if not args.from_log:
        _fill_stores("first", versions, names)
    results = _collect(args, [
        (who, name, _child("first", name, who), versions.env("after" if who == "pc" else who))
        for name in names for who in ["pc", *versions.names()]])
    whos = versions.names()
    names = [name for name in names if (name, "after") in results]
    print(f"\n{max(map(len, results.values()))} round(s), fresh process each; call alone and "
          f"whole script (wall), medians; ratio = python-control / ours")
    head = ("| diagram | python-control call | script | " + " | ".join(
        f"{w} call | ratio | {w} script | ratio" for w in whos) + " |")
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    for name in names:
        pc = results[(name, "pc")]
        pc_call, pc_wall = _med(r["call_s"] for r in pc), _med(r["wall"] for r in pc)
        cells = []
        for who in whos:
            runs = results[(name, who)]
            call, wall = _med(r["call_s"] for r in runs), _med(r["wall"] for r in runs)
            modes = "/".join(sorted({r["mode"] for r in runs}))
            cells.append(f"{call:.3f} s ({modes}) | {_ratio(pc_call, call)} | {wall:.2f} s | "
                         f"{_ratio(pc_wall, wall)}")
        print(f"| {name} | {pc_call:.3f} s | {pc_wall:.2f} s | " + " | ".join(cells) + " |")
    loads = [r["load"] for runs in results.values() for r in runs]
    print(f"\nload average (1 min): {min(loads)}-{max(loads)}")


#: A call's ``engine_mode``, as one letter.
LETTERS = {"python": "p", "compiled": "c", "python-control": "r"}


def section_rebuilt(args, versions, names):
    if not args.from_log:
        _fill_stores("rebuilt", versions, names)
    results = _collect(args, [(who, name, _child("rebuilt", name), versions.env(who))
                              for name in names for who in versions.names()])
    whos = versions.names()
    names = [name for name in names if (name, "after") in results]
    print(f"\n{max(map(len, results.values()))} round(s); each call's median time and "
          f"python-control / ours (calls 1-2: built once; 3-4: built again; 5: built a 3rd time)")
    print("| diagram | python-control | " + " | ".join(f"{w}: calls 1, 2, 3, 4, 5"
                                                     for w in whos) + " |")
    print("|---|---|" + "---|" * len(whos))
    for name in names:
        ref = _med(r["ref_s"] for who in whos for r in results[(name, who)])
        cells = []
        for who in whos:
            runs = results[(name, who)]
            calls = [_med(r["calls"][i][0] for r in runs) for i in range(5)]
            ratios = [_med(r["ref_s"] / r["calls"][i][0] for r in runs) for i in range(5)]
            modes = "".join(LETTERS.get(r["calls"][i][1], "?") for i in range(5)
                            for r in runs[-1:])
            cells.append(", ".join(f"{c * 1e3:.1f} ms {x:.1f}x" for c, x in
                                   zip(calls, ratios, strict=True)) + f" [{modes}]")
        print(f"| {name} | {ref * 1e3:.1f} ms | " + " | ".join(cells) + " |")
    loads = [r["load"] for runs in results.values() for r in runs]
    print(f"\n[p]ython / [c]ompiled / [r]: python-control's own run / [?] (an engine that "
          f"does not say); load average "
          f"(1 min): {min(loads)}-{max(loads)}")


def section_install(args, versions, names):
    lines = []

    def first_call(who, name, env):
        out, wall, err = run_child(_child("install", name), env)
        said = " ".join(line.strip() for line in err.splitlines() if "controlkit" in line)
        return f"{out['call_s']:.2f} s ({out['mode']}) | {wall:.1f} s | {load()} | {said[:120]}"

    for _ in range(args.rounds):
        for who in versions.names():
            for name in names:  # each row the first call after installing: its own store
                with tempfile.TemporaryDirectory(prefix="controlkit-install-") as tmp:
                    (Path(tmp) / "numba").mkdir()
                    env = versions.env(who, store=Path(tmp) / "store",
                                       NUMBA_CACHE_DIR=Path(tmp) / "numba")
                    call = first_call(who, name, env)
                    lines.append(f"| {who} | empty store, {name} | {call} |")
                print(lines[-1], file=sys.stderr, flush=True)
            if who != "after":
                continue
            with tempfile.TemporaryDirectory(prefix="controlkit-warmup-") as tmp:
                (Path(tmp) / "numba").mkdir()
                env = versions.env(who, store=Path(tmp) / "store",
                                   NUMBA_CACHE_DIR=Path(tmp) / "numba")
                start = time.perf_counter()
                subprocess.run([sys.executable, "-m", "controlkit", "warmup"], env=env,
                               check=True, capture_output=True)
                warmup = time.perf_counter() - start
                lines.append(f"| {who} | `python -m controlkit warmup`, empty store | - | "
                             f"{warmup:.1f} s | {load()} | |")
                for name in names:
                    call = first_call(who, name, env)
                    lines.append(f"| {who} | after warmup, {name} | {call} |")
                    print(lines[-1], file=sys.stderr, flush=True)
    print("\n| engine | call | call alone | script wall | load | said on stderr |")
    print("|---|---|---|---|---|---|")
    print("\n".join(lines))


def section_long(args, versions, names):
    lines = []
    for _ in range(args.rounds):
        for name in names:
            for who in versions.names():
                out, wall, err = run_child(_child("long", name), versions.env(who))
                said = " ".join(line for line in err.splitlines() if "controlkit" in line)
                py = f"~{out['python_s']:.0f} s" if out["python_s"] else "-"
                lines.append(f"| {name} ({LONG[name]:g} s) | {who} | {out['first_s']:.1f} s "
                             f"({out['first_mode']}) | {out['warm_s']:.1f} s "
                             f"({out['warm_mode']}) | "
                             f"~{out['ref_s']:.0f} s | {py} | {load()} | {said[:100]} |")
                print(lines[-1], file=sys.stderr, flush=True)
    print("\n| diagram | engine | first run, new wiring | warm | python-control / ref. "
          "(from 1 %) | as Python (from 1 %) | load | said on stderr |")
    print("|---|---|---|---|---|---|---|---|")
    print("\n".join(lines))


def _pids():
    return {int(entry.name) for entry in Path("/proc").iterdir() if entry.name.isdigit()}


def _ours_left(session, store, older):
    """Processes of session ``session``, or naming ``store`` (an older engine's compiles
    name the module they compile), still alive and not among the pids ``older`` (those
    running before the script): (pid, args)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) in older:
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        sid = int(stat.rsplit(")", 1)[1].split()[4])
        if sid == session or str(store) in cmdline:
            found.append((int(entry.name), cmdline.strip()[:150]))
    return found


def section_processes(args, versions, names):
    print("\n| engine | script | call | processes left at +0.1 s | +2 s | +10 s | +30 s | "
          "gone after |")
    print("|---|---|---|---|---|---|---|---|")
    for _ in range(args.rounds):
        for name in names:
            for who in versions.names():
                store = versions.stores[who]
                older = _pids()
                process = subprocess.Popen(
                    [sys.executable, *_child("processes", name)], env=versions.env(who),
                    stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
                    start_new_session=True)
                out = json.loads(process.communicate()[0].strip().splitlines()[-1])
                ended = time.perf_counter()
                seen, gone, marks = {}, None, (0.1, 2.0, 10.0, 30.0)
                while time.perf_counter() - ended < 120:
                    now = time.perf_counter() - ended
                    left = _ours_left(process.pid, store, older)
                    for mark in marks:
                        if mark not in seen and now >= mark:
                            seen[mark] = left
                    if not left:
                        gone = now if gone is None else gone
                        if now >= marks[-1] and now - gone > 5:  # none for 5 s
                            break
                    else:
                        gone = None
                    time.sleep(0.05)
                cells = " | ".join(
                    f"{len(seen.get(m, []))}" + (f": `{seen[m][0][1][:70]}`"
                                                 if seen.get(m) else "") for m in marks)
                print(f"| {who} | {name}, new wiring | {out['call_s']:.2f} s ({out['mode']}) "
                      f"| {cells} | {f'{gone:.1f} s' if gone is not None else '> 120 s'} |",
                      flush=True)


SECTIONS = {"steps": section_steps, "first": section_first, "rebuilt": section_rebuilt,
            "install": section_install, "long": section_long,
            "processes": section_processes}
DEFAULT_ROWS = {
    "steps": lambda: [n for n, g in rows().items() if g != "first"],
    "first": lambda: [*FIRST_ROWS, *[n for n, g in rows().items()
                                      if g in ("continuous", "mixed", "user", "idiom")]],
    "rebuilt": lambda: [*FIRST_ROWS, *[n for n, g in rows().items()
                                        if g in ("continuous", "user", "idiom")]],
    "install": lambda: ["cruise PI 301 points", "car_pi", "spacecraft proposed"],
    "long": lambda: list(LONG),
    "processes": lambda: ["car_pi"],
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("section", choices=list(SECTIONS))
    parser.add_argument("--before", metavar="DIR", help="another checkout, measured beside")
    parser.add_argument("--after", metavar="DIR",
                        help="the checkout measured as 'after' (default: the installed one; "
                             "e.g. a `git archive` of a commit, stable while work goes on)")
    parser.add_argument("--store", default=os.environ.get(
        "CONTROLKIT_CACHE_DIR", Path.home() / ".cache" / "controlkit" / "bench-after"),
                        help="this checkout's store (default: CONTROLKIT_CACHE_DIR or "
                             "~/.cache/controlkit/bench-after)")
    parser.add_argument("--before-store",
                        default=Path.home() / ".cache" / "controlkit" / "bench-before",
                        help="the other checkout's store")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--only", nargs="+", metavar="ROW", help="rows (see --list)")
    parser.add_argument("--list", action="store_true", help="list the rows and exit")
    parser.add_argument("--boundscheck", action="store_true",
                        help="steps: also compiled without index checks (NUMBA_BOUNDSCHECK=0)")
    parser.add_argument("--from-log", metavar="FILE",
                        help="steps, first, rebuilt: print the tables of a run's stderr log "
                             "(an interrupted run's too) instead of measuring")
    parser.add_argument("--child", nargs="+", help=argparse.SUPPRESS)
    if argv is None and "--child" in sys.argv:  # a child: --child SECTION ROW [WHO]
        section, *rest = sys.argv[sys.argv.index("--child") + 1:]
        print(json.dumps(CHILDREN[section](*rest)))
        return 0
    args = parser.parse_args(argv)
    sys.path.insert(0, str(ROOT / "tests"))
    if args.list:
        print("\n".join(f"{g:10s} {n}" for n, g in rows().items()))
        return 0
    names = args.only or DEFAULT_ROWS[args.section]()
    unknown = set(names) - set(rows())
    if unknown:
        parser.error(f"unknown rows {sorted(unknown)}; --list lists them")
    if args.rounds < 1:
        parser.error(f"--rounds must be >= 1, got {args.rounds}")
    SECTIONS[args.section](args, Versions(args), names)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
