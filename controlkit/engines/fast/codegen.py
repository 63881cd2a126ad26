"""A diagram's own module: its evaluator written out line by line, kernels pasted in.

python-control sweeps every block's output until the signals settle; with declared
feedthrough the order is known in advance (:func:`.plan.evaluation_order`).
:func:`generate` writes it out as the four functions of an evaluator (:mod:`.loops`),
every index a literal, every kernel pasted in (``inline="always"``), and one entry point,
``run_discrete`` (the discrete loop pasted in; or, when every block fires at every step,
the step written out in its own loop, :func:`_step`); a continuous run hands the four
functions to the instants' loop, compiled once for every diagram
(:func:`.store.instants_loop`). The parameters stay values at run time (``P``), so a new
value never recompiles.
"""

from __future__ import annotations

import hashlib
import inspect

import numpy as np

from ... import _jit
from ...kernels import lti
from ..source.runs import runs
from .loops import STAGE, caught
from .plan import CONTINUOUS, DISCRETE, SAMPLED, exact_sum

#: The first line of every module the engine writes: Python reads the rest as UTF-8.
CODING = "# -*- coding: utf-8 -*-"


def quoted(text) -> str:
    """``text`` as a Python string literal, whatever its class (a name is data: the
    ``repr`` of a subclass of ``str`` could be any code).

    Examples
    --------
    >>> print(quoted("it's"), quoted("a\\nb"))
    "it's" 'a\\nb'
    """
    return str.__repr__(text if isinstance(text, str) else str(text))


def numbers(value, numpy="np") -> str:
    """``repr`` of a float or a (nested) list of them, as a literal of a module's text
    (exact): an infinity or a NaN, whose ``repr`` names nothing, by the name ``numpy``
    gives it there.

    Examples
    --------
    >>> numbers([1.5, -float("inf"), float("nan")])
    '[1.5, -np.inf, np.nan]'
    """
    return repr(value).replace("inf", f"{numpy}.inf").replace("nan", f"{numpy}.nan")


def _terms(coefficients, name, from_zero=True):
    """``coefficients @ v`` as the sum of its terms, ``v[c]`` named ``name(c)``: from
    ``0.0``, as numpy's matrix products sum (a ``-0.0`` term gives ``0.0``, which
    ``atan2`` or ``copysign`` tell apart), or, ``from_zero=False``, the terms alone (numpy's
    ``dot`` of a 1 x 1 matrix, a product of numbers)."""
    row = np.asarray(coefficients, dtype=float).tolist()  # (numpy's floats one by one: slow)
    terms = [name(c) if g == 1.0 else f"{numbers(g)} * {name(c)}"
             for c, g in enumerate(row) if g != 0.0]
    return " + ".join(["0.0"] * (from_zero or not terms) + terms)


#: The largest LTI block written out term by term (products in its state and output
#: equations); a larger one calls the LTI kernels, whose loops cost little beside its work.
LTI_TERMS_WRITTEN_OUT = 256


def _lti_sums(P, kernel, row, ref):
    """The right-hand sides of an LTI block's outputs (``kernel`` is ``lti_output``) or
    next state (``lti_update``), one per row, every index a literal (``ref(array, i)``
    names ``x[i]`` or ``ui[i]``); None for another kernel, a large block, or sums numpy's
    BLAS could order otherwise (:func:`.plan.exact_sum`). Written out, a small block costs
    a few nanoseconds a step instead of ~10."""
    n, m, q = row.NX, row.NU, row.NY
    if kernel is lti.lti_output:
        first = row.P0 + 3 + n * n + n * m  # C, then D (see lti.pack)
        second, count = first + q * n, q
    elif kernel is lti.lti_update:
        first = row.P0 + 3  # A, then B
        second, count = first + n * n, n
    else:
        return None
    if count * (n + m) > LTI_TERMS_WRITTEN_OUT or not all(
            exact_sum(P[start + i * size:start + (i + 1) * size])
            for start, size in ((first, n), (second, m)) for i in range(count)):
        return None
    sums = []
    for i in range(count):
        fx = "".join(f" + P[{first + i * n + j}] * {ref('x', row.X0 + j)}" for j in range(n))
        gu = "".join(f" + P[{second + i * m + j}] * {ref('ui', row.U0 + j)}" for j in range(m))
        sums.append(f"(0.0{fx}) + (0.0{gu})")
    return sums


