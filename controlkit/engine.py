"""Fast simulation of discrete interconnects of controlkit blocks.

python-control steps an interconnect by sweeping every block's output
function until the signals stop changing, twice per step (for the outputs
and for the update). For a diagram of controlkit blocks the order in which
outputs can be computed is known in advance: blocks whose output reads only
their state first, then the feedthrough blocks in dependency order. This
module writes that order out as one plain loop over time, with the
zero-order-hold Runge-Kutta steps of sampled blocks inlined, and compiles the
loop with numba when it is installed (cached on disk, see :data:`CACHE_DIR`).
The kernels called are the blocks' own, so the result equals
``control.input_output_response`` on the same system.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import sys as pysys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import control as ct
import numpy as np

from . import _checks, _jit, _usercode
from ._block import BlockKernels
from .kernels import common, lti
from .simulation import check_arguments, chunk_bounds, response

#: Where generated simulation loops are written (and numba caches them).
CACHE_DIR = Path(os.environ.get("CONTROLKIT_CACHE_DIR",
                                Path.home() / ".cache" / "controlkit" / "engine"))


class UnsupportedSystem(ValueError):
    """The fast engine cannot run this system (the message names the block and why).

    Examples
    --------
    >>> from controlkit.blocks.spacecraft import spacecraft_plant
    >>> try:
    ...     compile_system(spacecraft_plant())
    ... except UnsupportedSystem as reason:
    ...     print(reason)
    'plant' is a single block; the fast engine runs interconnects
    """


@dataclass(frozen=True)
class _Block:
    index: int
    system: object
    kernel: object
    x0: int  # state offset
    u0: int  # offset in the list of all subsystem inputs
    y0: int  # offset in the list of all subsystem outputs
    p0: int  # parameter offset
    tier: str = "compiled"
    reason: str = ""


#: The tiers a block can get, fastest first (see :func:`explain`).
TIERS = ("compiled", "python", "python-control")


class BlockTier(NamedTuple):
    """How the fast engine runs one block: ``tier`` is one of :data:`TIERS`.

    Examples
    --------
    >>> row = BlockTier("pi", "compiled", "LTI block (state space)")
    >>> row.tier
    'compiled'
    """

    name: str
    tier: str
    reason: str


def _local_params(sys, block, params):
    """The parameters python-control hands ``block`` inside ``sys`` (see its _update_params)."""
    local = dict(block.params)
    local.update(sys.params)
    if params:
        local.update(params)
    return local


def _probe_feedthrough(output, nx, nu, ny, on_error=True):
    """Whether ``output(t, x, u, out)`` moves with ``u`` at random trial points
    (``on_error`` where the output cannot be evaluated there)."""
    if nu == 0 or ny == 0:
        return False
    rng = np.random.default_rng(1)
    for _ in range(3):
        x = rng.uniform(-1, 1, nx)
        u = rng.uniform(-1, 1, nu)
        try:
            a = np.array(output(0.0, x, np.zeros(nu), np.empty(ny)), dtype=float)
            b = np.array(output(0.0, x, u, np.empty(ny)), dtype=float)
        except Exception:  # undefined at this point
            return on_error
        if not np.array_equal(a, b, equal_nan=True):
            return True
    return False


def _python_kernels(block, local, reason):
    """Kernels calling ``block``'s own functions from Python, inside the engine's loop."""
    if isinstance(block, ct.InterconnectedSystem):  # a nested diagram: its own sweeps
        def output(t, x, u, p, out):
            block._update_params(local)
            out[:] = block._out(t, x, u)
            return out

        def update(t, x, u, p, out):
            block._update_params(local)
            out[:] = block._rhs(t, x, u)
            return out
        feed = None
    else:
        output = (_usercode.python_kernel(block.outfcn, local) if block.outfcn is not None
                  else common.state_output)
        update = _usercode.python_kernel(block.updfcn, local) if block.nstates else None
        feed = (_usercode.reads_input(block.outfcn) if block.outfcn is not None else False)
    if feed is None or hasattr(block, "kernel_reason"):
        feed = _probe_feedthrough(lambda t, x, u, out: output(t, x, u, None, out),
                                  block.nstates, block.ninputs, block.noutputs)
    return BlockKernels(output, update, np.zeros(0), feed), "python", reason


def _user_kernels(block, local):
    """A user's ``nlsys``: compiled with its parameters frozen, else called from Python."""
    if isinstance(block, ct.InterconnectedSystem) or hasattr(block, "kernel_reason"):
        reason = getattr(block, "kernel_reason", "a nested interconnect")
        return _python_kernels(block, local, reason)
    folder = _cache_folder()
    try:
        output = common.state_output
        if block.outfcn is not None:
            output, _ = _usercode.compiled_kernel(block.outfcn, local, folder, block.noutputs,
                                                  block.nstates, block.ninputs)
        update = None
        if block.nstates:
            update, _ = _usercode.compiled_kernel(block.updfcn, local, folder, block.nstates,
                                                  block.nstates, block.ninputs)
    except _usercode.NotCompilable as why:
        return _python_kernels(block, local, f"user function not compiled: {why}")
    feed = _usercode.reads_input(block.outfcn) if block.outfcn is not None else False
    if feed is None:
        feed = True
    return (BlockKernels(output, update, np.zeros(0), feed), "compiled",
            "user nlsys compiled with its parameters frozen")


