"""A user's ``(t, x, u, params)`` function as a kernel ``(t, x, u, p, out)``: called as
Python (:class:`UserKernel`), or compiled from its translated text, kept in the store.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import re
import sys
import time
from pathlib import Path
from types import FunctionType

import numpy as np

from .... import _jit
from ...source import NotCompilable, Plan, as_written, plan_function
from ...source.reading import call_target
from ...source.runs import code_digest
from .. import store
from .layout import ParamLayout
from .writer import kernel_source

#: What each role of a user function computes, for messages.
ROLES = {"output": ("output function", "outputs"), "update": ("update function", "states")}
#: About how long compiling a user's kernel takes per line of its translated functions,
#: before the store measured one, each kernel counted :data:`KERNEL_MORE_LINES` longer for
#: numba's work per function (on a 2-core machine, the medians of 1 900 compiles: 0.17-0.26
#: s for 4-8 lines, 0.19-0.41 s for 9-14, 0.32-0.65 s for 18-25).
KERNEL_LINE_SECONDS = 0.02
KERNEL_MORE_LINES = 5
#: About how long compiling a kernel that works on arrays can take (one that calls numpy,
#: or controlkit's versions of its linear algebra, products and sums, or uses its state or
#: input vector whole): numba then compiles array code of its own, 0.3-4.7 s measured
#: for one-line functions (``np.linalg.solve``: 4.7 s), which their lines do not tell.
NUMPY_KERNEL_SECONDS = 5.0
#: controlkit's helpers that work on arrays, as a kernel's text names them.
_ARRAY_HELPERS = re.compile(r"_ck_(solve|det|slogdet|norm|matmul|dot|trace|sum|mean)")
#: numpy's functions of numbers: called on numbers (not a vector whole), no array code.
_NUMBER_FUNCTIONS = frozenset(
    "sin cos tan arcsin arccos arctan arctan2 sinh cosh tanh arcsinh arccosh arctanh exp "
    "expm1 exp2 log log10 log2 log1p sqrt cbrt square abs absolute fabs sign floor ceil "
    "trunc rint hypot deg2rad rad2deg radians degrees minimum maximum fmin fmax power mod "
    "fmod copysign isnan isfinite isinf float64 int64".split())
#: The store files of kernels known to be compiled (a record, once written, stays).
_KEPT: set = set()


class UserKernel:
    """A user's function as a kernel: its Python self when called, compiled on request.

    Called as ``kernel(t, x, u, p, out)`` it calls ``fn(t, x, u, params)`` with the
    block's parameters and stores the result in ``out``, refusing a result of another
    size with the block's name (python-control raises for a lone system and, inside an
    interconnect, silently spreads a single value over the slots). :meth:`text` writes
    the kernel module for a parameter layout, :meth:`compiled` gives its numba function.

    Parameters
    ----------
    fn : callable
        The user's function.
    values : dict
        The parameters python-control hands it.
    block : str
        The block's name.
    role : {"output", "update"}

    Examples
    --------
    >>> k = UserKernel(lambda t, x, u, params: params["a"] * x, {"a": 2.0}, "gain", "output")
    >>> k(0.0, np.ones(1), np.zeros(0), None, np.empty(1)).tolist()
    [2.0]
    >>> k(0.0, np.ones(2), np.zeros(0), None, np.empty(1))
    Traceback (most recent call last):
    ...
    controlkit.engines.fast.usercode.compiling.SizeError: inconsistent size of outputs; ...
    """

    def __init__(self, fn, values, block, role):
        self.fn, self.params, self.block, self.role = fn, dict(values), block, role
        self._plan = self._text = None

    def __call__(self, t, x, u, p, out):
        try:
            result = self.fn(t, x, u, self.params)
        except Exception as error:  # Python's own error, told where it happened
            _told_where(error, f"in block {self.block!r}, its {ROLES[self.role][0]}, at "
                               f"t = {t:g} s")
            raise
        if type(result) is np.ndarray and result.shape == out.shape:
            out[:] = result  # (the most common return, a third of the time of the rest)
            return out
        what, unit = ROLES[self.role]
        if result is None:
            raise TypeError(f"block {self.block!r}: its {what} returned None at t = {t:g} "
                            f"s (a return statement missing?); it must return its "
                            f"{out.size} {unit}")
        value = np.asarray(result).reshape(-1)
        if value.size != out.size:  # python-control's words (for a lone system), and where
            raise SizeError(f"inconsistent size of {unit}; system specified {out.size}, "
                            f"{what} returned {value.size} (block {self.block!r}, at t = {t:g} s)")
        out[:] = value  # (as python-control stores it: a complex number's real part, warned)
        return out

    def plan(self) -> Plan:
        """The function read from its source (see :func:`.source.plan_function`)."""
        if self._plan is None:
            self._plan = plan_function(self.fn)
        return self._plan

    def text(self, layout: ParamLayout) -> str:
        """The kernel module's text for the block's parameter ``layout`` (or
        NotCompilable with the reason, numba's own when it refused this text before)."""
        text = kernel_source(self.plan(), layout)
        said = store.refusal(text, "user")
        if said is not None:
            raise NotCompilable(f"numba could not compile it ({said}; found by an earlier "
                                f"compile, kept in the store)")
        self._text = text
        return text

    @property
    def identity(self) -> str:
        """The kernel module's name in the store (what the diagram's text names); as
        Python, what its function runs (not its block's name: a diagram built again, its
        blocks named anew by python-control, is the same module, whose earlier runs count
        for the rule)."""
        if self._text:
            return store.name_of(self._text, "user")
        try:
            code = call_target(self.fn)[0].__code__
        except NotCompilable:  # (a builtin: its name)
            return f"python {self.role}: {getattr(self.fn, '__qualname__', type(self.fn))}"
        return f"python {self.role}: {_runs_code(code)}"

    def compiled(self):
        """The kernel of the store module of :meth:`text` (compiled before the diagram
        that calls it, :func:`compile_kernel`): the user's functions are pasted into it,
        and its indexes checked (``boundscheck``), so that an index outside an array is
        Python's ``IndexError``, not a read of other memory."""
        with store.LOCK:  # (another thread sees the module's functions all wrapped)
            module = store.import_module(store.module_file(self._text, "user"))
            if not isinstance(module.kernel, _jit.Jitted):  # (once a process)
                for name, value in list(vars(module).items()):
                    if isinstance(value, FunctionType) and value.__module__ == module.__name__:
                        options = (dict(boundscheck=True, error_model="numpy", cache=True)
                                   if name == "kernel"
                                   else dict(inline="always", error_model="numpy"))
                        setattr(module, name, _jit.Jitted(value, options))
        return module.kernel


@functools.cache
def _runs_code(code) -> str:
    """A function's code by its name and a digest of what it runs."""
    digest = hashlib.sha256()
    code_digest(code, digest)
    return f"{code.co_qualname} ({digest.hexdigest()[:16]})"


def kernels_to_compile(kernels) -> list[tuple[float, object]]:
    """The user's compiled kernels among ``kernels`` (a compiled job's) that the store does
    not keep compiled yet, as steps ``(seconds, make)``: about how long compiling each
    takes (its lines and :data:`KERNEL_MORE_LINES` times the store's median seconds per
    line, :func:`.store.compile_times`, else :data:`KERNEL_LINE_SECONDS`; one that calls numpy
    on arrays, :data:`NUMPY_KERNEL_SECONDS`) and what compiles it.

    Examples
    --------
    >>> kernels_to_compile([np.sin])  # (not a user's kernel)
    []
    """
    per_line = store.compile_times("kernel", more=KERNEL_MORE_LINES)
    per_line = float(np.median(per_line)) if per_line else KERNEL_LINE_SECONDS
    steps = []
    for kernel in dict.fromkeys(kernels):  # (a function used by two blocks: one compile)
        path = _kept_in(kernel)
        if path is not None and path not in _KEPT:
            if store.record(path) is not None:
                _KEPT.add(path)
            elif path.exists():  # (else a store emptied under a running session)
                lines, numpy = _size(path)
                steps.append((NUMPY_KERNEL_SECONDS if numpy
                              else per_line * (lines + KERNEL_MORE_LINES),
                              functools.partial(compile_kernel, kernel)))
    return steps


def compile_kernel(kernel) -> None:
    """Compile a user's ``kernel`` (a step of :func:`kernels_to_compile`) for the types a
    diagram's module calls it with (``t`` and four 1-D slices), keep it in the store and
    record the time it took: a module compiled later loads it (and the time estimates the
    next kernels).

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.engines.fast.run import compiled_job
    >>> def decay(t, x, u, params):
    ...     return [-params.get("a", 1.0) * x[0] + u[0]]
    >>> block = ct.nlsys(decay, None, inputs="u", outputs="x", states="x", name="decay")
    >>> job = compiled_job(ct.interconnect([block], inputs="u", outputs="x"), None)
    >>> kernels = [] if isinstance(job, str) else job.plan.kernels
    >>> for _, make in kernels_to_compile(kernels):
    ...     make()
    >>> kernels_to_compile(kernels)
    []
    """
    path = _kept_in(kernel)
    numba = store.numba_checked()
    vector = numba.types.Array(numba.float64, 1, "C")
    with store.LOCK:  # (a thread, or a process, that compiled it first recorded its time)
        if store.record(path) is not None:
            return
        start = time.perf_counter()
        try:
            kernel.dispatcher.compile((numba.float64, vector, vector, vector, vector))
        except (MemoryError, OSError):  # (the machine's, not the text's: tried again)
            raise
        except Exception as error:  # numba's refusal, kept: later sessions do not try
            store.refuse(path, error)
            raise
        seconds = round(time.perf_counter() - start, 3)
        if store.record(path) is None:  # (a numpy one's time is not read per line)
            lines, numpy = _size(path)
            store.write_record(path, seconds=seconds, lines=lines,
                               entry="numpy kernel" if numpy else "kernel")


def _kept_in(kernel) -> Path | None:
    """The store file of a user's compiled ``kernel``; None for any other function."""
    module = sys.modules.get(getattr(kernel, "__module__", None) or "")
    file = getattr(module, "__file__", None)
    return Path(file) if file and Path(file).stem.startswith("user_") \
        and isinstance(kernel, _jit.Jitted) else None


@functools.cache
def _size(path: Path) -> tuple[int, bool]:
    """The lines of the functions of the kernel module at ``path`` (not its comments and
    imports), and whether its ``user`` function works on arrays (a store file's text never
    changes: its name is its text's digest)."""
    text = path.read_text()
    lines = [line for line in text.splitlines()
             if line.strip() and not line.startswith(("#", "import ", "from "))]
    functions = {node.name: node for node in ast.parse(text).body
                 if isinstance(node, ast.FunctionDef)}
    user = functions.get("user")
    if user is None or len(user.args.args) < 3:  # (not the writer's form: as an array one)
        return len(lines), True
    vectors = frozenset(argument.arg for argument in user.args.args[1:3])  # (its x and u)
    return len(lines), _works_on_arrays(functions, "user", vectors, set())


def _works_on_arrays(functions, name, vectors, seen) -> bool:
    """Whether function ``name`` of a kernel module calls numpy or controlkit's array
    helpers, or uses one of ``vectors`` (its arguments that hold the state or input
    vector) whole; a vector handed on to a function of the module counts as that
    function's use of it."""
    handed = set()
    for call in ast.walk(functions[name]):
        callee = functions.get(getattr(call.func, "id", None)) if isinstance(
            call, ast.Call) else None
        if callee is None or callee.name == name:
            continue
        given = {argument.arg for argument, value in zip(callee.args.args, call.args,
                                                         strict=False)
                 if isinstance(value, ast.Name) and value.id in vectors}
        handed |= {id(value) for value in call.args if isinstance(value, ast.Name)}
        key = (callee.name, frozenset(given))
        if given and key not in seen:
            seen.add(key)
            if _works_on_arrays(functions, callee.name, frozenset(given), seen):
                return True
    body = ast.Module(body=functions[name].body, type_ignores=[])
    indexed = {id(node.value) for node in ast.walk(body) if isinstance(node, ast.Subscript)}
    return any(
        isinstance(node, ast.Name) and (node.id in vectors and id(node) not in indexed | handed
                                        or _ARRAY_HELPERS.fullmatch(node.id))
        or isinstance(node, ast.Call) and _calls_numpy_on_arrays(node.func)
        for node in ast.walk(body))


def _calls_numpy_on_arrays(function) -> bool:
    """Whether a call of ``function`` (a kernel text's expression) is numpy's, other than
    one of its functions of numbers (``np.sin``, not ``np.zeros`` nor ``np.linalg.solve``;
    the module's text names numpy ``_np_``, or the user's ``np`` frozen)."""
    names = []
    while isinstance(function, ast.Attribute):
        names.append(function.attr)
        function = function.value
    name = function.id if isinstance(function, ast.Name) else ""
    numpy = name == "_np_" or name != as_written(name) == "np"  # (or the user's np, frozen)
    return numpy and bool(names) and not (len(names) == 1 and names[0] in _NUMBER_FUNCTIONS)


class SizeError(RuntimeError, ValueError):
    """A user's function returned more or fewer values than its block declares: a
    ``RuntimeError`` as python-control raises for a lone system, and a ``ValueError`` as
    numpy's inside an interconnect.

    Examples
    --------
    >>> isinstance(SizeError("inconsistent size"), ValueError)
    True
    """


#: Errors whose message is their one argument, which Python prints as it is: the block and
#: the time are written into it (a note would not show in ``str(error)``).
_PLAIN_MESSAGES = (ArithmeticError, ValueError, IndexError, TypeError, AttributeError,
                   NameError, AssertionError, RuntimeError)


def _told_where(error, where):
    """Follow ``error``'s message by ``(where)``: the same type, Python's own words."""
    plain = type(error).__str__ is BaseException.__str__ or isinstance(error, _PLAIN_MESSAGES)
    if plain and len(error.args) == 1 and isinstance(error.args[0], str) \
            and not isinstance(error, KeyError | UnicodeError | OSError):
        error.args = (f"{error.args[0]} ({where})",)
    else:
        error.add_note(f"({where})")


def block_layout(kernels, values) -> ParamLayout:
    """The packed parameters shared by a block's user functions (NotCompilable if the
    keys they read are not known, or a value cannot be packed).

    Examples
    --------
    >>> def f(t, x, u, params):
    ...     return [params["k"] * x[0]]
    >>> block_layout([UserKernel(f, {"k": 2.0}, "b", "output")], {"k": 2.0}).size
    1
    """
    keys = set()
    for kernel in kernels:
        plan = kernel.plan()
        read = plan.params_read()
        if read is None:
            raise NotCompilable(plan.why_not() or "the params it reads are not known")
        keys |= read
    return ParamLayout(keys, values)