def _lti_lines(P, kernel, row, out, start, ref=lambda array, i: f"{array}[{i}]"):
    """:func:`_lti_sums` assigned to ``out[start:]`` (None where that is None)."""
    sums = _lti_sums(P, kernel, row, ref)
    return None if sums is None else [f"{out}[{start + i}] = {e}" for i, e in enumerate(sums)]


def _step(plan, P, rows, names, evaluate, ref, loads, args, view):
    """The loop of ``run_discrete`` when every block fires at every step, each step
    written out in it (not inlined into :func:`.loops.discrete_run`: servo loop of
    benchmarks/bench_hand_written.py 21.0 -> 15.9 ns a step).

    ``evaluate``'s lines, then the outputs and updates, which read the signals and states
    kept in locals (``ref``): LLVM cannot forward a store into one array to a load from
    another that might alias it. Written-out LTI blocks write their next state straight
    into ``x`` (their own states loaded before); a kernel's update writes ``xn``, copied
    into ``x`` at the end. The same operations in the same order: the same bits.
    """
    n = plan.sys.nstates
    if n <= STATES_HELD_IN_LOCALS:
        # every state loaded once, recorded from its local: reading x back after the
        # stores into X (which might alias it) cost the servo loop 16.1 -> 13.3 ns a step
        loaded = [f"_x{i} = x[{i}]" for i in range(n)]
        for i in range(n):
            ref("x", i)  # known from here on
        loads.clear()
        top = [*loaded, *(f"X[{i}, k] = _x{i}" for i in range(n))]
    else:
        loaded, top = [], [f"for i in range({n}):", "    X[i, k] = x[i]"]
    skip = set(loaded)  # loaded at the top of the step already
    lines = []
    for line in evaluate:  # a NaN output stops the run, naming its block
        code = line.strip()
        if line in skip:
            continue
        if code.startswith("return "):
            pad = line[:len(line) - len(line.lstrip())]
            lines += [f"{pad}status[0] = k", f"{pad}status[1] = {code.split()[1]}",
                      f"{pad}return x"]
        else:
            lines.append(line)
    lines += _output_lines(plan, "col", ref)
    back = []  # states a kernel steps in xn, copied into x at the end
    for b, row in enumerate(rows):
        if row.UPD < 0 or not row.NX or row.KIND not in (DISCRETE, SAMPLED):
            continue  # its states keep their value: nothing to write
        if row.KIND == SAMPLED:  # RK4 steps from xn itself
            first = row.X0
            lines += [f"xn[{i}] = x[{i}]" for i in range(first, first + row.NX)]
            lines += _rk4_lines(names[row.UPD], row, view)
            back += range(first, first + row.NX)
            continue
        sums = _lti_sums(P, plan.kernels[row.UPD], row, ref)
        if sums is None:
            lines.append(f"{names[row.UPD]}(t, {args(b, ('xn', row.X0), row.NX)})")
            back += range(row.X0, row.X0 + row.NX)
            continue
        lines += loads  # its own states not read yet, loaded before any is written
        loads.clear()
        lines += [f"x[{row.X0 + i}] = {e}" for i, e in enumerate(sums)]
    lines += [f"x[{i}] = xn[{i}]" for i in back]
    return ["for k in range(k0, k1):", *("    " + line for line in top), "    t = T[k]",
            "    col = k", *("    " + line for line in lines)]


def _output_lines(plan, column, ref):
    """The diagram's outputs at column ``column`` of ``Y``, read through ``ref(array, i)``
    (``ys`` for a block's output, ``ui`` for a diagram input); a row whose sum is not
    exact in any order is made as python-control makes it (:func:`_maps`)."""
    ny, exact = plan.ny, plan.outputs_exact
    output_map = np.asarray(plan.sys.output_map, dtype=float)
    single = getattr(plan.sys, "single_system", False)
    return [f"Y[{r}, {column}] = " + (_terms(output_map[r], lambda c: ref("ys", c) if c < ny
                                             else ref("ui", c - ny), from_zero=not single)
                                      if exact[r] else
                                      _product("_OUTPUT_MAP", plan.sys.output_map,
                                               "np.concatenate((ys, ui))", r))
            for r in range(plan.sys.noutputs)]