def _resolve(sys, block, params):
    """``(BlockKernels, tier, reason)`` for one block of ``sys``."""
    kernel = getattr(block, "kernels", None)
    if kernel is not None:
        _check_feedthrough(block, kernel)
        return kernel, "compiled", "controlkit block"
    local = _local_params(sys, block, params)
    if isinstance(block, ct.StateSpace):  # also a transfer function, converted by interconnect
        D = np.asarray(block.D, dtype=float)
        return (BlockKernels(lti.lti_output, lti.lti_update if block.nstates else None,
                             lti.pack(block.A, block.B, block.C, D), bool(D.any())),
                "compiled", "LTI block (state space)")
    sampling = getattr(block, "sampling", None)
    continuous = getattr(block, "continuous", None)
    if sampling is not None and continuous is not None:
        if sampling["method"] != "rk4":
            return _python_kernels(block, local, "sampled with solve_ivp")
        inner = dict(continuous.params)
        inner.update(local)
        kernel, tier, reason = _resolve(sys, continuous, None) if getattr(
            continuous, "kernels", None) is not None else _user_kernels(continuous, inner)
        return (kernel.sampled(block.dt, sampling["substeps"]), tier,
                f"{reason}, sampled by RK4")
    if isinstance(block, ct.NonlinearIOSystem):
        return _user_kernels(block, local)
    raise UnsupportedSystem(f"block {block.name!r} cannot be compiled: "
                            f"a {type(block).__name__}, not an I/O system the engine knows")


def _check_feedthrough(block, kernel):
    """Refuse a block declared without feedthrough whose output moves with its input."""
    if kernel.feedthrough or not block.ninputs or not block.noutputs:
        return
    p = kernel.params
    if _probe_feedthrough(lambda t, x, u, out: kernel.output(t, x, u, p, out),
                          block.nstates, block.ninputs, block.noutputs, on_error=False):
        raise ValueError(
            f"block {block.name!r} is declared without feedthrough (feedthrough=False) but "
            f"its output changes with its input; declare feedthrough=True")


