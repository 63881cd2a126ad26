"""Drawing any ``control.InterconnectedSystem`` as a block diagram, with matplotlib only.

The picture is read off python-control's own connection matrices, so it
shows what the simulation will do, not what the author meant. It is drawn the
way control papers draw loops:

- blocks in columns in signal order (a layered, Sugiyama-style layout: feedback
  edges found by a depth-first search from the external inputs, columns by
  longest path), the longest chain of blocks on one row and parallel branches
  on rows below it;
- one line per signal: a signal that feeds several blocks is one line that
  branches (a dot marks each branch point), labelled once where it leaves its
  block; feedback runs in lanes under the diagram, signals that skip columns
  in lanes above it;
- python-control's ``summing_junction`` blocks, and inputs that the connection
  map sums (two sources with gains +-1 on one port), as circles with signs;
  static single-input gains as triangles; a nested interconnect as one block
  with a double frame;
- display names (``$L_a$``), frames around groups of blocks and a parallel
  placement (``beside``) taken from the ``labels``/``groups`` arguments, from a
  ``drawing_hints`` dict that the diagram builders attach to the interconnect,
  or from a block's own ``display_name`` and ``junction`` attributes (the papers'
  blocks carry their symbols: :func:`controlkit.blocks.contract.drawn_as`), so a
  block is drawn as itself in any diagram, and a block of your own by its name.

Block and signal names are drawn literally (python-control's ``plant$sampled``
stays as it is); only labels given explicitly as display names are TeX.
Unconnected inputs and unused outputs are marked in red. No Graphviz or other
system package is needed.
"""

from ._draw import draw_block_diagram
from ._graph import compress_signals, diagram_graph

__all__ = ["compress_signals", "diagram_graph", "draw_block_diagram"]

for _public in (compress_signals, diagram_graph, draw_block_diagram):
    _public.__module__ = __name__  # documented (and checked) as controlkit.drawing's own
del _public
