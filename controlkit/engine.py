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

import control as ct
import numpy as np

from . import _jit

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


def _blocks(sys):
    if not isinstance(sys, ct.InterconnectedSystem):
        raise UnsupportedSystem(
            f"{sys.name!r} is a single block; the fast engine runs interconnects")
    if not sys.isdtime(strict=True):
        raise UnsupportedSystem(
            f"{sys.name!r} is continuous time (dt = {sys.dt}); sample its continuous blocks "
            f"with controlkit.sampling.sample_nlsys so that the diagram is discrete")
    blocks, xs, us, ys, ps = [], 0, 0, 0, 0
    for i, block in enumerate(sys.syslist):
        kernel = getattr(block, "kernels", None)
        if kernel is None:
            reason = getattr(block, "kernel_reason", None) or "not a controlkit block"
            raise UnsupportedSystem(f"block {block.name!r} cannot be compiled: {reason}")
        if kernel.update is not None and kernel.rk4 is None and not block.isdtime(strict=True):
            raise UnsupportedSystem(f"block {block.name!r} is continuous and not sampled")
        blocks.append(_Block(i, block, kernel, xs, us, ys, ps))
        xs += block.nstates
        us += block.ninputs
        ys += block.noutputs
        ps += kernel.params.size
    return blocks


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
    py = getattr(function, "py_func", function)
    return py.__module__, py.__name__


def _generate(sys, blocks, order):
    imports, names = {}, {}
    for b in blocks:
        for role, fn in (("out", b.kernel.output), ("upd", b.kernel.update)):
            if fn is None:
                continue
            module, name = _function_ref(fn)
            if "<" in name or module is None or module == "__main__":
                raise UnsupportedSystem(
                    f"block {b.system.name!r}: its kernel {name} is not importable")
            alias = f"{role}_{b.index}"
            imports[alias] = (module, name)
            names[(role, b.index)] = alias
    nsub_out = sys.connect_map.shape[1]
    # buffers live outside the time loop: allocation is what a compiled step costs
    setup = ["x = X0.copy()", f"xn = np.empty({sys.nstates})", f"ys = np.zeros({nsub_out})"]
    setup += [f"ui_{b.index} = np.zeros({b.system.ninputs})" for b in blocks]
    for b in blocks:
        if b.kernel.rk4 is not None and b.system.nstates:
            n = b.system.nstates
            setup += [f"{name}_{b.index} = np.empty({n})"
                      for name in ("xs", "xt", "k1", "k2", "k3", "k4")]
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
        m, ui = s.nstates, f"ui_{b.index}"
        xs, xt, k1, k2, k3, k4 = (f"{name}_{b.index}"
                                  for name in ("xs", "xt", "k1", "k2", "k3", "k4"))
        # controlkit.sampling._rk4_step element by element: the same operations in the
        # same order, so the same numbers, without temporary arrays
        body += [
            f"{xs}[:] = x[{sl}]",
            f"h = {Ts!r} / {n}",
            f"for i in range({n}):",
            "    tt = t + i * h",
            f"    {f}(tt, {xs}, {ui}, {p}, {k1})",
            f"    for j in range({m}):",
            f"        {xt}[j] = {xs}[j] + (h / 2) * {k1}[j]",
            f"    {f}(tt + h / 2, {xt}, {ui}, {p}, {k2})",
            f"    for j in range({m}):",
            f"        {xt}[j] = {xs}[j] + (h / 2) * {k2}[j]",
            f"    {f}(tt + h / 2, {xt}, {ui}, {p}, {k3})",
            f"    for j in range({m}):",
            f"        {xt}[j] = {xs}[j] + h * {k3}[j]",
            f"    {f}(tt + h, {xt}, {ui}, {p}, {k4})",
            f"    for j in range({m}):",
            f"        {xs}[j] = {xs}[j] + (h / 6) * ("
            f"{k1}[j] + 2 * {k2}[j] + 2 * {k3}[j] + {k4}[j])",
            f"xn[{sl}] = {xs}",
        ]
    body.append("x[:] = xn")
    L += ["        " + line for chunk in body for line in chunk.split("\n")]
    L.append("    return x")
    return "\n".join(L) + "\n"


#: Loops loaded in this process, by generated source (the kernels imported here are fixed).
_LOADED: dict[str, object] = {}


def _load(source: str):
    if source in _LOADED:  # no need to read and hash the kernels' files again
        return _LOADED[source]
    # numba caches the loop with the kernels inlined but keys on the loop's file alone:
    # the kernels' source goes into the file name so that editing them recompiles
    modules = sorted({line.split()[1] for line in source.splitlines()
                      if line.startswith("from ")})
    kernel_sources = "".join(Path(importlib.util.find_spec(m).origin).read_text()
                             for m in modules)
    key = hashlib.sha256((source + kernel_sources + str(_jit.HAVE_NUMBA)).encode()
                         ).hexdigest()[:20]
    folder = CACHE_DIR
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:  # a read-only home: keep the loops for this machine's session only
        folder = Path(tempfile.gettempdir()) / "controlkit-engine"
        folder.mkdir(parents=True, exist_ok=True)
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
        run = _jit.numba.njit(cache=True)(run)
    _LOADED[source] = run
    return run