def _blocks(sys, params=None):
    if not isinstance(sys, ct.InterconnectedSystem):
        name = getattr(sys, "name", type(sys).__name__)
        raise UnsupportedSystem(
            f"{name!r} is a single block; the fast engine runs interconnects")
    if not sys.isdtime(strict=True):
        raise UnsupportedSystem(
            f"{sys.name!r} is continuous time (dt = {sys.dt}); sample its continuous blocks "
            f"with controlkit.sampling.sample_nlsys so that the diagram is discrete")
    blocks, xs, us, ys, ps = [], 0, 0, 0, 0
    for i, block in enumerate(sys.syslist):
        kernel, tier, reason = _resolve(sys, block, params)
        if kernel.update is not None and kernel.rk4 is None and not block.isdtime(strict=True):
            raise UnsupportedSystem(f"block {block.name!r} is continuous and not sampled")
        blocks.append(_Block(i, block, kernel, xs, us, ys, ps, tier, reason))
        xs += block.nstates
        us += block.ninputs
        ys += block.noutputs
        ps += kernel.params.size
    return blocks


def _params_read(block):
    """The parameter names ``block`` reads, or None where that cannot be known."""
    if getattr(block, "kernels", None) is not None or isinstance(block, ct.StateSpace):
        return set()  # controlkit blocks take theirs when built; LTI blocks have none
    if isinstance(block, ct.InterconnectedSystem):
        keys = set(block.params)
        for sub in block.syslist:
            more = _params_read(sub)
            if more is None:
                return None
            keys |= more
        return keys
    continuous = getattr(block, "continuous", None)
    if continuous is not None:
        inner = _params_read(continuous)
        return None if inner is None else inner | set(block.params)
    if hasattr(block, "kernel_reason"):
        return set()
    keys = set(block.params)
    for fn in (block.updfcn, block.outfcn):
        if fn is not None:
            more = _usercode.used_params(fn)
            if more is None:
                return None
            keys |= more
    return keys


def check_params(sys, params):
    """Refuse ``params`` keys that no block of ``sys`` reads (python-control ignores them).

    Raises
    ------
    ValueError
        Naming the unknown keys and the ones the blocks read.

    Examples
    --------
    >>> import control as ct
    >>> gain = ct.nlsys(None, lambda t, x, u, params: params["k"] * u, inputs=1, outputs=1,
    ...                 params={"k": 2.0}, name="gain")
    >>> check_params(gain, {"k": 3.0})
    >>> try:
    ...     check_params(gain, {"K": 3.0})
    ... except ValueError as error:
    ...     print(error)  # doctest: +NORMALIZE_WHITESPACE
    params ['K'] are read by no block of 'gain' (they read ['k']); controlkit's own
    blocks take their parameters when they are built, e.g. outer_controller(F=...)
    """
    if not params:
        return
    if not isinstance(params, dict):
        raise ValueError(f"params must be a dict of parameter values, got "
                         f"{type(params).__name__}")
    keys = _params_read(sys)
    if keys is None:  # a function without source: python-control's own behaviour
        return
    unknown = sorted(set(params) - keys)
    if unknown:
        raise ValueError(
            f"params {unknown} are read by no block of {sys.name!r} (they read "
            f"{sorted(keys)}); controlkit's own blocks take their parameters when they are "
            f"built, e.g. outer_controller(F=...)")


def explain(sys, params=None) -> list[BlockTier]:
    """How the fast engine runs each block of ``sys``: its tier and the reason.

    Tiers (:data:`TIERS`): ``"compiled"`` (numba, in the generated loop),
    ``"python"`` (the block's own Python function called from the generated
    loop: no python-control sweeps, but slower) and ``"python-control"``
    (the whole diagram falls back to :func:`control.input_output_response`;
    the reason says why).

    Parameters
    ----------
    sys : control.InterconnectedSystem
        The diagram.
    params : dict, optional
        Parameters as for :func:`controlkit.simulation.simulate` (they decide
        the values frozen into compiled user functions).

    Returns
    -------
    list of BlockTier
        ``(name, tier, reason)`` per block, in ``sys.syslist`` order.

    Examples
    --------
    >>> import control as ct
    >>> pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi",
    ...                       inputs="e", outputs="u")
    >>> plant = ct.nlsys(lambda t, x, u, p: x + 0.1 * (u - p.get("a", 1.0) * x ** 3),
    ...                  lambda t, x, u, p: x, inputs="u", outputs="y", states=1,
    ...                  dt=0.1, name="plant")
    >>> error = ct.summing_junction(["r", "-y"], "e", name="error")
    >>> loop = ct.interconnect([plant, pi, error], inputs="r", outputs="y")
    >>> for row in explain(loop):
    ...     print(row.name, "|", row.tier, "|", row.reason)
    plant | compiled | user nlsys compiled with its parameters frozen
    pi | compiled | LTI block (state space)
    error | compiled | LTI block (state space)
    """
    try:
        blocks = _blocks(sys, params)
        _evaluation_order(sys, blocks)
    except UnsupportedSystem as why:
        return [BlockTier(s.name, "python-control", str(why))
                for s in getattr(sys, "syslist", [sys])]
    note = "" if _jit.HAVE_NUMBA else " (numba not installed: the loop runs as Python)"
    return [BlockTier(b.system.name, b.tier, b.reason + note) for b in blocks]


