"""The simulation loop of a diagram, written out as Python source.

python-control steps an interconnect by sweeping every block's output function
until the signals stop changing, twice per step (for the outputs and for the
update). For a diagram whose blocks declare their feedthrough the order in which
outputs can be computed is known in advance: blocks whose output reads only their
state first, then the feedthrough blocks in dependency order. This module writes
that order out as one plain loop over time, with the zero-order-hold Runge-Kutta
steps of sampled blocks inlined (:func:`controlkit.kernels.common.rk4_step`).
"""

from __future__ import annotations

import numpy as np

from ... import _jit
from ...kernels import common
from ..contract import UnsupportedSystem


def evaluation_order(sys, blocks):
    """State-only outputs first, then feedthrough blocks in dependency order.

    Raises
    ------
    UnsupportedSystem
        Naming the blocks of an algebraic loop.

    Examples
    --------
    >>> from controlkit.engines.fast.tiers import blocks_of
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> loop = cmg_loop()
    >>> [loop.syslist[i].name for i in evaluation_order(loop, blocks_of(loop))]
    ['reference', 'cmg', 'smc', 'saturation']
    """
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


def generate(sys, blocks, order):
    """The loop's source and the kernels it must be handed (those not importable).

    Examples
    --------
    >>> from controlkit.engines.fast.tiers import blocks_of
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> loop = cmg_loop()
    >>> blocks = blocks_of(loop)
    >>> source, injected = generate(loop, blocks, evaluation_order(loop, blocks))
    >>> [line for line in source.splitlines() if line.startswith("def ")], injected
    (['def run(T, X0, U, P, Y, X, status, k0, k1):'], {})
    """
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
        "# generated by controlkit.engines.fast: do not edit",
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