def compile_system(sys):
    """Generate (and compile, with numba) the simulation loop of an interconnect.

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
    blocks = _blocks(sys)
    order = _evaluation_order(sys, blocks)
    return _load(_generate(sys, blocks, order)), blocks


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


def simulate_fast(sys, T, X0, U=0.0, *, progress=None, chunks=1, record_every=1,
                  on_chunk=None) -> ct.TimeResponseData:
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
    from .sampling import TimeGrid

    run, blocks = compile_system(sys)
    streamed = record_every != 1 or on_chunk is not None
    if not (streamed and isinstance(T, TimeGrid)):  # a lazy grid stays lazy when streamed
        T = np.ascontiguousarray(T, dtype=float)
    N = T.size
    if isinstance(T, TimeGrid):
        if N > 1 and not np.isclose(T.Ts, sys.dt):
            raise ValueError(f"time steps of T must equal the sampling time {sys.dt}")
    for k0 in range(0, max(N - 1, 0) if not isinstance(T, TimeGrid) else 0,
                    STREAM_CHUNK_STEPS):  # in pieces: no copy of T
        if not np.allclose(np.diff(T[k0:k0 + STREAM_CHUNK_STEPS + 1]), sys.dt):
            raise ValueError(f"time steps of T must equal the sampling time {sys.dt}")
    U = np.asarray(U, dtype=float)
    # a view: a constant input costs no memory per step until a chunk is copied out of it
    U = np.broadcast_to(U.reshape(-1, 1) if U.ndim <= 1 else U, (sys.ninputs, N))
    X0 = np.ascontiguousarray(np.asarray(X0, dtype=float).reshape(-1))
    if X0.size != sys.nstates:
        raise ValueError(f"X0 must have {sys.nstates} values, got {X0.size}")
    P = np.concatenate([b.kernel.params for b in blocks] + [np.zeros(0)])
    kept = recorded_indices(N, record_every)
    if streamed:
        return _stream(sys, run, blocks, T, X0, U, P, kept, on_chunk, progress)
    U = np.ascontiguousarray(U)
    Y = np.zeros((sys.noutputs, N))
    X = np.zeros((sys.nstates, N))
    status = np.array([-1, -1])
    bounds = np.linspace(0, N, max(1, min(int(chunks), N)) + 1).round().astype(int)
    x = X0
    for k0, k1 in zip(bounds[:-1], bounds[1:], strict=True):
        x = run(T, x, U, P, Y, X, status, k0, k1)
        if status[0] >= 0:
            _explain_failure(sys, blocks, T, X, U, status)
        if progress is not None:
            progress(k1 / N)
    return ct.TimeResponseData(
        T, Y, X, U, output_labels=sys.output_labels, state_labels=sys.state_labels,
        input_labels=sys.input_labels, sysname=sys.name, issiso=sys.issiso(),
        title="Input/output response for " + sys.name, plot_inputs=sys.ninputs > 0,
    )


def _stream(sys, run, blocks, T, x, U, P, kept, on_chunk, progress):
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
            _explain_failure(sys, blocks, Tc, Xb, Uc, status)
        if on_chunk is not None:
            on_chunk(Tc, Yb[:, :k1 - k0], Xb[:, :k1 - k0])
        mine = (kept >= k0) & (kept < k1)
        Y[:, mine] = Yb[:, kept[mine] - k0]
        X[:, mine] = Xb[:, kept[mine] - k0]
        if progress is not None:
            progress(k1 / N)
    return ct.TimeResponseData(
        T[kept], Y, X, U[:, kept], output_labels=sys.output_labels,
        state_labels=sys.state_labels, input_labels=sys.input_labels, sysname=sys.name,
        issiso=sys.issiso(), title="Input/output response for " + sys.name,
        plot_inputs=sys.ninputs > 0,
    )


def _explain_failure(sys, blocks, T, X, U, status):
    """A kernel returned NaN: let the block's Python wrapper say why, in its own words."""
    k = int(status[0])
    b = blocks[int(status[1])]
    block = b.system
    sys._update_params(None)
    ulist, _ = sys._compute_static_io(T[k], X[:, k], U[:, k])
    block.output(T[k], X[b.x0:b.x0 + block.nstates, k], ulist[b.u0:b.u0 + block.ninputs])
    raise FloatingPointError(f"block {block.name!r} returned NaN at t = {T[k]:g} s")
