"""A block-diagram editor for any python-control interconnect, in the notebook.

:class:`DiagramEditor` (needs ``pip install "controlkit[widget]"``) shows an
interconnect as a block diagram to rewire with the mouse; :class:`DiagramModel`
is the diagram as plain data, with the checks and the code writer, usable
without a notebook.
"""

from ._model import PROBLEM_KINDS, DiagramModel, Problem, passes_input
from ._palette import PALETTE

__all__ = ["PALETTE", "PROBLEM_KINDS", "DiagramEditor", "DiagramModel", "Problem",
           "passes_input"]


def __getattr__(name):
    if name == "DiagramEditor":
        try:
            from ._editor import DiagramEditor
        except ImportError as error:  # anywidget is an optional dependency
            raise ImportError('controlkit.widget.DiagramEditor needs anywidget: '
                              'pip install "controlkit[widget]"') from error
        return DiagramEditor
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