def _evaluation_order(sys, blocks):
    """State-only outputs first, then feedthrough blocks in dependency order."""
    owner = np.empty(sum(b.system.noutputs for b in blocks), dtype=int)
    for b in blocks:
        owner[b.y0:b.y0 + b.system.noutputs] = b.index
    needs = {}
    for b in blocks:
        rows = sys.connect_map[b.u0:b.u0 + b.system.ninputs]
        needs[b.index] = {int(owner[j]) for j in np.nonzero(rows.any(axis=0))[0]}
    order = [b.index for b in blocks if not b.kernel.feedthrough]
    done = set(order)
    pending = [b.index for b in blocks if b.kernel.feedthrough]
    while pending:
        ready = [i for i in pending if needs[i] <= done]
        if not ready:
            names = [sys.syslist[i].name for i in pending]
            raise UnsupportedSystem(f"algebraic loop through blocks {names}")
        for i in ready:
            order.append(i)
            done.add(i)
            pending.remove(i)
    return order


def _gather(target, row_map, input_row):
    """Source lines computing ``target[i]`` from subsystem outputs and external inputs."""
    lines = []
    for i, (row, ext) in enumerate(zip(row_map, input_row, strict=True)):
        terms = [f"ys[{j}]" if g == 1.0 else f"{g!r} * ys[{j}]" for j, g in
                 ((j, row[j]) for j in np.nonzero(row)[0])]
        terms += [f"u[{j}]" if g == 1.0 else f"{g!r} * u[{j}]" for j, g in
                  ((j, ext[j]) for j in np.nonzero(ext)[0])]
        lines.append(f"{target}[{i}] = " + (" + ".join(terms) if terms else "0.0"))
    return lines


def _gather_inputs(sys, b):
    """Source lines filling block ``b``'s input buffer from the interconnect's maps."""
    rows = slice(b.u0, b.u0 + b.system.ninputs)
    return _gather(f"ui_{b.index}", sys.connect_map[rows], sys.input_map[rows])


def _function_ref(function):
    py = _jit.python_function(function)
    return py.__module__, py.__name__


