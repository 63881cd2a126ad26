"""A function's :class:`Plan`: its statements as the compiler needs them, the helpers it
calls and the values it reads from outside; made once per callable and used again while
those values are unchanged. Also the two questions the ``params`` check and the engine ask.
"""

from __future__ import annotations

import ast
import contextlib
import copy
import re
import weakref
from dataclasses import dataclass, field

from .reading import (
    PARAMS,
    Frozen,
    NotCompilable,
    _binding_key,
    _called_as_python_control,
    _definition,
    _input_name,
    call_target,
)
from .rewrites import walk
from .translator import _Translator
from .values import _same, _same_items


@dataclass(eq=False)
class Plan:
    """One function, specialised to how it is called: what the compiler needs.

    Attributes
    ----------
    function : function
        The Python function.
    name : str
        Its name in the generated module.
    arguments : list of str
        The arguments it keeps (the run-time ones), in order.
    body : list of ast.stmt
        Its statements, params reads as :data:`PARAM_READ` calls, helper calls renamed
        to their plans' names, values from outside renamed to the keys of ``frozen``.
    frozen : dict
        Module-level name -> value (a number, array, string, module or function) read
        from outside the function.
    helpers : list of Plan
        The plans of the functions it calls.
    keys : set
        The run-time ``params`` keys it reads itself.
    opaque : str or None
        Why the keys it reads cannot all be known (``params`` used otherwise than by key).
    problem : str or None
        Why it cannot be compiled.
    checks : list
        ``(read, value)`` for each value read from outside the function: ``read()`` reads
        it again (see :meth:`valid`).
    written : dict
        The compiler's text of the plan's functions, by parameter layout.
    finished : list or None
        :meth:`tree` of a finished plan (set by :func:`plan_function`), which no longer
        changes; None while the plan is being built.
    call : tuple or None
        For the top plan, what calling the callable ran when the plan was made
        (:func:`~.reading.call_target`: a partial's values, a class's ``__call__``):
        the plan is used again only while it runs the same.

    Examples
    --------
    >>> def pi_output(t, x, u, params):
    ...     return params.get("kp", 0.5) * u[0] + params["ki"] * x[0]
    >>> plan = plan_function(pi_output)
    >>> plan.arguments, sorted(plan.keys), plan.why_not()
    (['t', 'x', 'u', 'params'], ['ki', 'kp'], None)
    """

    function: object
    name: str
    index: int = 0
    arguments: list = field(default_factory=list)
    body: list = field(default_factory=list)
    frozen: dict = field(default_factory=dict)
    helpers: list = field(default_factory=list)
    keys: set = field(default_factory=set)
    opaque: str | None = None
    problem: str | None = None
    checks: list = field(default_factory=list)
    code: object = None
    defaults: object = None
    kwdefaults: object = None
    written: dict = field(default_factory=dict)
    finished: list | None = field(default=None, repr=False, compare=False)
    call: tuple | None = field(default=None, repr=False, compare=False)

    def valid(self) -> bool:
        """Whether everything this plan (and each plan it calls) read from outside its
        function is still what it was: the same code and defaults, the same objects under
        the same names, the same numbers in the same attributes and dicts. Arrays are
        compared by identity: their contents are read again whenever code is written."""
        for plan in self.tree():
            fn = plan.function
            if fn.__code__ is not plan.code or fn.__defaults__ is not plan.defaults \
                    or not _same_items(fn.__kwdefaults__, plan.kwdefaults):
                return False
            if not all(_same(getter(), value) for getter, value in plan.checks):
                return False
        return True

    def tree(self):
        """This plan and every plan it calls, each once (callers first)."""
        if self.finished is not None:  # a finished plan's helpers no longer change
            return self.finished
        seen, order, stack = set(), [], [self]
        while stack:
            plan = stack.pop()
            if id(plan) in seen:
                continue
            seen.add(id(plan))
            order.append(plan)
            stack.extend(reversed(plan.helpers))
        return order

    def params_read(self):
        """The run-time keys read by this plan and its helpers, or None if unknown."""
        keys = set()
        for plan in self.tree():
            if plan.opaque is not None:
                return None
            keys |= plan.keys
        return keys

    def why_not(self):
        """Why the plan cannot be compiled (the first reason found), or None."""
        for plan in self.tree():
            reason = plan.opaque or plan.problem
            if reason is not None:
                where = "" if plan.name == "user" else f" (in {plan.function.__qualname__})"
                return reason + where
        return None


