"""How a function's arguments are bound at a call: to a value known when the plan is made
(:class:`Frozen`), to the run-time ``params`` (:data:`PARAMS`) or to a value known only
when the function runs (:data:`RUNTIME`).
"""

from __future__ import annotations

from dataclasses import dataclass

from .reading import NotCompilable, _definition


class _Runtime:
    """Binding of an argument to a value known only when the function runs."""

    def __repr__(self):
        return "runtime"


#: A function argument given a value at run time (kept in the compiled signature).
RUNTIME = _Runtime()
#: A function argument that receives the run-time ``params`` (the packed vector, compiled).
PARAMS = "params"


@dataclass(eq=False)
class Frozen:
    """A function argument bound to a value known when the plan is made (dropped from
    the compiled signature): a partial's argument, a default, a method's ``self``.

    Examples
    --------
    >>> Frozen(2.0).value
    2.0
    """

    value: object


def _called_as_python_control(target, bound, keywords):
    """The bindings of ``target`` called as ``fn(t, x, u, params)`` with the values
    :func:`~.reading.call_target` found bound, or the reason it cannot be bound."""
    call = [Frozen(v) for v in bound] + [RUNTIME, RUNTIME, RUNTIME, PARAMS]
    return _bind(target, call, {k: Frozen(v) for k, v in keywords.items()})


def _input_name(bindings):
    """The argument that receives ``u`` (the third of t, x, u, params)."""
    runtime = [name for name, b in bindings.items() if b is RUNTIME or b == PARAMS]
    return runtime[2] if len(runtime) == 4 else None


def _bind(fn, positional, keywords):
    """Each argument name of ``fn`` -> its binding, as Python would bind the call, or
    the reason it cannot be bound."""
    try:
        arguments, _ = _definition(fn.__code__, copy=False)
    except NotCompilable as why:
        return str(why)
    if arguments.vararg is not None or arguments.kwarg is not None:
        return f"{fn.__qualname__} takes *args or **kwargs"
    names = [a.arg for a in arguments.posonlyargs + arguments.args]
    kwonly = [a.arg for a in arguments.kwonlyargs]
    if len(positional) > len(names):
        return f"{fn.__qualname__} is called with {len(positional)} arguments"
    bindings = dict(zip(names, positional, strict=False))
    for key, value in keywords.items():
        if key in bindings or key not in names + kwonly:
            return f"{fn.__qualname__} cannot take the argument {key!r}"
        bindings[key] = value
    defaults = dict(zip(names[len(names) - len(fn.__defaults__ or ()):],
                        fn.__defaults__ or (), strict=True))
    defaults.update(fn.__kwdefaults__ or {})
    for name in names + kwonly:
        if name not in bindings:
            if name not in defaults:
                return f"{fn.__qualname__} is called without its argument {name!r}"
            bindings[name] = Frozen(defaults[name])
    return {name: bindings[name] for name in names + kwonly}


def _binding_key(binding):
    if isinstance(binding, Frozen):
        return ("frozen", id(binding.value))
    return ("params",) if binding == PARAMS else ("runtime",)