def _generate(sys, blocks, order):
    """The loop's source and the kernels it must be handed (those not importable)."""
    imports, names, injected = {}, {}, {}
    for b in blocks:
        for role, fn in (("out", b.kernel.output), ("upd", b.kernel.update)):
            if fn is None:
                continue
            alias = f"{role}_{b.index}"
            names[(role, b.index)] = alias
            module, name = _function_ref(fn)
            if "<" in name or module is None or module == "__main__" or "<" in getattr(
                    _jit.python_function(fn), "__qualname__", "<"):
                if b.tier != "python":
                    raise UnsupportedSystem(
                        f"block {b.system.name!r}: its kernel {name} is not importable")
                injected[alias] = fn
                continue
            imports[alias] = (module, name)
    nsub_out = sys.connect_map.shape[1]
    # buffers live outside the time loop: allocation is what a compiled step costs
    setup = ["x = X0.copy()", f"xn = np.empty({sys.nstates})", f"ys = np.zeros({nsub_out})"]
    setup += [f"ui_{b.index} = np.zeros({b.system.ninputs})" for b in blocks]
    for b in blocks:
        if b.kernel.rk4 is not None and b.system.nstates:
            n = b.system.nstates
            setup += [f"xs_{b.index} = np.empty({n})",
                      f"work_{b.index} = ({', '.join([f'np.empty({n})'] * 5)})"]
    if any(b.kernel.rk4 is not None for b in blocks):
        imports["rk4_step"] = (common.__name__, "rk4_step")
    L = [
        "# generated by controlkit.engine: do not edit",
        "import numpy as np",
        *[f"from {m} import {n} as {a}" for a, (m, n) in sorted(imports.items())],
        "",
        "",
        "def run(T, X0, U, P, Y, X, status, k0, k1):",
        "    # steps k0..k1-1; returns the state at k1",
        *["    " + line for line in setup],
        "    for k in range(k0, k1):",
        "        t = T[k]",
        "        u = U[:, k]",
        "        X[:, k] = x",
    ]
    body = []
    for i in order:
        b = blocks[i]
        s = b.system
        body.append(f"# {s.name}: output")
        if b.kernel.feedthrough:  # otherwise the output reads the state only
            body += _gather_inputs(sys, b)
        body.append(f"{names[('out', i)]}(t, x[{b.x0}:{b.x0 + s.nstates}], ui_{i}, "
                    f"P[{b.p0}:{b.p0 + b.kernel.params.size}], ys[{b.y0}:{b.y0 + s.noutputs}])")
        if s.noutputs:
            body.append(f"if np.isnan(ys[{b.y0}]):")
            body.append(f"    status[0] = k\n    status[1] = {i}\n    return x")
    # inputs of state-only blocks, now that every output is known
    for b in blocks:
        if not b.kernel.feedthrough:
            body += _gather_inputs(sys, b)
    # system outputs: output_map over [subsystem outputs, subsystem inputs]
    for r, row in enumerate(sys.output_map):
        terms = []
        for j in np.nonzero(row)[0]:
            g = row[j]
            if j < nsub_out:
                ref = f"ys[{j}]"
            else:
                owner = next(b for b in blocks
                             if b.u0 <= j - nsub_out < b.u0 + b.system.ninputs)
                ref = f"ui_{owner.index}[{j - nsub_out - owner.u0}]"
            terms.append(ref if g == 1.0 else f"{g!r} * {ref}")
        body.append(f"Y[{r}, k] = " + (" + ".join(terms) if terms else "0.0"))
    for b in blocks:
        s = b.system
        if b.kernel.update is None or s.nstates == 0:
            continue
        sl = f"{b.x0}:{b.x0 + s.nstates}"
        p = f"P[{b.p0}:{b.p0 + b.kernel.params.size}]"
        f = names[("upd", b.index)]
        if b.kernel.rk4 is None:
            body.append(f"{f}(t, x[{sl}], ui_{b.index}, {p}, xn[{sl}])")
            continue
        Ts, n = b.kernel.rk4
        # kernels.common.rk4_step, as sample_nlsys calls it; numba inlines it (no allocation)
        body += [
            f"xs_{b.index}[:] = x[{sl}]",
            f"h = {Ts!r} / {n}",
            f"for i in range({n}):",
            f"    rk4_step({f}, t + i * h, xs_{b.index}, ui_{b.index}, {p}, h, "
            f"work_{b.index}, xs_{b.index})",
            f"xn[{sl}] = xs_{b.index}",
        ]
    body.append("x[:] = xn")
    L += ["        " + line for chunk in body for line in chunk.split("\n")]
    L.append("    return x")
    return "\n".join(L) + "\n", injected


#: Loops loaded in this process, by generated source (the kernels imported here are fixed).
_LOADED: dict[str, object] = {}


