"""The notebook warm-up (controlkit._warmup): it starts where it should, finishes, is
waited for by a fork, and never imports beside the person's own imports."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

#: A Jupyter kernel, as far as controlkit can tell (IPython's shell is running).
AS_IN_A_KERNEL = ("import sys, types; sys.modules['IPython'] = types.ModuleType('IPython')\n"
                  "sys.modules['IPython'].get_ipython = object\n")


def _run(code: str, **env) -> subprocess.CompletedProcess:
    environment = {k: v for k, v in os.environ.items() if k != "CONTROLKIT_WARMUP"}
    environment.update(env)
    return subprocess.run([sys.executable, "-c", code], env=environment, timeout=120,
                          capture_output=True, text=True)


def test_in_a_kernel_numba_and_the_engine_are_ready_before_the_first_call():
    result = _run(AS_IN_A_KERNEL + (
        "import control as ct\n"
        "import controlkit\n"
        "from controlkit import _quiet, _warmup\n"
        "assert _quiet._THREAD is not None and _quiet._THREAD.daemon\n"
        "_warmup.wait()\n"
        "assert not _quiet._THREAD.is_alive()\n"
        "assert 'controlkit.engines.fast.response' in sys.modules\n"
        "import numpy as np\n"
        "p = ct.ss([[-1.0]], [[1.0]], [[1.0]], [[0.0]], inputs='u', outputs='y')\n"
        "T = np.linspace(0, 1, 3)\n"
        "ours = controlkit.input_output_response(p, T, 1.0).outputs\n"
        "print(np.abs(ours - ct.input_output_response(p, T, 1.0).outputs).max())\n"))
    assert result.returncode == 0, result.stderr
    assert float(result.stdout) < 1e-12


@pytest.mark.parametrize("setting, started", [("0", False), ("1", True)])
def test_the_setting_decides(setting, started):
    code = "import controlkit\nprint(controlkit._quiet._THREAD is not None)\n"
    result = _run(code, CONTROLKIT_WARMUP=setting)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == [str(started)]


def test_outside_a_kernel_nothing_starts_and_a_bad_setting_is_named():
    result = _run("import IPython, controlkit\nprint(controlkit._quiet._THREAD is None)\n",
                  PYTHONWARNINGS="always")  # IPython imported, but no shell runs
    assert result.stdout.split() == ["True"], result.stderr
    result = _run(AS_IN_A_KERNEL + "import controlkit\n"
                  "print(controlkit._quiet._THREAD is not None)\n",
                  CONTROLKIT_WARMUP="yes", PYTHONWARNINGS="always")
    assert result.stdout.split() == ["True"], result.stderr
    assert "CONTROLKIT_WARMUP must be '0' or '1', not 'yes'; ignored" in result.stderr


def test_a_fork_waits_for_the_warm_up_and_the_child_uses_numba():
    result = _run(
        "import os, control, controlkit\n"
        "from controlkit import _quiet, _warmup\n"
        "pid = os.fork()\n"
        "if pid == 0:\n"
        "    from controlkit.kernels.common import rk4_step\n"
        "    import controlkit._jit as j\n"
        "    os._exit(0 if j.HAVE_NUMBA else 3)\n"
        "print(_quiet._THREAD.is_alive(), os.waitpid(pid, 0)[1])\n",
        CONTROLKIT_WARMUP="1")
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["False", "0"]


@pytest.mark.parametrize("imports", [
    # A package's module imported directly while the thread imports the package: ended
    # in "cannot import name 'prepare' from partially initialized module" in 3 of 8 runs
    # when the thread imported beside the person's cells.
    "import controlkit.studies.spacecraft.diagrams, controlkit.engines.fast.run",
    "import numba; from numba.typed import List; import controlkit.blocks.sampling",
    "import time; time.sleep(0.2); import controlkit.sweep, controlkit.drawing",
])
def test_the_persons_imports_while_it_runs_are_never_half_done(imports):
    result = _run(
        f"import control, controlkit\n{imports}\n"
        "from controlkit import simulate, initial_state, time_grid\n"
        "import controlkit.studies.spacecraft.diagrams as d\n"
        "loop = d.output_zeroing_loop()\n"
        "r = simulate(loop, time_grid(0.5, 0.1), X0=initial_state(loop, plant=[1, 0, 0, 0]))\n"
        "print(r.outputs.shape[-1])\n", CONTROLKIT_WARMUP="1")
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["6"]


def test_the_warm_up_loads_the_driver_from_the_cache_and_never_compiles_it(tmp_path,
                                                                          monkeypatch):
    code = AS_IN_A_KERNEL + (
        "import controlkit\n"
        "from controlkit import _warmup\n"
        "_warmup.wait()\n"
        "from controlkit.engines.fast import loader\n"
        "d = loader.driver()\n"
        "print(len(d.run_continuous.overloads), len(d.run_discrete.overloads))\n")
    # the cache as the suite left it: the driver compiled by earlier tests (or now)
    import control as ct
    import numpy as np

    import controlkit
    from controlkit.engines.fast import run as fast_run

    monkeypatch.setattr(fast_run, "MODULES", "never")
    for dt in (0, 0.1):  # the driver's two entry points, compiled if need be
        lag = ct.ss([[-1.0 if dt == 0 else 0.5]], [[1.0]], [[1.0]], [[0.0]], dt=dt,
                    inputs="u", outputs="y", name="lag")
        controlkit.input_output_response(ct.interconnect([lag], inputs="u", outputs="y"),
                                         np.arange(3) * 0.1, 1.0, 0.0)
    result = _run(code)
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["1", "1"]
    # an empty cache: the thread compiles nothing (a compile holds numba's lock for seconds)
    result = _run(code, CONTROLKIT_CACHE_DIR=str(tmp_path / "cache"))
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["0", "0"]


def test_after_a_run_on_its_module_a_notebook_loads_its_blocks_entries_for_a_new_wiring(
        monkeypatch):
    # the entries in the cache, as a first wiring on the driver leaves them
    import controlkit
    from controlkit.engines.fast import run as fast_run

    here = os.path.dirname(os.path.abspath(__file__))
    sys.path.insert(0, here)
    from continuous_diagrams import CONTINUOUS

    monkeypatch.setattr(fast_run, "MODULES", "never")
    loop, T, X0, U = CONTINUOUS["steering"]()
    controlkit.input_output_response(loop, T, U, X0)
    result = _run(AS_IN_A_KERNEL + (
        f"sys.path.insert(0, {here!r})\n"
        "import numpy as np, controlkit\n"
        "from controlkit import _warmup\n"
        "from controlkit.engines.fast import entries, run\n"
        "from continuous_diagrams import CONTINUOUS\n"
        "_warmup.wait()\n"
        "loop, T, X0, U = CONTINUOUS['steering']()\n"
        "first = controlkit.input_output_response(loop, T, U, X0).outputs\n"
        "job = run.prepare(loop, None, (T[0], X0, U[:, 0]))  # the call's own, kept\n"
        "_warmup.wait()  # for the entries, loaded after the call\n"
        "print(job.how, all(entries.loaded(k) for k in job.plan.kernels))\n"
        "run.MODULES = 'never'  # the same blocks wired anew: on the driver\n"
        "before = {m for m in sys.modules if m.startswith('controlkit_entry_')}\n"
        "loop, T, X0, U = CONTINUOUS['steering']()\n"
        "again = controlkit.input_output_response(loop, T, U, X0).outputs\n"
        "after = {m for m in sys.modules if m.startswith('controlkit_entry_')}\n"
        "print(after == before, np.abs(again - first).max())\n"),
        CONTROLKIT_MODULES="now")
    assert result.returncode == 0, result.stderr
    ran, loaded, nothing_imported, difference = result.stdout.split()
    assert (ran, loaded, nothing_imported) == ("module", "True", "True")
    assert float(difference) <= 1e-12


def test_the_entries_are_loaded_from_the_cache_only(tmp_path):
    # an empty cache: nothing is compiled in the background (a compile holds numba's lock)
    result = _run(
        "from controlkit.engines.fast import entries\n"
        "from controlkit.engines.fast.loader import cache_folder\n"
        "from controlkit.kernels.common import constant_output\n"
        "print(entries.preload([constant_output], cache_folder()),\n"
        "      entries.loaded(constant_output),\n"
        "      len(entries._imported(entries._reference(constant_output),\n"
        "                            cache_folder()).overloads))\n",
        CONTROLKIT_CACHE_DIR=str(tmp_path / "cache"))
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["0", "False", "0"]


def test_a_session_opened_again_finds_the_diagrams_run_last_loaded_before_its_first_call():
    here = os.path.dirname(os.path.abspath(__file__))
    build = (f"sys.path.insert(0, {here!r})\n"
             "import controlkit\n"
             "from controlkit.engines.fast import loader, run\n"
             "from continuous_diagrams import CONTINUOUS\n"
             "loop, T, X0, U = CONTINUOUS['dc_motor']()\n")
    first = _run("import sys\n" + build + "controlkit.input_output_response(loop, T, U, X0)\n"
                 "import numpy as np\n"
                 "print(run.prepare(loop, None, (T[0], np.asarray(X0, float),\n"
                 "                               np.atleast_2d(U)[:, 0])).how)\n",
                 CONTROLKIT_MODULES="now", CONTROLKIT_WARMUP="0")
    assert first.returncode == 0, first.stderr
    assert first.stdout.split() == ["module"]
    again = _run(AS_IN_A_KERNEL + "import controlkit\ncontrolkit._warmup.wait()\n" + build + (
        "module = sys.modules.get('controlkit_' + loader.module_path(\n"
        "    run.prepare(loop).source).stem)\n"
        "print(module is not None and len(module.run_continuous.overloads))\n"))
    assert again.returncode == 0, again.stderr
    assert again.stdout.split() == ["1"]


def test_the_marks_of_diagrams_run_give_the_last_ones_oldest_first(tmp_path, monkeypatch):
    from controlkit.engines.fast import recent

    monkeypatch.setattr(recent, "_folder", lambda: tmp_path / "recent")
    (tmp_path / "recent").mkdir()
    for age, stem in enumerate(["diagram_c", "diagram_b", "diagram_a", "diagram_gone"]):
        if stem != "diagram_gone":
            (tmp_path / f"{stem}.py").write_text("")
        mark = tmp_path / "recent" / f"{stem}.run_continuous"
        mark.touch()
        os.utime(mark, (1000.0 - age, 1000.0 - age))
    (tmp_path / "recent" / "diagram_a.not_an_entry").touch()
    assert [(p.name, e) for p, e in recent.modules(2)] == [("diagram_b.py", "run_continuous"),
                                                           ("diagram_c.py", "run_continuous")]
    left = sorted(p.name for p in (tmp_path / "recent").iterdir())
    assert left == ["diagram_a.run_continuous", "diagram_b.run_continuous",
                    "diagram_c.run_continuous"]
    with pytest.raises(ValueError, match="limit must be 0 or more, got -1"):
        recent.modules(-1)


def test_the_warm_up_never_imports_a_persons_module_for_a_diagram_of_last_time(tmp_path):
    # a user kernel importing the person's numba helper by name: the helper's module is
    # theirs to import (when and from where they choose), so that diagram is not loaded
    from controlkit.engines.fast import recent

    (tmp_path / "controlkit_user_a.py").write_text(
        "import numpy as _np_\nfrom helper_of_theirs import nj as _f_nj  # 0123\n")
    (tmp_path / "controlkit_user_b.py").write_text("import numpy as _np_\n")
    for name, kernel in (("diagram_a", "a"), ("diagram_b", "b")):
        (tmp_path / f"{name}.py").write_text(
            f"import numpy as np\nfrom controlkit.kernels.not_imported_yet import f\n"
            f"from controlkit_user_{kernel} import kernel as kernel_0\n")
    assert recent._imports_only_what_is_there(tmp_path / "diagram_b.py")
    assert not recent._imports_only_what_is_there(tmp_path / "diagram_a.py")
    for line in ("import numpy, helper_of_theirs\n",  # the second name of an import
                 "from json import helper_of_theirs\n"):  # a submodule of theirs, or not
        (tmp_path / "diagram_c.py").write_text(line)
        assert not recent._imports_only_what_is_there(tmp_path / "diagram_c.py")
    (tmp_path / "diagram_c.py").write_text("from json import dumps\nimport numpy, sys\n")
    assert recent._imports_only_what_is_there(tmp_path / "diagram_c.py")
    assert recent.load(tmp_path / "diagram_a.py", "run_continuous") is False
    assert "helper_of_theirs" not in sys.modules and "controlkit_user_a" not in sys.modules


def _unloaded_kernel(t, x, u, p, out):
    """A kernel whose entry no test loads (a module-level function, as entries need)."""
    out[0] = x[0]
    return out


def test_a_call_never_waits_on_a_background_load_that_waits_for_a_quiet_moment():
    # the background waits while a module is being imported (the person's `import study`
    # that runs a diagram): it must not hold the engine's import lock meanwhile, or the
    # call in that import waits for it (20 s, the quiet wait's limit)
    import threading
    import time
    from importlib import _bootstrap

    import numba

    from controlkit._quiet import IMPORTING
    from controlkit.engines.fast import entries, loader

    kernel = numba.njit(_unloaded_kernel)
    globals()["_unloaded_kernel_jit"] = kernel  # importable by name, as entries need
    kernel.py_func.__name__ = "_unloaded_kernel_jit"
    done = threading.Event()

    def preload():
        entries.preload([kernel], loader.cache_folder())
        done.set()

    with _bootstrap._ModuleLockManager("a_module_being_imported"):
        worker = threading.Thread(target=preload, daemon=True)
        worker.start()
        time.sleep(0.2)  # it now waits for a quiet moment
        assert not done.is_set()
        assert IMPORTING.acquire(timeout=10)  # free: the call's import goes on
        IMPORTING.release()
    worker.join(30)
    assert done.is_set()


def test_the_modules_the_engine_writes_run_under_its_import_lock(tmp_path):
    # another thread (the warm-up) finds them in sys.modules only once they are whole
    from controlkit._quiet import IMPORTING
    from controlkit.engines.fast import loader
    from controlkit.engines.fast.usercode import compiling

    text = ("from controlkit._quiet import IMPORTING as _lock\n"
            "OWNED = _lock._is_owned()\n\n\n"
            "def kernel(t, x, u, p, out):\n    return out\n")
    path = loader.module_path(text + "# diagram\n")
    assert loader.import_module(path).OWNED is True
    user = tmp_path / "controlkit_user_owned.py"
    user.write_text(text)
    assert compiling.import_user_module(user).OWNED is True
    assert not IMPORTING._is_owned()


def test_a_quiet_moment_waits_for_a_thread_making_numbas_context():
    # numba makes its target context holding that property's lock, then takes the
    # compiler lock; a background step holding the compiler lock must not then wait for
    # the property's lock (a deadlock of the person's first numba call)
    import threading
    import time

    from numba.core.compiler_lock import global_compiler_lock
    from numba.core.registry import CPUTarget

    from controlkit._quiet import alone

    making = vars(CPUTarget)["_toplevel_target_context"]._lock
    got = {}
    holding = threading.Event()

    def first_numba_call():  # numba's own order: the context's lock, then the compiler's
        with making:
            holding.set()
            time.sleep(0.2)
            got["compiler lock"] = global_compiler_lock._lock.acquire(timeout=5)
            if got["compiler lock"]:
                global_compiler_lock._lock.release()

    person = threading.Thread(target=first_numba_call)
    person.start()
    assert holding.wait(60)  # the person's thread holds the context's lock
    with alone(global_compiler_lock) as quiet:
        got["context lock"] = making.acquire(timeout=5)  # what refresh() then asks for
        if got["context lock"]:
            making.release()
    person.join()
    assert quiet and got == {"compiler lock": True, "context lock": True}