def _product(name, matrix, vector, row) -> str:
    """Row ``row`` of ``matrix @ vector`` as numpy makes it, ``matrix`` being the module's
    constant ``name``: a dot product for one row, the matrix-vector product for more."""
    if np.shape(matrix)[0] == 1:
        return f"{name}[0].dot({vector})"
    return f"{name}.dot({vector})[{row}]"


def _maps(plan) -> list[str]:
    """The module's constants python-control's maps are (``_CONNECT``, ``_INPUT_MAP``,
    ``_OUTPUT_MAP``), where a row of one is not exact in any order: python-control
    makes every block's inputs as ``connect_map @ outputs + input_map @ u`` and the
    diagram's outputs as ``output_map @ [outputs, inputs]``, and numpy's BLAS sums a row
    in an order that depends on the whole matrix. Numbers only (``repr`` of floats)."""
    sys = plan.sys
    lines = []
    for name, matrix, rows in (("_CONNECT", sys.connect_map, plan.inputs_exact),
                               ("_INPUT_MAP", sys.input_map, plan.inputs_exact),
                               ("_OUTPUT_MAP", sys.output_map, plan.outputs_exact)):
        if not all(rows):
            array = np.ascontiguousarray(matrix, dtype=float)
            lines.append(f"{name} = np.array({numbers(array.ravel().tolist())}, dtype=np.float64)"
                         f".reshape({array.shape!r})")
    return (["# python-control's maps: sums not exact in any order are made as it makes them"]
            + lines if lines else [])


#: A discrete step holds this many states in locals at most (a larger diagram's step
#: records them in a loop and loads them where they are read).
STATES_HELD_IN_LOCALS = 64


def _rk4_lines(kernel, row, view):
    """A sampled block's update: ``row.SUB`` steps of length ``row.H`` of
    :func:`~controlkit.kernels.common.rk4_step` written out, its operations in its order
    (the same bits, at half the cost: cruise loop ~190 -> ~80 ns). ``scratch`` holds
    ``k1 .. k4`` and the trial state, ``n`` values each."""
    n, x0, h = row.NX, row.X0, row.H
    k = [view("scratch", j * n, n) for j in range(5)]
    rest = f"{view('ui', row.U0, row.NU)}, {view('P', row.P0, row.NP)}"

    def each(template):  # one line per component, or a loop for a large block
        if n <= 8:
            return [template.format(j=j, x=x0 + j, k1=j, k2=n + j, k3=2 * n + j,
                                    k4=3 * n + j, xt=4 * n + j) for j in range(n)]
        loop = template.format(j="j", x=f"{x0} + j", k1="j", k2=f"{n} + j", k3=f"{2 * n} + j",
                               k4=f"{3 * n} + j", xt=f"{4 * n} + j")
        return [f"for j in range({n}):", "    " + loop]

    trial = "scratch[{xt}] = xn[{x}] + "
    body = [f"ti = t + i * {h!r}",
            f"{kernel}(ti, {view('xn', x0, n)}, {rest}, {k[0]})",
            *each(trial + f"({h!r} / 2) * scratch[{{k1}}]"),
            f"{kernel}(ti + {h!r} / 2, {k[4]}, {rest}, {k[1]})",
            *each(trial + f"({h!r} / 2) * scratch[{{k2}}]"),
            f"{kernel}(ti + {h!r} / 2, {k[4]}, {rest}, {k[2]})",
            *each(trial + f"{h!r} * scratch[{{k3}}]"),
            f"{kernel}(ti + {h!r}, {k[4]}, {rest}, {k[3]})",
            *each(f"xn[{{x}}] = xn[{{x}}] + ({h!r} / 6) * (scratch[{{k1}}] + 2 * scratch[{{k2}}]"
                  f" + 2 * scratch[{{k3}}] + scratch[{{k4}}])")]
    return [f"for i in range({row.SUB}):", *["    " + line for line in body]]


