"""The state the layout stages share, the text measure and the spacings they agree on."""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

_PORT_PITCH = 0.34   # between two ports on a block's side (inches)
_TRACK_PITCH = 0.17  # between two vertical tracks in a gap (inches)
_LANE_PITCH = 0.22   # between two horizontal lanes (inches)
_INPUT_PITCH = 0.25  # between the starts of two external inputs, whose names stand there


def _text_size(text, size, math=False, weight="normal"):
    """Width and height of ``text`` in inches."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import text_to_path

    prop = FontProperties(size=size, weight=weight)
    lines = text.split("\n")
    w = max(text_to_path.get_text_width_height_descent(line, prop, ismath=bool(math))[0]
            for line in lines)
    return float(w) / 72.0, len(lines) * size * 1.25 / 72.0


@dataclass
class _Draft:
    """A diagram being laid out: each stage of :func:`._layout.layout` fills its fields.

    Given: ``fonts`` (points: signal labels, block names, second lines), ``graph``
    (:func:`~controlkit.drawing.diagram_graph`, for the loose ends) and ``groups``
    (``{frame label: [blocks]}``).

    Decided by, in order:

    - ``_place_blocks``: ``nodes`` (``{block: node dict}``; later stages add its size and
      place), ``nets``, ``layer`` (``{block: column}``) and ``row``;
    - ``_classify_nets``: each net's kinds and exits, and ``omitted`` (the declared
      outputs not drawn as arrows);
    - ``_place_rows``: ``y_row`` (``{row: y}``) and ``local`` (``{row: [feedback nets
      inside one frame on that row]}``, run in a lane just under the row);
    - ``_place_columns``: ``label_w`` (``{gap: width of its labels}``), ``exits``
      (``{gap: [nets]}`` leaving along a track there), ``entries`` (``{gap: [(net,
      column)]}`` arriving along one), ``gap_x`` (``{gap: left edge}``) and ``x_right``;
    - ``_place_ports``: ``port_xy`` and ``in_xy``; ``_place_inputs``: ``input_y``;
    - ``_place_tracks``: ``track_x``; ``_place_lanes``: ``lane_top``, ``lane_bottom`` and
      ``local_nets``.

    Gap ``c`` is the space left of column ``c``; gap ``ncol`` is right of the last column.
    """

    fonts: tuple[float, float, float]
    graph: dict
    groups: dict
    nodes: dict = field(default_factory=dict)
    nets: list = field(default_factory=list)
    layer: dict = field(default_factory=dict)
    row: dict = field(default_factory=dict)
    y_row: dict = field(default_factory=dict)
    local: defaultdict = field(default_factory=lambda: defaultdict(list))
    label_w: defaultdict = field(default_factory=lambda: defaultdict(float))
    exits: defaultdict = field(default_factory=lambda: defaultdict(list))
    entries: defaultdict = field(default_factory=lambda: defaultdict(list))
    gap_x: dict = field(default_factory=dict)
    x_right: float = 0.0
    port_xy: dict = field(default_factory=dict)
    in_xy: dict = field(default_factory=dict)
    track_x: dict = field(default_factory=dict)
    lane_top: dict = field(default_factory=dict)
    lane_bottom: dict = field(default_factory=dict)
    local_nets: set = field(default_factory=set)
    omitted: list = field(default_factory=list)
    input_y: dict = field(default_factory=dict)

    def __post_init__(self):
        self._frame_of = {}  # block -> the first frame that lists it
        for glabel, members in self.groups.items():
            for m in members:
                self._frame_of.setdefault(m, glabel)

    @property
    def ncol(self):
        """The number of columns."""
        return max(self.layer.values()) + 1

    @property
    def frame_pad(self):
        """Room above the rows for the frames' labels (none without frames)."""
        return 0.45 if self.groups else 0.0

    def inner(self, net):
        """0 for a net whose ends are all in one frame (its lanes go nearest), else 1."""
        ends = [net.src] + list(net.kinds)
        f = {self._frame_of.get(e) for e in ends}
        return 0 if len(f) == 1 and None not in f else 1

    def blocks_top(self):
        """The top edge of the highest block."""
        return max(node["y"] + node["h"] / 2 for node in self.nodes.values())

    def blocks_bottom(self):
        """The bottom edge of the lowest block."""
        return min(node["y"] - node["h"] / 2 for node in self.nodes.values())

    def source_y(self, net):
        """The y of the block a net comes from (0 for an external input)."""
        return self.nodes[net.src]["y"] if net.src in self.nodes else 0.0

    def towards(self, net):
        """Where a net heads to, for ordering ports top to bottom (lanes outermost)."""
        ys = []
        for b, k in net.kinds.items():
            ys.append(+1e3 if k == "skip" else -1e3 if k == "back" else self.nodes[b]["y"])
        return max(ys) if ys else self.nodes[net.src]["y"]

    def span(self, net):
        """The horizontal distance a net covers; shorter lanes go nearer the blocks."""
        xs = [self.nodes[b]["x"] for b in net.kinds] + [
            self.nodes[net.src]["x"] if net.src in self.nodes else 0.0]
        return max(xs) - min(xs)
