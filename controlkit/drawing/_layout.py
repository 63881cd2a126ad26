"""Layered layout of a block diagram: columns, rows, ports, tracks and lanes.

:func:`layout` runs named stages in order. Each decides one thing, writes it into the
shared :class:`_Draft` and leaves the rest to the next stages:

1. :func:`_place_blocks` - each block's column and row (and the junctions of implicit sums);
2. :func:`_size_blocks` - each block's width and height, from its text and its ports;
3. :func:`_classify_nets` - each connection: to the next column, skipping columns, back, out;
4. :func:`_place_rows` - the y of each row, with room for feedback inside a frame;
5. :func:`_place_columns` - the x of each column and the width of the gaps between them;
6. :func:`_place_ports` - where each net leaves and enters a block, and
   :func:`_place_inputs` where each external input starts (:mod:`._routing`);
7. :func:`_place_tracks` and :func:`_place_lanes` - the vertical runs in the gaps and the
   horizontal runs above and below the rows (:mod:`._routing`);
8. :func:`_frame` - the title and the page's extent, as a :class:`DiagramLayout`.

Lengths are in inches (the figure is drawn one unit per inch, so text keeps its size in
points), x to the right, y up, row 0 at ``y = 0``.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import dataclass, field

from .._checks import warn_caller
from ._draft import _LANE_PITCH, _PORT_PITCH, _TRACK_PITCH, _Draft, _text_size
from ._graph import (
    _IN,
    _OUT,
    _base,
    _block_rank,
    _discrete,
    _kind,
    _nets,
    _require_interconnect,
    _shape,
    _signal_label,
    compress_signals,
    diagram_graph,
)
from ._ordering import _columns, _feedback_elements, _rows, _vertical_ok
from ._routing import _place_inputs, _place_lanes, _place_ports, _place_tracks


@dataclass(frozen=True)
class DiagramLayout:
    """Where everything of a block diagram goes, in inches: what the renderer draws.

    Attributes
    ----------
    nodes : dict
        ``{block: node}``; a node dict holds ``shape`` (``"block"``, ``"group"``,
        ``"gain"``, ``"sum"``), ``label``/``math``/``sub`` (the texts), the centre
        ``x``, ``y`` and the size ``w``, ``h``, ``flip`` for a block drawn pointing back
        (a sensor in the feedback path) and ``spare_xy``/``unused_xy`` for loose ends.
    nets : list
        The drawn signals (``_graph._Net``), each with ``kinds`` (``{block: "next" |
        "skip" | "back"}``), ``out``, ``far`` and ``dangling`` (how it leaves the loop).
    layer, row : dict
        ``{block: column}``, ``{block: row}`` (row 0 the main path, others below).
    port_xy : dict
        ``{(net, block): (x, y)}`` where a net leaves its source block.
    in_xy : dict
        ``{(net, block): (x, y, side)}`` where it enters, and from which side.
    input_y : dict
        ``{net: y}`` where an external input starts (its name is written there), left of
        the first column.
    track_x : dict
        ``{(net, "exit") | (net, column): x}``: the vertical runs in the gaps.
    lane_top, lane_bottom : dict
        ``{net: y}``: horizontal runs above the rows (skips) and below them (feedback).
    local_nets : set
        Feedback inside one frame on one row, run under that row instead of the page.
    groups : dict
        ``{frame label: [blocks]}``, the frames to draw.
    graph : dict
        :func:`~controlkit.drawing.diagram_graph` of the system (loose ends).
    gap_x : dict
        ``{gap: x}``, the left edge of the gap left of each column (gap ``ncol`` the last).
    x_right : float
        Where signals leaving the loop end.
    fonts : tuple of float
        Sizes in points of signal labels, block names and second lines.
    title : str
        The title; ``title_math`` says whether it is TeX.
    y_title, x_mid : float
        The title's centre.
    width, height : float
        The page: the drawing and nothing around it (no bands added for proportions).
    y_top, y_bottom : float
        The page's top and bottom edges.
    omitted : str
        The declared outputs not drawn as arrows (the ``outputs`` hint leaves them out),
        as a label (``"u, q, mu"``), written under the drawing at ``y_omitted``; ``""``
        when every output is drawn.
    y_omitted : float
    """

    nodes: dict
    nets: list
    layer: dict
    row: dict
    port_xy: dict
    in_xy: dict
    input_y: dict
    track_x: dict
    lane_top: dict
    lane_bottom: dict
    local_nets: set
    groups: dict
    graph: dict
    gap_x: dict
    x_right: float
    fonts: tuple[float, float, float]
    title: str
    title_math: bool
    y_title: float
    x_mid: float
    width: float
    height: float
    y_top: float
    y_bottom: float
    omitted: str = ""
    y_omitted: float = 0.0


@dataclass
class _Hints:
    """How the diagram is asked to look: ``sys.drawing_hints`` merged with the arguments.

    ``labels`` (display names, TeX: the hints', then blocks' ``display_name``, then the
    ``labels`` argument), ``groups`` (frames), ``beside`` (``{block: other}``: share a
    column), ``rows`` (``{block: row}``), ``notes`` (second lines), ``sums``
    (``{block: {input: sign}}``: the hints', then blocks' ``junction``), ``title`` and
    ``outputs`` (the declared outputs drawn as arrows; None: all).
    """

    labels: dict
    groups: dict
    beside: dict = field(default_factory=dict)
    rows: dict = field(default_factory=dict)
    notes: dict = field(default_factory=dict)
    sums: dict = field(default_factory=dict)
    title: str | None = None
    outputs: list | None = None

    @classmethod
    def of(cls, sys, labels, groups):
        """The hints of ``sys``, with the ``labels`` and ``groups`` arguments on top."""
        hints = dict(getattr(sys, "drawing_hints", None) or {})
        merged_labels = dict(hints.get("labels", {}))
        for s in sys.syslist:
            if getattr(s, "display_name", None):
                merged_labels.setdefault(s.name, s.display_name)
        merged_labels.update(labels or {})
        merged_labels = {block: _drawable(block, text) for block, text in merged_labels.items()}
        merged_groups = dict(hints.get("groups", {}))
        merged_groups.update(groups or {})
        sums = dict(hints.get("sums", {}))
        for s in sys.syslist:
            if getattr(s, "junction", None):
                sums.setdefault(s.name, dict(s.junction))
        return cls(merged_labels, merged_groups, dict(hints.get("beside", {})),
                   dict(hints.get("rows", {})), dict(hints.get("notes", {})),
                   sums, hints.get("title"), hints.get("outputs"))


def _drawable(block, label):
    """``label`` as matplotlib can draw it: TeX its mathtext cannot read (``$\\frac{$`` from
    a shared file) is drawn as its text, with a warning naming the block."""
    if not isinstance(label, str) or label.count("$") - label.count(r"\$") < 2:
        return label
    from matplotlib.mathtext import MathTextParser

    try:
        MathTextParser("path").parse(label)
    except (ValueError, RecursionError) as error:
        said = (str(error).strip().splitlines() or [type(error).__name__])[-1][:80]
        warn_caller(f"the label {label[:40]!r} of block {block!r} is not TeX matplotlib can "
                    f"draw ({said}); it is drawn as its text")
        return label.replace("$", r"\$")
    return label


def layout(sys, *, labels=None, groups=None, fontsize=10.0, title=None) -> DiagramLayout:
    """Place every block, port, track and lane of ``sys``'s diagram, in inches.

    Returns the :class:`DiagramLayout` that :func:`~controlkit.drawing.draw_block_diagram`
    draws. The arguments are those of ``draw_block_diagram``.
    """
    _require_interconnect(sys)
    hints = _Hints.of(sys, labels, groups)
    draft = _Draft(fonts=(fontsize, fontsize + 2, fontsize - 0.5), graph=diagram_graph(sys),
                   groups=hints.groups)
    _place_blocks(draft, sys, hints)
    _size_blocks(draft)
    _classify_nets(draft, sys, _shown_outputs(sys, hints.outputs))
    _place_rows(draft)
    _place_columns(draft)
    _place_ports(draft)
    _place_inputs(draft)
    _place_tracks(draft)
    _place_lanes(draft)
    return _frame(draft, sys, title, hints.title)


# ----------------------------------------------------------------------------- the stages

def _blocks(sys, hints):
    """A node for each block of ``sys`` with its shape and texts, and the blocks' order
    (:func:`._graph._block_rank`: the wiring's, whatever the order of ``sys.syslist``)."""
    nodes, order = {}, _block_rank(sys)
    for s in sorted(sys.syslist, key=lambda s: order[s.name]):
        shape, extra = _shape(s)
        label = hints.labels.get(s.name)
        nodes[s.name] = {"shape": shape, "signs": extra if shape == "sum" else {},
                         "gain": extra if shape == "gain" else None,
                         "discrete": _discrete(s),
                         "label": label if label is not None else s.name,
                         "math": label is not None, "virtual": False,
                         "sub": hints.notes.get(s.name) or (
                             (f"{s.name}, {_kind(s)}" if _kind(s) != "static" else s.name)
                             if label is not None else _kind(s))}
    return nodes, order


def _place_blocks(draft, sys, hints):
    """Decide each block's column and row: the diagram's reading order.

    Columns follow the signal (longest path without the feedback edges, see
    :func:`._ordering._columns`), so forward arrows point right; row 0 is the longest
    chain of neighbouring columns and parallel branches go below it. A block at the end
    of the main row that only feeds back (a sensor) moves under the block feeding it, as
    textbooks draw a feedback path. The nets are made here too, because a sum that the
    connection map or ``hints.sums`` implies becomes a junction node with a place of its
    own. Sets ``nodes``, ``nets``, ``layer`` (columns numbered without gaps) and ``row``.
    """
    nodes, order = _blocks(sys, hints)
    nets, _ = _nets(sys, nodes, hints.sums)
    for n in nodes:
        order.setdefault(n, len(order))
    layer, entries = _columns(nodes, nets, hints.beside)
    row = _rows(nodes, nets, layer, entries, order, hints.rows)
    for n, feeder in _feedback_elements(nodes, nets, layer, row, entries).items():
        # a sensor or gain in the feedback path: under its feeder, pointing back
        nodes[n]["flip"], nodes[n]["feeder"] = True, feeder
        layer[n] = layer[feeder]
        row[n] = max(row[m] for m in nodes if layer[m] == layer[n] and m != n) + 1
    used = sorted(set(layer.values()))
    draft.nodes, draft.nets, draft.row = nodes, nets, row
    draft.layer = {n: used.index(c) for n, c in layer.items()}


def _size_blocks(draft):
    """Decide each block's width ``w`` and height ``h`` (and a gain's ``text``).

    A block is as wide as its name (bold) or its second line, plus a margin, and tall
    enough for both lines and for its ports one pitch apart,
    ``h = max(text + 0.3, 0.34 * max(inputs, outputs, 1) + 0.15)``, so arrows never
    crowd. A junction is a circle of diameter 0.4; a gain's triangle grows with its text.
    A loose end counts as a port, since it is drawn as one.
    """
    f_sig, f_name, f_sub = draft.fonts
    pitch = _PORT_PITCH
    n_in, n_out = defaultdict(int), defaultdict(int)
    for net in draft.nets:
        if net.src in draft.nodes:
            n_out[net.src] += 1
        for b, _, _ in net.dests:
            if b in draft.nodes:
                n_in[b] += 1
    for n in draft.graph["unconnected_inputs"]:
        n_in[n] += 1
    for n in draft.graph["unused_outputs"]:
        n_out[n] += 1
    for n, node in draft.nodes.items():
        if node["shape"] == "sum":
            node["w"] = node["h"] = 0.4
            continue
        tw, th = _text_size(node["label"] if node["math"] else node["label"].replace("$", "S"),
                            f_name, node["math"], "bold")
        if node["shape"] == "gain":
            text = node["label"] if node["math"] else (node["gain"] or node["label"])
            node["text"] = text
            tw, th = _text_size(text, f_name, node["math"])
            node["w"] = max(0.7, tw + 0.5)
            node["h"] = max(0.6, tw * 0.6 + 0.3, pitch * max(n_in[n], n_out[n]) + 0.1)
            continue
        sw, sh = _text_size(node["sub"], f_sub)
        node["w"] = max(1.0, tw + 0.35, sw + 0.3)
        node["h"] = max(th + sh + 0.3, pitch * max(n_in[n], n_out[n], 1) + 0.15)


def _classify_nets(draft, sys, shown):
    """Decide how each net runs: its ``kinds`` and whether it leaves the loop.

    A destination in the next column (or a sensor fed by its block) is ``"next"`` (a
    short arrow), one further right ``"skip"`` (a lane above the rows), one to the left
    or in the same column ``"back"`` (feedback, a lane below). Every declared output in
    ``shown`` (all of them unless the ``outputs`` hint chooses) leaves the loop: from the
    last column on the right (``out``); from further left as a short grey stub
    (``dangling``) if the signal goes nowhere else, or, if it feeds blocks too, along a
    top lane to the right (``far``), where a reader looks for the results. Outputs not
    shown are listed under the drawing (``omitted``). Nets that go nowhere are dropped.
    """
    nodes, layer = draft.nodes, draft.layer

    def kind_of(net, b):
        ls = layer[net.src] if net.src in nodes else -1
        if layer[b] == ls + 1 or nodes[b].get("feeder") == net.src:
            return "next"
        return "skip" if layer[b] > ls + 1 else "back"

    last = draft.ncol - 1
    for net in draft.nets:
        internal = [b for b, _, _ in net.dests if b != _OUT]
        net.out_ports = [p for b, ports, _ in net.dests if b == _OUT for p in ports
                         if p in shown]
        net.out = bool(net.out_ports)
        net.far = net.out and bool(internal) and layer.get(net.src, -1) != last
        net.dests = [d for d in net.dests if d[0] != _OUT]
        net.dangling = not net.dests and net.out and layer.get(net.src, -1) != last
        net.kinds = {b: kind_of(net, b) for b, _, _ in net.dests}
    draft.nets = [n for n in draft.nets if n.dests or n.out]
    draft.omitted = [label for label in sys.output_labels if label not in shown]


def _shown_outputs(sys, hint):
    """The declared outputs drawn as arrows: all, or those the ``outputs`` hint names
    (labels, or base names for every element: ``"h"`` is ``h[0], h[1]``).

    Like the other hints, names of signals the diagram no longer has (a rewired loop
    keeps its builder's hints) are passed over, and a hint that names none of its
    outputs draws them all: a hint never hides every output.
    """
    hint = [hint] if isinstance(hint, str) else list(hint or [])
    shown = {label for label in sys.output_labels if label in hint or _base(label) in hint}
    return shown or set(sys.output_labels)


def _place_rows(draft):
    """Decide the y of each row: ``y_row`` and the frame-local feedback lanes ``local``.

    Row 0 is at ``y = 0``; each next row sits below the one above with 0.55 in between
    their tallest blocks. Feedback inside one frame and one row runs in a lane just under
    that row (so the frame can enclose it), and those lanes widen the space under their
    row by ``0.3 + 0.22`` per lane.
    """
    nodes, row, local = draft.nodes, draft.row, draft.local
    row_ids = sorted(set(row.values()))
    row_h = {r: max(nodes[n]["h"] for n in nodes if row[n] == r) for r in row_ids}
    for net in draft.nets:
        ends = [net.src] + list(net.kinds)
        if ("back" in net.kinds.values() and draft.inner(net) == 0
                and len({row.get(e) for e in ends}) == 1):
            local[row[net.src]].append(net)
    draft.y_row = {row_ids[0]: 0.0}
    for above, r in zip(row_ids[:-1], row_ids[1:], strict=True):
        room = 0.3 + _LANE_PITCH * len(local[above]) if local[above] else 0.0
        draft.y_row[r] = draft.y_row[above] - (row_h[above] / 2 + 0.55 + room + row_h[r] / 2)


def _fill_gaps(draft):
    """Decide what each gap between columns holds: labels and vertical tracks.

    Gap ``c`` is left of column ``c``. It holds the labels of the signals leaving column
    ``c - 1`` (a loop output of the last column is labelled where it leaves instead, one
    leaving along a top lane at both ends), the red notes of loose
    ends, an exit track for each net of column ``c - 1`` that branches, changes row or
    leaves along a lane (a flipped block's, in the gap on its left), and an entry track
    for each lane arriving at a block of column ``c`` from its side (a junction fed from
    above or below needs none).
    """
    nodes, layer, row = draft.nodes, draft.layer, draft.row
    f_sig, _, f_sub = draft.fonts
    label_w, exits, entries = draft.label_w, draft.exits, draft.entries
    for net in draft.nets:
        src_col = layer[net.src] if net.src in nodes else -1
        w, _ = _text_size(net.label, f_sig)
        flip = nodes.get(net.src, {}).get("flip", False)
        if net.src in nodes and not nodes[net.src]["virtual"] and not flip and not (
                net.out and not net.dangling and not net.far):  # labelled where it leaves
            label_w[src_col + 1] = max(label_w[src_col + 1], w + 0.2)
        if net.dangling:
            continue
        needs_track = (len(net.dests) > 1 or net.out and net.dests
                       or any(k != "next" for k in net.kinds.values()))
        if needs_track or net.src in nodes and any(
                row[b] != row[net.src] for b in net.kinds):
            exits[src_col if flip else src_col + 1].append(net)
        for b, k in net.kinds.items():
            if k in ("skip", "back") and not (nodes[b]["shape"] == "sum" and
                                              _vertical_ok(b, k, nodes, layer, row)):
                key = (net, layer[b])
                if key not in entries[layer[b]]:
                    entries[layer[b]].append(key)
    for n, ports in draft.graph["unconnected_inputs"].items():
        w, _ = _text_size("unconnected: " + ", ".join(compress_signals(ports)), f_sub)
        label_w[layer[n]] = max(label_w[layer[n]], w + 0.6)
    for n, ports in draft.graph["unused_outputs"].items():
        w, _ = _text_size("unused: " + ", ".join(compress_signals(ports)), f_sub)
        label_w[layer[n] + 1] = max(label_w[layer[n] + 1], w + 0.3)


def _place_columns(draft):
    """Decide the x of each column and gap: ``gap_x``, ``x_right`` and the blocks' centres.

    A column is as wide as its widest block. A gap is as wide as what :func:`_fill_gaps`
    put in it, ``max(0.6, labels + 0.4 + 0.17 * tracks)``, so a label never meets a track.
    """
    _fill_gaps(draft)
    nodes, layer, ncol = draft.nodes, draft.layer, draft.ncol
    label_w, exits, entries = draft.label_w, draft.exits, draft.entries
    col_w = [max(nodes[n]["w"] for n in nodes if layer[n] == c) for c in range(ncol)]
    gap_w = {g: max(0.6, label_w[g] + 0.4 + _TRACK_PITCH * (len(exits[g]) + len(entries[g])))
             for g in range(ncol + 1)}
    x_col, x = {}, 0.0
    for c in range(ncol):
        draft.gap_x[c] = x
        x += gap_w[c]
        x_col[c] = x + col_w[c] / 2
        x += col_w[c]
    draft.gap_x[ncol] = x
    draft.x_right = x + gap_w[ncol]
    for n, node in nodes.items():
        node["x"], node["y"] = x_col[layer[n]], draft.y_row[draft.row[n]]


def _frame(draft, sys, title, hint_title):
    """Decide the title and the page: the finished :class:`DiagramLayout`.

    The page spans the lanes, the blocks and the names of the signals entering on the
    left and leaving on the right, with the title above, and nothing more: a wide loop
    is a wide picture (padding it to a slide's proportions would only add blank bands).
    A title given as an argument or a hint is TeX; the system's own name is drawn
    literally.
    """
    f_sig, f_name, f_sub = draft.fonts
    top_rows, bottom_rows = draft.blocks_top(), draft.blocks_bottom()
    title_math = title is not None or bool(hint_title)  # the system's own name is literal
    title = title if title is not None else hint_title or sys.name
    y_top = (max(draft.lane_top.values()) if draft.lane_top
             else top_rows + draft.frame_pad) + 0.25
    y_bottom = min([bottom_rows] + list(draft.lane_bottom.values())) - 0.2
    x_left = -max([_text_size(n.label, f_sig)[0] + 0.1 for n in draft.nets if n.src == _IN]
                  + [0])
    x_right_text = draft.x_right + max([_text_size(n.label, f_sig)[0] + 0.1 for n in draft.nets
                                        if n.out and not n.dangling] + [0])
    tw, th = _text_size(title, f_name + 1, title_math and title.count("$") >= 2)
    y_title = y_top + th * 0.6
    y_top = y_title + th * 0.6
    sizes = Counter(_base(label) for label in sys.output_labels)
    omitted = f"also outputs: {_signal_label(draft.omitted, sizes)}" if draft.omitted else ""
    nw = _text_size(omitted, f_sub)[0] + 0.4 if omitted else 0.0
    y_omitted = y_bottom - 0.1
    if omitted:  # a line under the drawing names the outputs drawn nowhere else
        y_bottom -= 0.3
    width = max(x_right_text - x_left, tw + 0.4, nw) + 0.3
    height = y_top - y_bottom + 0.2
    # no blank bands to reach a slide's proportions: a wide diagram stays wide, and a slide
    # or a notebook scales it to its width
    x_mid = (x_left + x_right_text) / 2
    return DiagramLayout(
        nodes=draft.nodes, nets=draft.nets, layer=draft.layer, row=draft.row,
        port_xy=draft.port_xy, in_xy=draft.in_xy, input_y=draft.input_y,
        track_x=draft.track_x,
        lane_top=draft.lane_top, lane_bottom=draft.lane_bottom, local_nets=draft.local_nets,
        groups=draft.groups, graph=draft.graph, gap_x=draft.gap_x, x_right=draft.x_right,
        fonts=draft.fonts, title=title, title_math=title_math, y_title=y_title, x_mid=x_mid,
        width=width, height=height, y_top=y_top, y_bottom=y_bottom, omitted=omitted,
        y_omitted=y_omitted)
