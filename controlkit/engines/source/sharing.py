"""One plan for every function made anew from the same ``def``.

A diagram's builder that defines its blocks' functions inside itself (``def pi_rate(...)``
inside ``def cruise_loop(...)``, closures reading what the builder was handed) makes new
function objects at every call: wiring the diagram again would read, parse and translate
each of them again (about 1 ms a function) though nothing in them changed. A plan depends
only on what it was made from: the code, the defaults and every value read from outside
the function (:attr:`~.plan.Plan.checks`). So the plan of an earlier function of the same
code serves a new one when each of those reads, made through the new function, gives the
same value (by :func:`~.values._same`, as :meth:`~.plan.Plan.valid` asks) -- or, for a
helper read from the closure, a function of the same code that the same holds for in turn
(``pi_rate`` calling its sibling closure ``pi_output``). :func:`share` makes that plan's
copy for the new function, its reads bound to the new closure; anything it cannot match
exactly gives None, and the function is planned from its source as before.
"""

from __future__ import annotations

import dataclasses
import functools
import types
from collections import OrderedDict

from .values import (
    _cell,
    _global,
    _reevaluate,
    _same,
    _same_items,
    _same_sequence,
    _snapshot,
)

#: Plans by code object, the most recently made or shared last; each code keeps a few
#: (functions of one ``def`` that read different values). A bounded number of plans (and
#: the functions they hold) is kept alive, so that a diagram built anew after the old one
#: was dropped still finds them.
_BY_CODE: OrderedDict = OrderedDict()
_CODES_KEPT = 64
_PER_CODE = 4


def remember(plan) -> None:
    """Keep ``plan`` (a finished top plan of a plain function) for :func:`share`.

    :func:`~.plan.plan_function` calls it for each plan it makes or shares.

    Examples
    --------
    >>> from controlkit.engines.source import plan_function
    >>> plan = plan_function(lambda t, x, u, params: -x)
    >>> remember(plan)
    >>> _BY_CODE[plan.code][-1] is plan
    True
    """
    code = plan.code
    kept = [p for p in _BY_CODE.pop(code, []) if p is not plan][-(_PER_CODE - 1):]
    _BY_CODE[code] = [*kept, plan]
    while len(_BY_CODE) > _CODES_KEPT:
        _BY_CODE.popitem(last=False)


def share(fn):
    """A plan for ``fn`` (a plain function) copied from one kept for its code, or None.

    Examples
    --------
    >>> from controlkit.engines.source import plan_function
    >>> def build(gain):
    ...     def output(t, x, u, params):
    ...         return gain * params["k"] * u[0]
    ...     return output
    >>> first = plan_function(build(2.0))
    >>> again = plan_function(build(2.0))  # a new closure, the same def and values
    >>> again is first, again.function is first.function, again.body is first.body
    (False, False, True)
    >>> plan_function(build(3.0)).body is first.body  # it reads another gain
    False
    """
    if not isinstance(fn, types.FunctionType):
        return None
    for plan in reversed(_BY_CODE.get(fn.__code__, ())):
        shared = _copy_for(plan, fn)
        if shared is not None:
            return shared
    return None


class _Differs(Exception):
    """The kept plan does not serve the new function."""


def _copy_for(top, fn):
    if top.call is None or top.call[1] or top.call[2] or top.function is fn:
        return None  # a partial or bound callable: planned from its source
    try:
        return _Sharing(top, fn).copy()
    except _Differs:
        return None


class _Sharing:
    """The matching of one kept plan tree against a new top function."""

    def __init__(self, top, fn):
        self.top = top
        self.new_function = {id(top.function): fn}  # old function -> its new twin
        self.kept = set()  # ids of old functions whose plans serve unchanged

    def copy(self):
        order = self.top.tree()
        copies = {}
        for plan in order:  # callers first: a helper's twin is known before its plan
            new = self.new_function.get(id(plan.function))
            if new is None:
                if not plan.valid():
                    raise _Differs
                self.kept.add(id(plan.function))
                copies[id(plan)] = plan
            else:
                copies[id(plan)] = self._copy(plan, new)
        for plan in order:
            each = copies[id(plan)]
            if each is not plan:
                each.helpers = [copies[id(h)] for h in plan.helpers]
            elif any(copies[id(h)] is not h for h in plan.tree()):
                raise _Differs  # a kept plan calls a helper that changed
        new_top = copies[id(self.top)]
        tree = new_top.tree()
        if len({p.name for p in tree}) != len(tree):
            raise _Differs  # an old function and its twin both called: names would clash
        new_top.call = (new_top.function, [], {})
        new_top.finished = tree
        return new_top

    def _copy(self, plan, new):
        old = plan.function
        if new.__code__ is not plan.code or new.__globals__ is not old.__globals__ \
                or not _same_sequence(new.__defaults__, plan.defaults) \
                or not _same_items(new.__kwdefaults__, plan.kwdefaults):
            raise _Differs
        checks = []
        for getter, value in plan.checks:
            getter = _rebound(getter, old, new)
            now = getter()
            same = _same(now, value)
            if not same:
                self._twin(value, now)
            checks.append((getter, value if same else now))
        return dataclasses.replace(
            plan, function=new, defaults=new.__defaults__,
            kwdefaults=_snapshot(new.__kwdefaults__), frozen=dict(plan.frozen),
            checks=checks, helpers=list(plan.helpers), finished=None, call=None)

    def _twin(self, old, new):
        """``new`` read where ``old`` was: a function of the same code whose plan is in
        the tree (its copy is checked in turn), else the plan differs."""
        if not (isinstance(old, types.FunctionType) and isinstance(new, types.FunctionType)
                and old.__code__ is new.__code__) or id(old) in self.kept \
                or not any(p.function is old for p in self.top.tree()):
            raise _Differs
        if self.new_function.setdefault(id(old), new) is not new:
            raise _Differs


def _rebound(getter, old, new):
    """``getter`` (a read made through ``old``) reading through ``new`` instead."""
    if isinstance(getter, functools.partial):
        if getter.func is _cell:
            for mine, theirs in zip(old.__closure__ or (), new.__closure__ or (), strict=True):
                if mine is getter.args[0]:
                    return functools.partial(_cell, theirs)
            raise _Differs  # a cell that is not the function's own
        if getter.func is _reevaluate:
            root, steps = getter.args
            return functools.partial(_reevaluate, _rebound(root, old, new), steps)
        if getter.func is _global:
            return getter  # the same module namespace (checked) or a dict read by identity
    return getter  # a value bound when the plan was made (an argument, an import)