def _cache_folder() -> Path:
    """:data:`CACHE_DIR`, or a temporary folder when it cannot be written."""
    folder = CACHE_DIR
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # a read-only home: keep the loops for this machine's session only
        folder = Path(tempfile.gettempdir()) / "controlkit-engine"
        folder.mkdir(parents=True, exist_ok=True)
    return folder


#: A diagram's loop that is not compiled yet (neither in this process nor in the disk cache)
#: runs as plain Python, calling the compiled kernels, for its first this-many steps in a
#: process: compiling a loop costs 1-3 s, the Python loop 5-40 us a step (measured in
#: benchmarks/bench_user_diagrams.py), so short exploratory runs of a newly wired diagram
#: start at once and the loop is compiled once the runs grow long.
COMPILE_AFTER_STEPS = 50_000

#: Steps run as Python so far, per loop source (see :data:`COMPILE_AFTER_STEPS`).
_PYTHON_STEPS: dict[str, int] = {}


def _python_loop(source: str, injected=None):
    """The generated loop run as plain Python, calling the (compiled) kernels it imports.

    The RK4 helper is swapped for its Python version: handed a kernel from Python, numba
    would compile a new, uncacheable specialisation of it for every kernel.
    """
    namespace = {}
    exec(compile(source, "<controlkit loop>", "exec"), namespace)
    namespace.update(injected or {})
    if "rk4_step" in namespace:
        namespace["rk4_step"] = _jit.python_function(common.rk4_step)
    return namespace["run"]


def _load(source: str, injected=None, steps=None):
    if injected:  # Python kernels in the loop: run it as plain Python, handed those kernels
        return _python_loop(source, injected)
    if source in _LOADED:  # no need to read and hash the kernels' files again
        return _LOADED[source]
    # numba caches the loop with the kernels inlined but keys on the loop's file alone:
    # the kernels' source goes into the file name so that editing them recompiles
    folder = _cache_folder()
    if str(folder) not in pysys.path:  # compiled user kernels are modules there
        pysys.path.append(str(folder))
    modules = sorted({line.split()[1] for line in source.splitlines()
                      if line.startswith("from ")})
    kernel_sources = "".join(Path(importlib.util.find_spec(m).origin).read_text()
                             for m in modules)
    key = hashlib.sha256((source + kernel_sources + str(_jit.HAVE_NUMBA)
                          + str(_jit.CACHE_FORMAT)).encode()).hexdigest()[:20]
    path = folder / f"loop_{key}.py"
    if not path.exists():  # keep the file's date: numba's cache keys on it
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(source)
        os.replace(tmp, path)
    spec = importlib.util.spec_from_file_location(f"controlkit_loop_{key}", path)
    module = importlib.util.module_from_spec(spec)
    pysys.modules[spec.name] = module  # numba's disk cache re-imports it by name
    spec.loader.exec_module(module)
    run = module.run
    if _jit.HAVE_NUMBA:
        run = _jit.numba.njit(cache=True)(run)  # compiled or loaded at its first call
        if steps is not None and not _in_disk_cache(run) \
                and _PYTHON_STEPS.get(source, 0) + steps < COMPILE_AFTER_STEPS:
            _PYTHON_STEPS[source] = _PYTHON_STEPS.get(source, 0) + steps
            return _python_loop(source)
    _LOADED[source] = run
    return run


def _in_disk_cache(dispatcher) -> bool:
    """Whether numba's disk cache holds compiled code of ``dispatcher``'s function.

    Asked of numba's own cache object, which knows where the index is (next to the loop's
    file, or under ``NUMBA_CACHE_DIR`` when that is set: looking only next to the file,
    every run with ``NUMBA_CACHE_DIR`` ran the CMG loop as Python, 0.3 s slower).
    """
    try:
        return os.path.exists(dispatcher._cache._cache_file._index_path)
    except AttributeError:  # another numba's internals: compile, as for a long run
        return True