def kernel_identity(fn) -> str:
    """What a kernel is, for the module's text (and so its name in the store): a
    controlkit kernel, or one of a store module, by its dotted name; another by its name,
    a digest of its module's source and one of what it runs
    (:func:`controlkit.engines.source.runs.runs`: the values of its closure and its
    globals, the helpers it calls), so that a kernel made by a factory with other values,
    or a helper edited in another module, is a new module; a user function by its
    compiled module's name (:attr:`identity`).

    Examples
    --------
    >>> from controlkit.kernels.lti import lti_output
    >>> kernel_identity(lti_output)
    'controlkit.kernels.lti.lti_output'
    """
    identity = getattr(fn, "identity", None)
    if isinstance(identity, str):
        return identity
    py = _jit.python_function(fn)
    module = str(getattr(py, "__module__", None))
    name = f"{module}.{getattr(py, '__qualname__', getattr(py, '__name__', '?'))}"
    if module.startswith(("controlkit.", "controlkit_store_")):
        return name  # (a store module's name is a digest of its text, which freezes all)
    try:
        text = inspect.getsource(inspect.getmodule(py))
    except (OSError, TypeError):
        text = repr(getattr(py, "__code__", py))
    return f"{name} (source {hashlib.sha256(text.encode()).hexdigest()[:16]}, runs {runs(fn)})"


