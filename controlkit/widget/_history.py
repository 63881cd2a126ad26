"""Undo and redo: the diagram as it was before each edit.

A :func:`snapshot` keeps what an edit can change - blocks (their systems are shared:
an edit replaces a block's system, never changes it), wires, external signals, hints,
the run's setup and positions - so that :func:`restore` puts the model back exactly.
:class:`History` is the two stacks behind Ctrl+Z and Ctrl+Shift+Z.
"""

from __future__ import annotations

import copy
from dataclasses import replace

#: The model's fields an edit may change.
FIELDS = ("name", "wires", "inputs", "outputs", "summed", "hints", "horizon", "sources",
          "initial", "source_name")


def snapshot(model):
    """The state of ``model`` that :func:`restore` brings back."""
    state = {name: copy.deepcopy(getattr(model, name)) for name in FIELDS}
    state["blocks"] = {n: replace(b, look=copy.deepcopy(b.look))
                       for n, b in model.blocks.items()}
    return state


def restore(model, state):
    """Put ``model`` back as it was when ``state`` was taken."""
    for name in FIELDS:
        setattr(model, name, copy.deepcopy(state[name]))
    model.blocks = {n: replace(b, look=copy.deepcopy(b.look))
                    for n, b in state["blocks"].items()}


class History:
    """The edits that can be undone and redone, at most ``depth`` of each.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.widget import DiagramModel
    >>> lag = ct.ss(-1.0, 1.0, 1.0, 0.0, name="lag", inputs="u", outputs="y")
    >>> model = DiagramModel.from_interconnect(ct.interconnect([lag], inputs="u",
    ...                                                        outputs="y"))
    >>> history = History()
    >>> history.record(model)
    >>> model.delete_block("lag")
    >>> history.undo(model), list(model.blocks)
    (True, ['lag'])
    >>> history.redo(model), list(model.blocks)
    (True, [])
    """

    def __init__(self, depth=200):
        self.depth = depth
        self.done, self.undone = [], []

    def record(self, model):
        """Call before an edit: the state to go back to."""
        self.done.append(snapshot(model))
        del self.done[:-self.depth]
        self.undone.clear()

    def forget(self, model):
        """The edit recorded last failed: put the model back as it was, drop the entry."""
        if self.done:
            restore(model, self.done.pop())

    def undo(self, model):
        """Go back one edit; False when there is nothing to undo."""
        if not self.done:
            return False
        self.undone.append(snapshot(model))
        restore(model, self.done.pop())
        return True

    def redo(self, model):
        """Do again the edit undone last; False when there is nothing to redo."""
        if not self.undone:
            return False
        self.done.append(snapshot(model))
        restore(model, self.undone.pop())
        return True
