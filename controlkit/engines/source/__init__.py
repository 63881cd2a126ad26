"""Reading a user's ``(t, x, u, params)`` function from its source.

What a function reads can only be known from its source: which ``params`` keys
(for the ``params`` check every backend makes), whether it reads ``u`` (its
feedthrough, for the fast engine's evaluation order), and the statements the fast
engine compiles. This package turns a function written as python-control's examples and
course notebooks write them (the idioms understood are listed in docs/fast-blocks.md,
*Writing a function that compiles*) into a :class:`Plan`: its statements with every read
of the run-time ``params`` in one canonical form, the helper functions it calls
(planned the same way, transitively) and the values it reads from outside (its
module, its closure, the objects it was bound to), which the compiler freezes.

Anything else is recorded, not guessed: a ``params`` use that is not understood
makes the keys read unknown (the ``params`` check then accepts every key, as
python-control does) and the function not compilable, with the reason.

The package's rooms: :mod:`.reading` (a function's own source, what a call runs, how it
binds the arguments), :mod:`.plan` (:class:`Plan`, :func:`plan_function` and the
questions :func:`used_params`, :func:`reads_input` and :func:`side_effect`),
:mod:`.translator` with its part :mod:`.outside` (names, objects and helper functions read
from outside), :mod:`.rewrites` (syntax trees, loops over keys written out),
:mod:`.values` (which values can be frozen, and whether they changed).
"""

from .plan import Plan, plan_function, reads_input, side_effect, used_params
from .reading import PARAM_READ, NotCompilable
from .rewrites import copy_tree, function_def, walk

__all__ = ["PARAM_READ", "NotCompilable", "Plan", "copy_tree", "function_def", "plan_function",
           "reads_input", "side_effect", "used_params", "walk"]
