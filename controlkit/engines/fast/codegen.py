"""A diagram's own module: its evaluator written out line by line, kernels pasted in.

python-control steps an interconnect by sweeping every block's output function until
the signals stop changing. For a diagram whose blocks declare their feedthrough the
order in which outputs can be computed is known in advance (:func:`evaluation_order`):
blocks whose output reads only their state first, then the feedthrough blocks in
dependency order. :func:`generate` writes that order out as the four functions of an
evaluator (:mod:`.loops`) with every index a literal and every kernel pasted in by numba
(``inline="always"``), and two entry points that hand them to the loops of
:mod:`.loops`. The module is compiled per wiring (a second or two) and cached on disk;
the parameters stay values at run time (``P``), so a new value never recompiles.
"""

from __future__ import annotations

import numpy as np

from ... import _jit
from ..contract import UnsupportedSystem
from .plan import CONTINUOUS, DISCRETE, SAMPLED


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



def _terms(ptr, cols, gain, r, name):
    terms = []
    for q in range(ptr[r], ptr[r + 1]):
        g, ref = gain[q], name(cols[q])
        terms.append(ref if g == 1.0 else f"{g!r} * {ref}")
    return " + ".join(terms) if terms else "0.0"


def _kernel_names(plan):
    """``(alias per kernel index, import lines, kernels to inject)`` of a plan's kernels."""
    aliases, imports, injected = [], [], {}
    for i, fn in enumerate(plan.kernels):
        py = _jit.python_function(fn)
        module, name = getattr(py, "__module__", None), getattr(py, "__name__", "<?>")
        alias = f"kernel_{i}"
        aliases.append(alias)
        importable = (module not in (None, "__main__") and "<" not in name
                      and "<" not in getattr(py, "__qualname__", "<")
                      and hasattr(fn, "py_func"))
        if importable:
            imports.append((module, name, alias))
        else:  # a Python function (python tier): handed to the module when it is run
            injected[alias] = fn
    return aliases, imports, injected