def generate(plan):
    """The source of ``plan``'s module (see the module's description).

    Kernels are named ``kernel_<i>``, a comment says which (:func:`kernel_identity`); the
    engine hands them in, compiled or as Python. No block's or diagram's name appears.
    Blocks fire at their instants when :attr:`.plan.Plan.held` (else at every step).
    A NaN output stops the run at its block (block contract rule 6).

    Examples
    --------
    >>> from controlkit.engines.fast.run import prepare
    >>> from controlkit.studies.cmg.diagrams import cmg_loop
    >>> source = generate(prepare(cmg_loop()).plan)
    >>> [line[:22] for line in source.splitlines() if line.startswith("def run")]
    ['def run_discrete(T, X0']
    """
    held_logic = plan.held
    P = plan.parameters()  # (which LTI blocks are written out depends on its zeros)
    identities = tuple(map(kernel_identity, plan.kernels))
    rows, ny = plan.rows, plan.ny
    names = [f"kernel_{i}" for i in range(len(plan.kernels))]
    trusted = plan.controlkit_s_own  # (NaN in, NaN out: their NaN checks can wait, see below)
    inputs = np.hstack([plan.sys.connect_map, plan.sys.input_map]).astype(float)

    # In evaluate, the signals that written-out lines compute are also kept in locals
    # (``_y3``, ``_u4``, ``_x0``), which later lines read: LLVM cannot keep an array entry
    # in a register across stores into other arrays that might alias it (servo loop 18.4
    # -> 17.0 ns a step). Only at the function's top level, where every path defines them.
    known, loads = {}, []

    def ref(array, i):
        if array == "x" and ("x", i) not in known:
            loads.append(f"_x{i} = x[{i}]")
            known[("x", i)] = f"_x{i}"
        return known.get((array, i), f"{array}[{i}]")

    exact = plan.inputs_exact
    # python-control's block inputs are ``connect_map @ ys + np.dot(input_map, u)``, swept
    # from ``np.dot(input_map, u)`` until they settle: summed from 0.0. But numpy's dot of a
    # 1 x 1 map is a product of numbers, which a -0.0 keeps, and the sweep stops at once
    # where the connections add 0.0 to it; a single system's inputs are those given.
    single = getattr(plan.sys, "single_system", False)
    lone_input = plan.sys.input_map.shape == (1, 1) or single

    def gather(b):
        lines = []
        for r in range(rows[b].U0, rows[b].U0 + rows[b].NU):
            if not exact[r]:
                value = (_product("_CONNECT", plan.sys.connect_map, "ys", r) + " + "
                         + _product("_INPUT_MAP", plan.sys.input_map, "U[:, col].copy()", r))
            elif lone_input:
                given = _terms(inputs[r, ny:], lambda c: f"U[{c}, col]", from_zero=False)
                fed = _terms(inputs[r, :ny], lambda c: ref("ys", c))
                value = (f"({given} if {fed} == 0.0 else {fed} + {given})"
                         if inputs[r, :ny].any() else given)
            else:
                value = _terms(inputs[r], lambda c: ref("ys", c) if c < ny
                               else f"U[{c - ny}, col]")
            lines += [f"_u{r} = {value}", f"ui[{r}] = _u{r}"]
            known[("ui", r)] = f"_u{r}"
        return lines

    def written_out(b, held):
        """The lines of block ``b``'s outputs written out (None: its kernel is called)."""
        row = rows[b]
        if held:  # inside a branch: into the array only
            return _lti_lines(P, plan.kernels[row.OUT], row, "ys", row.Y0, ref)
        sums = _lti_sums(P, plan.kernels[row.OUT], row, ref)
        if sums is None:
            return None
        lines = []
        for i, e in enumerate(sums):
            y = row.Y0 + i
            lines += [f"_y{y} = {e}", f"ys[{y}] = _y{y}"]
            known[("ys", y)] = f"_y{y}"
        return lines

    def view(array, start, size):
        # a slice, not a borrowed view (.views): numba's dead-store elimination once
        # dropped a pasted-in kernel's writes into a borrowed view (seen with the CMG's
        # reference generator, whose kernel indexes through a layout held in a local)
        return f"{array}[{start}:{start + size}]"

    def args(b, out, size):
        row = rows[b]
        return (f"{view('x', row.X0, row.NX)}, {view('ui', row.U0, row.NU)}, "
                f"{view('P', row.P0, row.NP)}, {view(out[0], out[1], size)}")

    # A NaN output stops the run naming its block. The checks of consecutive blocks of ours
    # (NaN in, NaN out: no index or branch of theirs can go wrong on it) are made together
    # before the next user function and at the end: an early return between two pasted-in
    # kernels keeps LLVM from pruning their slices' reference counts (servo loop of
    # benchmarks/bench_hand_written.py: 112 -> 32 ns a step). A user's function never sees a
    # NaN made upstream in the same step, as before.
    # A user's function that returns inf or NaN in any output stops it too: python-control's
    # interconnect cannot settle its signals on one (0 * inf in its connection map).
    evaluate, unchecked = [], []

    def checks():
        lines = []
        for y0, ny_user, b in unchecked:
            # (math's: numpy's of one number takes ten times as long as Python)
            bad = " or ".join(f"not math.isfinite({ref('ys', y)})"
                              for y in range(y0, y0 + ny_user)) or f"math.isnan({ref('ys', y0)})"
            lines += [f"if {bad}:", f"    return {b}"]
        unchecked.clear()
        return lines

    for b in plan.order:
        row = rows[b]
        if row.OUT not in trusted:
            evaluate += checks()
        evaluate.append(f"# block {b}")
        if row.FT:
            evaluate += gather(b)
        held = row.KIND in (DISCRETE, SAMPLED) and held_logic
        # python-control calls a single system's output function at the times it serves,
        # not at the integrator's stages (an interconnect's sweep calls them all there)
        unstaged = single and row.KIND == CONTINUOUS
        call = (written_out(b, held or unstaged)
                or [f"{names[row.OUT]}(t, {args(b, ('ys', row.Y0), row.NY)})"])
        evaluate += loads  # the states these lines read, loaded once at the top level
        loads.clear()
        if row.NY:
            unchecked.append((row.Y0, 0 if row.OUT in trusted else row.NY, b))
        if held:
            fires = "k >= 0" if row.EVERY == 1 else f"k >= 0 and k % {row.EVERY} == 0"
            evaluate += [f"if {fires}:", *["    " + c for c in call],
                         f"    for q in range({row.NY}):",
                         f"        held[{row.Y0} + q] = ys[{row.Y0} + q]",
                         "else:", f"    for q in range({row.NY}):",
                         f"        ys[{row.Y0} + q] = held[{row.Y0} + q]"]
        elif unstaged:
            evaluate += [f"if k != {STAGE}:", *["    " + c for c in call]]
        else:
            evaluate += call
    for b, row in enumerate(rows):
        if not row.FT:
            evaluate += gather(b)
    evaluate += checks()  # after the last copies: 77 -> 32 ns a step in that servo loop
    step = None if held_logic else _step(plan, P, rows, names, evaluate, ref, loads, args, view)
    evaluate.append("return -1")

    outputs = _output_lines(plan, "j", lambda array, i: f"{array}[{i}]") or ["pass"]

    nx = plan.sys.nstates
    # states no kernel rewrites whole at every step keep their value (a discrete block's
    # update writes all of its next state, rule 3 of the block contract; a sampled block's
    # RK4 steps from xn itself): copying only these saved 2 of 19 ns a step of a servo loop
    update = []
    for row in rows:
        rewritten = (row.KIND == DISCRETE and row.UPD >= 0 and not (held_logic and row.EVERY > 1))
        if not row.NX or rewritten:
            continue
        first, last = row.X0, row.X0 + row.NX
        update += ([f"xn[{i}] = x[{i}]" for i in range(first, last)] if row.NX <= 8 else
                   [f"for i in range({first}, {last}):", "    xn[i] = x[i]"])
    for b, row in enumerate(rows):
        if row.UPD < 0 or not row.NX or row.KIND not in (DISCRETE, SAMPLED):
            continue
        lines = []
        if row.KIND == DISCRETE:
            lines += (_lti_lines(P, plan.kernels[row.UPD], row, "xn", row.X0)
                      or [f"{names[row.UPD]}(t, {args(b, ('xn', row.X0), row.NX)})"])
        else:
            lines += _rk4_lines(names[row.UPD], row, view)
        if held_logic and row.EVERY > 1:
            update += [f"if k % {row.EVERY} == 0:", *["    " + line for line in lines]]
        else:
            update += lines

    derivatives = [line for b, row in enumerate(rows) if row.KIND == CONTINUOUS
                   for line in (_lti_lines(P, plan.kernels[row.UPD], row, "dx", row.X0) or [
                       f"{names[row.UPD]}(t, {args(b, ('dx', row.X0), row.NX)})"])] or ["pass"]

    widest = max([1, *(row.NX for row in rows)])
    buffers = [f"ys = np.zeros({ny})", f"ui = np.zeros({plan.nu})",
               f"xn = np.empty({nx})", f"scratch = np.empty({5 * widest})"]

    def function(signature, lines):
        return [f"def {signature}:", *["    " + line for line in lines], "", ""]

    def evaluator(signature, lines):  # pasted into run_discrete; compiled on their own for
        # the instants' loop
        return ["@jit(inline=True)", *function(signature, lines)]

    text = [
        CODING,  # (first: a name on the first two lines could declare another coding)
        # (blocks by their index, not their names: python-control names a system it is not
        # given a name 'sys[<count>]', a new name at each build of the same diagram)
        "# generated by controlkit.engines.fast.codegen: a diagram's module; do not edit",
        "# kernels, handed to the module by the engine (compiled, or as Python):",
        *[f"#   {alias}: {quoted(identity)}" for alias, identity in zip(names, identities,
                                                                   strict=True)],
        "import math",
        "",
        "import numpy as np",
        "",
        "from controlkit._jit import jit",
        "from controlkit.engines.fast.loops import discrete_run",
        "from controlkit.kernels.common import rk4_step",
        "",
        *_maps(plan),
        "",
        "",
        *evaluator("evaluate(t, x, U, col, P, ys, ui, held, k)", evaluate),
        *evaluator("outputs(ys, ui, Y, j)", outputs),
        *evaluator("update(t, x, ui, P, xn, k, scratch)", update or ["pass"]),
        *evaluator("derivatives(t, x, ui, P, dx)", derivatives),
        *function("run_discrete(T, X0, U, P, Y, X, status, k0, k1)", [
            "x = X0.copy()", *buffers, f"held = np.zeros({ny})",
            *(step or ["discrete_run(evaluate, update, outputs, T, x, U, P, Y, X, "
                       "status, k0, k1, ys, ui, held, xn, scratch)"]), "return x"]),
    ]
    return "\n".join(text) + caught(plan.calls_users)
