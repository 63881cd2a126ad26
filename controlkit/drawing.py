"""Drawing any ``control.InterconnectedSystem`` as a block diagram, with matplotlib only.

The picture is read off python-control's own connection matrices, so it
shows what the simulation will do, not what the author meant: one box per
subsystem, an arrow per connected pair of blocks labelled with its signals
(``q[0..3]`` for a vector), external inputs entering on the left, outputs
leaving on the right, feedback paths routed under the diagram, and unconnected
ports marked in red. It needs no Graphviz or other system package.
"""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

import control as ct
import numpy as np

_IN, _OUT = "inputs", "outputs"


def compress_signals(names) -> list[str]:
    """Shorten runs of indexed signals: ``q[0], q[1], q[2]`` -> ``q[0..2]``.

    Examples
    --------
    >>> compress_signals(["q[0]", "q[1]", "q[2]", "u[0]", "T1"])
    ['q[0..2]', 'u[0]', 'T1']
    """
    out, pending = [], None  # pending = (base, first, last)
    for name in names:
        m = re.fullmatch(r"(.*)\[(\d+)\]", name)
        if m and pending and m.group(1) == pending[0] and int(m.group(2)) == pending[2] + 1:
            pending = (pending[0], pending[1], int(m.group(2)))
            continue
        if pending:
            out.append(_indexed(*pending))
            pending = None
        if m:
            pending = (m.group(1), int(m.group(2)), int(m.group(2)))
        else:
            out.append(name)
    if pending:
        out.append(_indexed(*pending))
    return out


def _indexed(base, first, last):
    return f"{base}[{first}]" if first == last else f"{base}[{first}..{last}]"


def diagram_graph(sys):
    """The connection structure of an interconnect, as plain data.

    Returns
    -------
    dict
        ``blocks`` (names), ``edges`` (``{(source, target): [signal, ...]}`` with
        sources and targets block names or ``"inputs"``/``"outputs"``),
        ``unconnected_inputs`` and ``unused_outputs`` (``{block: [port, ...]}``).

    Examples
    --------
    >>> from controlkit.diagrams.spacecraft import output_zeroing_loop
    >>> g = diagram_graph(output_zeroing_loop())
    >>> g["edges"][("plant", "output")]
    ['q[0]', 'q[1]', 'q[2]', 'q[3]']
    """
    if not isinstance(sys, ct.InterconnectedSystem):
        raise ValueError(
            f"sys must be a control.InterconnectedSystem (built with control.interconnect), "
            f"got {type(sys).__name__}"
        )
    out_owner, in_owner = [], []
    for s in sys.syslist:
        out_owner += [(s.name, label) for label in s.output_labels]
        in_owner += [(s.name, label) for label in s.input_labels]
    edges = defaultdict(list)
    unconnected = defaultdict(list)
    for i, (block, port) in enumerate(in_owner):
        sources = np.nonzero(sys.connect_map[i])[0]
        externals = np.nonzero(sys.input_map[i])[0]
        for j in sources:
            gain = sys.connect_map[i, j]
            name = out_owner[j][1]
            edges[(out_owner[j][0], block)].append(name if gain == 1 else f"{gain:g}*{name}")
        for e in externals:
            edges[(_IN, block)].append(sys.input_labels[e])
        if not len(sources) and not len(externals):
            unconnected[block].append(port)
    nsub = len(out_owner)
    unused = defaultdict(list)
    for j, (block, port) in enumerate(out_owner):
        rows = np.nonzero(sys.output_map[:, j])[0]
        for r in rows:
            edges[(block, _OUT)].append(sys.output_labels[r])
        if not sys.connect_map[:, j].any() and not len(rows):
            unused[block].append(port)
    for r, row in enumerate(sys.output_map):  # outputs taken from subsystem inputs
        for j in np.nonzero(row[nsub:])[0]:
            edges[(in_owner[j][0], _OUT)].append(sys.output_labels[r])
    return {"blocks": [s.name for s in sys.syslist], "edges": dict(edges),
            "unconnected_inputs": dict(unconnected), "unused_outputs": dict(unused)}