def generate(plan, held_logic):
    """The source of ``plan``'s module, and the kernels it must be handed (not importable).

    The functions are plain Python: :mod:`.loader` compiles them (and pastes the
    kernels in) or runs them as Python (a diagram with a block on the python tier).

    ``held_logic``: whether discrete blocks hold their outputs between their instants (a
    diagram of several rates or with continuous states); without it every block fires
    at every step, as in python-control's discrete simulation.

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> source, injected = generate(prepare(cmg_loop()).plan, held_logic=False)
    >>> [line for line in source.splitlines() if line.startswith("def run")], injected
    (['def run_discrete(T, X0, U, P, Y, X, status, k0, k1):'], {})
    """
    rows, ny = plan.rows(), plan.ny
    names, imports, injected = _kernel_names(plan)
    ptr, cols, gain = plan.inputs

    def gather(b):
        return [f"ui[{r}] = " + _terms(ptr, cols, gain, r, lambda c: f"ys[{c}]" if c < ny
                                       else f"U[{c - ny}, col]")
                for r in range(rows[b].U0, rows[b].U0 + rows[b].NU)]

    def view(array, start, size):
        # a slice, not a borrowed view (.views): numba's dead-store elimination once
        # dropped a pasted-in kernel's writes into a borrowed view (seen with the CMG's
        # reference generator, whose kernel indexes through a layout held in a local)
        return f"{array}[{start}:{start + size}]"

    def args(b, out, size):
        row = rows[b]
        return (f"{view('x', row.X0, row.NX)}, {view('ui', row.U0, row.NU)}, "
                f"{view('P', row.P0, row.NP)}, {view(out[0], out[1], size)}")

    evaluate = []
    for b in plan.order:
        row = rows[b]
        evaluate.append(f"# {plan.sys.syslist[b].name}")
        if row.FT:
            evaluate += gather(b)
        call = [f"{names[row.OUT]}(t, {args(b, ('ys', row.Y0), row.NY)})"]
        if row.NY:
            call += [f"if np.isnan(ys[{row.Y0}]):", f"    return {b}"]
        held = row.KIND in (DISCRETE, SAMPLED) and held_logic
        if held:
            fires = "k >= 0" if row.EVERY == 1 else f"k >= 0 and k % {row.EVERY} == 0"
            evaluate += [f"if {fires}:", *["    " + c for c in call],
                         f"    for q in range({row.NY}):",
                         f"        held[{row.Y0} + q] = ys[{row.Y0} + q]",
                         "else:", f"    for q in range({row.NY}):",
                         f"        ys[{row.Y0} + q] = held[{row.Y0} + q]"]
        else:
            evaluate += call
    for b, row in enumerate(rows):
        if not row.FT:
            evaluate += gather(b)
    evaluate.append("return -1")

    optr, ocols, ogain = plan.outputs
    outputs = [f"Y[{r}, j] = " + _terms(optr, ocols, ogain, r,
                                        lambda c: f"ys[{c}]" if c < ny else f"ui[{c - ny}]")
               for r in range(plan.sys.noutputs)] or ["pass"]

    nx = plan.sys.nstates
    update = [f"for i in range({nx}):", "    xn[i] = x[i]"]
    for b, row in enumerate(rows):
        if row.UPD < 0 or not row.NX or row.KIND not in (DISCRETE, SAMPLED):
            continue
        lines = []
        if row.KIND == DISCRETE:
            lines.append(f"{names[row.UPD]}(t, {args(b, ('xn', row.X0), row.NX)})")
        else:
            n, h = row.NX, float(plan.h[b])
            work = ", ".join(view("scratch", j * n, n) for j in range(5))
            lines += [f"xs = {view('xn', row.X0, n)}", f"for i in range({row.SUB}):",
                      f"    rk4_step({names[row.UPD]}, t + i * {h!r}, xs, "
                      f"{view('ui', row.U0, row.NU)}, {view('P', row.P0, row.NP)}, "
                      f"{h!r}, ({work}), xs)"]
        if held_logic and row.EVERY > 1:
            update += [f"if k % {row.EVERY} == 0:", *["    " + line for line in lines]]
        else:
            update += lines

    derivatives = [f"{names[row.UPD]}(t, {args(b, ('dx', row.X0), row.NX)})"
                   for b, row in enumerate(rows) if row.KIND == CONTINUOUS] or ["pass"]

    widest = max([1, *(row.NX for row in rows)])
    buffers = [f"ys = np.zeros({ny})", f"ui = np.zeros({plan.nu})",
               f"xn = np.empty({nx})", f"scratch = np.empty({5 * widest})"]
    cidx = plan.continuous.tolist()

    def function(signature, lines):
        return [f"def {signature}:", *["    " + line for line in lines], "", ""]

    text = [
        "# generated by controlkit.engines.fast.codegen: a diagram's own module; do not edit",
        "import numpy as np",
        "",
        "from controlkit.engines.fast import loops, rk",
        "from controlkit.kernels.common import rk4_step",
        *[f"from {m} import {n} as {a}" for m, n, a in imports],
        "",
        "",
        *function("evaluate(t, x, U, col, P, ys, ui, held, k, plan)", evaluate),
        *function("outputs(ys, ui, Y, j, plan)", outputs),
        *function("update(t, x, ui, P, xn, k, plan, scratch)", update),
        *function("derivatives(t, x, ui, P, dx, plan)", derivatives),
        *function("rhs(t, y, args, out)",
                  ["loops.rhs_template(evaluate, derivatives, t, y, args, out)"]),
        *function("run_discrete(T, X0, U, P, Y, X, status, k0, k1)", [
            "x = X0.copy()", *buffers, f"held = np.zeros({ny})",
            "loops.discrete_run(evaluate, update, outputs, (), T, x, U, P, Y, X, status, "
            "k0, k1, ys, ui, held, xn, scratch)", "return x"]),
    ]
    if cidx or held_logic:
        text += function(
            "run_continuous(machine, instants, fire0, k0, k1, t_final, T, U, t_eval, "
            "eval_instant, ctrl, Y, X, Uo, x, held, P, method, rtol, atol, max_step, "
            "first_step, exact, status)", [
                *buffers, f"xt = np.empty({nx})", f"dx = np.zeros({nx})",
                f"cidx = np.array({cidx!r}, dtype=np.int64)",
                f"yc = np.empty({len(cidx)})", f"y_eval = np.empty((t_eval.shape[0], "
                f"{len(cidx)}))", "ubuf = np.empty((U.shape[0], 1))",
                f"work = rk.make_workspace({len(cidx)}, 0, t_eval.shape[0])",
                "args = ((), x, xt, cidx, T, U, ubuf, P, ys, ui, held, dx)",
                "loops.continuous_run(evaluate, update, outputs, rhs, machine, (), args, "
                "(instants, fire0, k0, k1, t_final, T, U, t_eval, eval_instant), "
                "(Y, X, Uo), (x, P, held), (ys, ui, xn, scratch, xt, cidx, yc, y_eval, "
                "ubuf, work), (method, rtol, atol, max_step, first_step, exact), ctrl, "
                "status)"])
    return "\n".join(text) + "\n", injected