def compile_system(sys, params=None, *, steps=None):
    """Generate (and compile, with numba) the simulation loop of an interconnect.

    With ``steps`` (the length of the run it is for), a loop not compiled yet runs as
    Python while the runs are short (:data:`COMPILE_AFTER_STEPS`).

    Raises
    ------
    UnsupportedSystem
        Naming the block that has no kernel, or the algebraic loop.

    Returns
    -------
    run : callable
        ``run(T, X0, U, P, Y, X, status, k0, k1) -> state at k1``.
    blocks : list
        The blocks with their offsets in the stacked state, signals and parameters.

    Examples
    --------
    >>> from controlkit.diagrams.cmg import cmg_loop
    >>> run, blocks = compile_system(cmg_loop())
    >>> [b.system.name for b in blocks]
    ['reference', 'cmg', 'smc', 'saturation']
    """
    blocks = _blocks(sys, params)
    order = _evaluation_order(sys, blocks)
    return _load(*_generate(sys, blocks, order), steps=steps), blocks


#: Steps simulated per chunk when a run is streamed (bounds the memory of long runs).
STREAM_CHUNK_STEPS = 20_000


def recorded_indices(N: int, record_every: int) -> np.ndarray:
    """Indices kept when every ``record_every``-th of ``N`` samples is recorded (and the last).

    Examples
    --------
    >>> recorded_indices(10, 4).tolist()
    [0, 4, 8, 9]
    """
    if isinstance(record_every, bool) or not isinstance(record_every, int | np.integer) \
            or record_every < 1:
        raise ValueError(f"record_every must be an integer >= 1, got {record_every!r}")
    kept = np.arange(0, N, int(record_every))
    return kept if N == 0 or kept[-1] == N - 1 else np.append(kept, N - 1)


def simulate_fast(sys, T, X0, U=0.0, *, params=None, progress=None, chunks=1,
                  record_every=1, on_chunk=None) -> ct.TimeResponseData:
    """Simulate a discrete interconnect of controlkit blocks without python-control's sweeps.

    Same arguments and result as :func:`control.input_output_response` for
    a discrete system (plus ``progress``, ``chunks``, ``record_every`` and
    ``on_chunk`` as in :func:`controlkit.simulation.simulate`). With
    ``record_every > 1`` or ``on_chunk`` the run is streamed: it proceeds in
    chunks of :data:`STREAM_CHUNK_STEPS` steps through fixed buffers, so memory
    does not grow with the horizon.

    Raises
    ------
    UnsupportedSystem
        When a block cannot be compiled (use the python-control path instead).

    Examples
    --------
    >>> from controlkit.scenarios.spacecraft import build_loop, initial_attitude
    >>> from controlkit.simulation import initial_state
    >>> loop = build_loop("ideal")
    >>> X0 = initial_state(loop, plant=initial_attitude())
    >>> resp = simulate_fast(loop, np.arange(3) * 0.1, X0)
    >>> resp.outputs.shape
    (10, 3)
    """
    T, X0, U = check_arguments(sys, T, X0, U)  # a lazy TimeGrid stays lazy, U a view
    run, blocks = compile_system(sys, params, steps=T.size)
    streamed = record_every != 1 or on_chunk is not None
    if not streamed:
        T = np.ascontiguousarray(T, dtype=float)
    N = T.size
    P = np.concatenate([b.kernel.params for b in blocks] + [np.zeros(0)])
    kept = recorded_indices(N, record_every)
    if streamed:
        return _stream(sys, run, blocks, T, X0, U, P, kept, on_chunk, progress, params)
    U = np.ascontiguousarray(U)
    Y = np.zeros((sys.noutputs, N))
    X = np.zeros((sys.nstates, N))
    status = np.array([-1, -1])
    bounds = chunk_bounds(N, chunks)
    x = X0
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        x = run(T, x, U, P, Y, X, status, k0, k1)
        if status[0] >= 0:
            _explain_failure(sys, blocks, T, X, U, status, params)
        if not np.isfinite(x).all():
            _explain_divergence(sys, blocks, T, X, x, k1, U, params)
        if progress is not None:
            progress(k1 / N)
    return response(sys, T, Y, X, U)