def _layers(nodes, edges, entries=()):
    """Longest-path layers after removing the back edges of a depth-first search.

    The search starts where the signals enter (``entries``, the blocks fed by external
    inputs), then at blocks nothing feeds: the diagram reads from the reference on.
    """
    succ = defaultdict(list)
    indeg = defaultdict(int)
    for (a, b) in edges:
        if a != b:
            succ[a].append(b)
            indeg[b] += 1
    roots = list(entries) + [n for n in nodes if indeg[n] == 0 and n not in entries]
    state, back = {}, set()

    def visit(n):
        state[n] = 1
        for m in succ[n]:
            if state.get(m) == 1:
                back.add((n, m))
            elif m not in state:
                visit(m)
        state[n] = 2

    for n in roots + nodes:
        if n not in state:
            visit(n)
    forward = [(a, b) for (a, b) in edges if (a, b) not in back and a != b]
    layer = dict.fromkeys(nodes, 0)
    for _ in nodes:
        for a, b in forward:
            layer[b] = max(layer[b], layer[a] + 1)
    if _OUT in layer:
        layer[_OUT] = max(layer.values()) + (0 if layer[_OUT] > max(
            v for k, v in layer.items() if k != _OUT) else 1)
    return layer, back


def draw_block_diagram(sys, filename=None, *, ax=None, title=None):
    """Draw an interconnect as a block diagram.

    Blocks are placed left to right in signal order. Arrows between neighbours
    are straight; arrows that skip blocks run in lanes above the diagram and
    feedback paths (red) in lanes below it. External inputs and outputs are
    short labelled stubs; unconnected inputs and unused outputs are marked red.

    Parameters
    ----------
    sys : control.InterconnectedSystem
        Any interconnect (ours or your own).
    filename : str or pathlib.Path, optional
        Also save the picture; the suffix chooses the format (``.svg``, ``.png``,
        ``.pdf``). In SVG the text stays text, so names can be searched.
    ax : matplotlib.axes.Axes, optional
        Draw into these axes (default: a new figure sized to the diagram).
    title : str, optional
        Title (default: the system's name).

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from controlkit.diagrams.cmg import cmg_loop
    >>> fig = draw_block_diagram(cmg_loop())
    >>> "q1, q2, q4, w1, w2, w4" in [t.get_text() for t in fig.axes[0].texts]
    True
    """
    import matplotlib.pyplot as plt
    from matplotlib.patches import FancyBboxPatch

    graph = diagram_graph(sys)
    blocks, edges = graph["blocks"], graph["edges"]
    internal = {k: v for k, v in edges.items() if _IN not in k and _OUT not in k}
    entries = [b for (a, b) in edges if a == _IN]
    layer, back = _layers(blocks, internal, list(dict.fromkeys(entries)))
    systems = {s.name: s for s in sys.syslist}

    # columns in signal order; a column holds blocks that do not feed each other
    columns = defaultdict(list)
    for n in blocks:
        columns[layer[n]].append(n)
    labels = {k: ", ".join(compress_signals(v)) for k, v in edges.items()}
    gap = {c: 1.2 for c in columns}
    for (a, b), text in labels.items():
        if a in layer and b in layer and (a, b) not in back and layer[b] == layer[a] + 1:
            gap[layer[b]] = max(gap[layer[b]], 0.11 * len(text) + 0.6)
    width = {n: max(1.5, 0.14 * len(n) + 0.5) for n in blocks}
    box_h, row = 0.9, 1.8
    x_left, centre = 0.0, {}
    for c in sorted(columns):
        x_left += gap[c]
        col_w = max(width[n] for n in columns[c])
        for i, n in enumerate(columns[c]):
            centre[n] = (x_left + col_w / 2, -i * row)
        x_left += col_w

    # attachment points spread along each side
    ends = defaultdict(list)  # (block, side) -> keys
    for (a, b) in edges:
        if a in centre:
            ends[(a, +1)].append((a, b))
        if b in centre:
            ends[(b, -1)].append((a, b))

    def attach(n, side, key):
        keys = ends[(n, side)]
        k = keys.index(key)
        x, y = centre[n]
        return (x + side * width[n] / 2, y + box_h * 0.35 * (1 - 2 * (k + 0.5) / len(keys)))

    if ax is None:
        n_top = sum(1 for (a, b) in internal if (a, b) not in back
                    and layer[b] != layer[a] + 1)
        n_bottom = len(back)
        depth = max(len(col) for col in columns.values())
        fig, ax = plt.subplots(figsize=(max(6.0, 0.95 * x_left + 2.5),
                                        1.6 + 0.9 * depth + 0.42 * (n_top + n_bottom) + 0.8))
    else:
        fig = ax.figure
    line = {"linewidth": 1.3, "solid_capstyle": "butt"}

    def arrow(points, color):
        ax.plot(*zip(*points, strict=True), color=color, **line)
        ax.annotate("", xy=points[-1], xytext=points[-2],
                    arrowprops={"arrowstyle": "-|>", "color": color, "lw": 1.3,
                                "shrinkA": 0, "shrinkB": 0, "mutation_scale": 12})

    def label(x, y, text, color, va="bottom"):
        ax.text(x, y, text, ha="center", va=va, fontsize=8, color=color,
                bbox={"facecolor": "white", "edgecolor": "none", "pad": 0.8, "alpha": 0.9})

    def lane(start, end, y, inset, text, color):
        """An arrow out of ``start``, along the lane at height ``y``, into ``end``."""
        xa, xb = start[0] + inset, end[0] - inset
        arrow([start, (xa, start[1]), (xa, y), (xb, y), (xb, end[1]), end], color)
        label((xa + xb) / 2, y, text, color, va="center")

    top = max(y for _, y in centre.values()) + box_h / 2 + 0.95
    bottom = min(y for _, y in centre.values()) - box_h / 2 - 0.35
    up = down = 0
    for key, text in labels.items():
        a, b = key
        if a == _IN or b == _OUT:
            continue
        start, end = attach(a, +1, key), attach(b, -1, key)
        if key in back or a == b:  # feedback: lanes below, red
            down += 1
            lane(start, end, bottom - 0.42 * down, 0.25 + 0.08 * down, text, "#b03a2e")
        elif layer[b] == layer[a] + 1:  # neighbours: straight, or a step halfway
            xm = (start[0] + end[0]) / 2
            arrow([start, (xm, start[1]), (xm, end[1]), end], "#1f3b6e")
            label(xm, max(start[1], end[1]) + 0.05, text, "#1f3b6e")
        else:  # skips blocks: lanes above
            up += 1
            lane(start, end, top + 0.42 * (up - 1), 0.2 + 0.06 * up, text, "#1f3b6e")

    for key, text in labels.items():  # external inputs and outputs: labelled stubs
        a, b = key
        if a == _IN:
            end = attach(b, -1, key)
            arrow([(end[0] - 0.55, end[1]), end], "#333")
            ax.text(end[0] - 0.6, end[1], text, ha="right", va="center", fontsize=8,
                    style="italic")
        elif b == _OUT:
            x, y = centre[a]
            start = (x + width[a] / 4, y + box_h / 2)
            arrow([start, (start[0], start[1] + 0.4)], "#333")
            ax.text(start[0] + 0.06, start[1] + 0.22, text, ha="left", va="center", fontsize=8,
                    style="italic")

    for n in blocks:
        x, y = centre[n]
        w = width[n]
        ax.add_patch(FancyBboxPatch((x - w / 2, y - box_h / 2), w, box_h,
                                    boxstyle="round,pad=0.02,rounding_size=0.08", zorder=3,
                                    facecolor="#eef3fb", edgecolor="#1f3b6e", linewidth=1.4))
        s = systems[n]
        kind = ("static" if s.nstates == 0 else
                "continuous" if s.isctime(strict=True) else f"discrete, dt = {s.dt:g}")
        ax.text(x, y + 0.1, n, ha="center", va="center", fontsize=10, weight="bold", zorder=4)
        ax.text(x, y - 0.22, kind, ha="center", va="center", fontsize=7, color="#555",
                zorder=4)

    for ports, side in ((graph["unconnected_inputs"], -1), (graph["unused_outputs"], +1)):
        for n, names in ports.items():
            x, y = centre[n]
            x += side * width[n] / 2
            tip = (x + side * 0.4, y - box_h / 2 - 0.1)
            ax.plot([x, tip[0]], [y - box_h / 4, tip[1]], color="red", linewidth=1)
            ax.plot(*tip, marker="o", markerfacecolor="white", markeredgecolor="red", zorder=5)
            what = "unconnected" if side < 0 else "unused"
            ax.text(tip[0], tip[1] - 0.12, f"{what}: {', '.join(compress_signals(names))}",
                    ha="center", va="top", fontsize=7, color="red")

    ax.set_title(title if title is not None else sys.name)
    ax.set_aspect("equal")
    ax.axis("off")
    ax.autoscale_view()
    ax.margins(0.04)
    fig.tight_layout()
    if filename is not None:
        import matplotlib as mpl

        with mpl.rc_context({"svg.fonttype": "none"}):
            fig.savefig(Path(filename), bbox_inches="tight", dpi=120)
    return fig