def plan_function(fn):
    """The :class:`Plan` of ``fn`` called as python-control calls it, ``fn(t, x, u, params)``.

    Raises
    ------
    NotCompilable
        When ``fn`` is not a Python callable whose source can be read.

    Examples
    --------
    >>> def servo(t, x, u, params):
    ...     J, b = map(params.get, ["J", "b"])
    ...     return [x[1], (u[0] - b * x[1]) / J]
    >>> plan = plan_function(servo)
    >>> sorted(plan.params_read()), plan.why_not()
    (['J', 'b'], None)
    """
    try:
        cached = _PLANS.get(fn)
    except TypeError:  # not hashable or not weakly referable: planned each time
        cached = None
    target, bound, keywords = call_target(fn)
    if cached is not None and cached.valid() and cached.call[0] is target \
            and len(bound) == len(cached.call[1]) and all(map(_same, bound, cached.call[1])) \
            and _same_items(keywords, cached.call[2]):
        return cached  # (calling fn still runs the same: a partial's values, __call__)
    bindings = _called_as_python_control(target, bound, keywords)
    if isinstance(bindings, str):
        raise NotCompilable(bindings)
    _definition(target.__code__, copy=False)  # no source: NotCompilable, nothing is known
    plan = _Build().plan(target, bindings, name="user")
    plan.call = (target, list(bound), dict(keywords))
    plan.finished = plan.tree()  # asked for at every run (its validity, keys, reasons)
    with contextlib.suppress(TypeError):
        _PLANS[fn] = plan
    return plan


#: Plans by the callable they were made for, kept while it lives and used again while
#: :meth:`Plan.valid` (a simulation asks for each block's plans several times).
_PLANS = weakref.WeakKeyDictionary()


class _Build:
    """The plans made for one function and its helpers (each specialisation once)."""

    def __init__(self):
        self.plans = {}
        self.count = 0

    def plan(self, fn, bindings, name=None):
        key = (fn, tuple((n, _binding_key(b)) for n, b in bindings.items()))
        if key in self.plans:
            return self.plans[key]
        self.count += 1
        name = name or f"_h{self.count}_{re.sub(r'[^0-9A-Za-z_]', '', fn.__name__)}"
        plan = Plan(fn, name, self.count,  # (a name is data: only letters of identifiers)
                    code=fn.__code__, defaults=fn.__defaults__,
                    kwdefaults=copy.copy(fn.__kwdefaults__))  # (changed in place)
        self.plans[key] = plan
        try:
            _, body = _definition(fn.__code__)
        except NotCompilable as why:
            plan.problem = str(why)
            if any(b == PARAMS or isinstance(b, Frozen) and isinstance(b.value, dict)
                   for b in bindings.values()):
                plan.opaque = f"params is handed to {fn.__qualname__}, whose source is unknown"
            return plan
        try:
            _Translator(self, plan, fn, bindings).translate(body)
        except Exception as error:  # noqa: BLE001 - a construct not foreseen: nothing known
            plan.problem = plan.opaque = (f"it could not be read ({type(error).__name__}: "
                                          f"{error})")
        return plan


def used_params(fn):
    """The ``params`` keys a ``(t, x, u, params)`` function reads, or None if unknown.

    Keys read through helpers it hands ``params`` to count; an alias, a key in a
    variable or ``map(params.get, [...])`` are understood. Where ``params`` is used in a
    way not understood (or the source is not available) the answer is None.

    Examples
    --------
    >>> sorted(used_params(lambda t, x, u, params: params["k"] * x + params.get("b", 0.0)))
    ['b', 'k']
    >>> def f(t, x, u, params):
    ...     p = params
    ...     return [p["gain"] * u[0]]
    >>> used_params(f)
    {'gain'}
    >>> used_params(lambda t, x, u, params: sum(params.values())) is None
    True
    """
    try:
        return plan_function(fn).params_read()
    except NotCompilable:
        return None


def reads_input(fn):
    """Whether a ``(t, x, u, params)`` function reads ``u`` (None when its source is unknown).

    Examples
    --------
    >>> reads_input(lambda t, x, u, params: 2 * x)
    False
    """
    try:
        target, bound, keywords = call_target(fn)
    except NotCompilable:
        return None
    # which argument is u follows from the code and how many arguments are bound, by
    # which names: asked again at every run of a diagram, answered once (0.25 ms a block)
    key = (target.__code__, len(bound), tuple(sorted(keywords)))
    if key not in _READS_INPUT:
        try:
            _, body = _definition(target.__code__, copy=False)
        except NotCompilable:
            return None
        bindings = _called_as_python_control(target, bound, keywords)
        name = None if isinstance(bindings, str) else _input_name(bindings)
        _READS_INPUT[key] = None if name is None else any(
            isinstance(n, ast.Name) and n.id == name for n in walk(ast.Module(body, [])))
    return _READS_INPUT[key]


#: :func:`reads_input`'s answers, by code object and binding.
_READS_INPUT: dict = {}