def _explain_divergence(sys, blocks, T, X, x, k1, U, params=None):
    """A state became non-finite: a sampled block that blew up inside its sample says so
    (as on the python-control path), otherwise the loop diverged."""
    bad = ~np.isfinite(np.column_stack([X[:, :k1], x]))
    k = int(np.argmax(bad.any(axis=0)))
    i = int(np.argmax(bad[:, k]))
    b = next(b for b in blocks if b.x0 <= i < b.x0 + b.system.nstates)
    if k >= 1 and b.kernel.rk4 is not None and np.isfinite(X[:, k - 1]).all():
        # the Python step of that sample, with its blow-up test (raises SamplingError)
        sys._update_params(params)
        try:
            ulist, _ = sys._compute_static_io(T[k - 1], X[:, k - 1], U[:, k - 1])
        except RuntimeError:
            ulist = None
        if ulist is not None and np.isfinite(ulist).all():
            s = b.system
            with np.errstate(all="ignore"):
                s._rhs(T[k - 1], X[b.x0:b.x0 + s.nstates, k - 1], ulist[b.u0:b.u0 + s.ninputs])
    t = T[k] if k < len(T) else T[-1] + (T[-1] - T[-2] if len(T) > 1 else 0.0)
    raise _checks.diverged(t, f"the state of block {b.system.name!r} became non-finite")


def _stream(sys, run, blocks, T, x, U, P, kept, on_chunk, progress, params=None):
    """Run the compiled loop chunk by chunk on slices of ``T`` and ``U``; keep ``kept`` only.

    The generated loop indexes its arrays from ``k0``, so each chunk runs on views of
    ``T`` and ``U`` with ``k0 = 0`` into buffers reused from chunk to chunk.
    """
    N = T.size
    step = min(STREAM_CHUNK_STEPS, max(N, 1))
    Yb, Xb = np.zeros((sys.noutputs, step)), np.zeros((sys.nstates, step))
    Y, X = np.zeros((sys.noutputs, kept.size)), np.zeros((sys.nstates, kept.size))
    status = np.array([-1, -1])
    for k0 in range(0, N, step):
        k1 = min(N, k0 + step)
        Tc, Uc = T[k0:k1], np.ascontiguousarray(U[:, k0:k1])
        x = run(Tc, x, Uc, P, Yb, Xb, status, 0, k1 - k0)
        if status[0] >= 0:
            _explain_failure(sys, blocks, Tc, Xb, Uc, status, params)
        if not np.isfinite(x).all():
            _explain_divergence(sys, blocks, Tc, Xb, x, k1 - k0, Uc, params)
        if on_chunk is not None:
            on_chunk(Tc, Yb[:, :k1 - k0], Xb[:, :k1 - k0])
        mine = (kept >= k0) & (kept < k1)
        Y[:, mine] = Yb[:, kept[mine] - k0]
        X[:, mine] = Xb[:, kept[mine] - k0]
        if progress is not None:
            progress(k1 / N)
    return response(sys, T[kept], Y, X, U[:, kept])


def _explain_failure(sys, blocks, T, X, U, status, params=None):
    """A kernel returned NaN: let the block's Python wrapper say why, in its own words."""
    k = int(status[0])
    b = blocks[int(status[1])]
    block = b.system
    sys._update_params(params)
    try:
        ulist, _ = sys._compute_static_io(T[k], X[:, k], U[:, k])
    except RuntimeError:  # python-control's sweep cannot settle on non-finite signals
        ulist = None
    if ulist is not None:
        block.output(T[k], X[b.x0:b.x0 + block.nstates, k], ulist[b.u0:b.u0 + block.ninputs])
    if not np.isfinite(X[:, k]).all():  # the loop diverged before the block's output did
        _explain_divergence(sys, blocks, T, X, X[:, k], k, U, params)
    raise FloatingPointError(f"block {block.name!r} returned NaN at t = {T[k]:g} s")
