"""Reading a user's ``(t, x, u, params)`` function from its source.

What a function reads can only be known from its source: which ``params`` keys (for the
``params`` check every backend makes), whether it reads ``u`` (its feedthrough), and the
statements the fast engine compiles. A function written as python-control's examples and
course notebooks write them (docs/fast-blocks.md, *Writing a function that compiles*)
becomes a :class:`Plan`: its statements with every read of the run-time ``params`` in one
canonical form, the helpers it calls (planned the same way) and the values it reads from
outside (its module, its closure, the objects it was bound to), which the compiler freezes.

Anything else is recorded, not guessed: a ``params`` use not understood makes the keys read
unknown (the ``params`` check then accepts every key, as python-control does) and the
function not compilable, with the reason.
"""

from .effects import draws, params_changed, side_effect
from .plan import Plan, plan_function, reads_input, used_params
from .reading import PARAM_READ, NotCompilable
from .rewrites import copy_tree, function_def, walk
from .translator import as_written

__all__ = ["PARAM_READ", "NotCompilable", "Plan", "as_written", "copy_tree", "draws",
           "function_def", "params_changed", "plan_function", "reads_input", "side_effect",
           "used_params", "walk"]
