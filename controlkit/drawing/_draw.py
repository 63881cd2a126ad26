"""Rendering a laid-out block diagram with matplotlib."""

from __future__ import annotations

from collections import defaultdict
from pathlib import Path

import numpy as np

from ._graph import _BLUE, _FILL, _FILL_DISCRETE, _GREY, _RED, _kind, compress_signals
from ._layout import _text_size, layout


def draw_block_diagram(sys, filename=None, *, ax=None, title=None, labels=None, groups=None,
                       fontsize=10.0):
    """Draw an interconnect as a paper-style block diagram.

    Parameters
    ----------
    sys : control.InterconnectedSystem
        Any interconnect (ours or your own).
    filename : str or pathlib.Path, optional
        Also save the picture; the suffix chooses the format (``.svg``, ``.png``,
        ``.pdf``). In SVG the text stays text, so names can be searched.
    ax : matplotlib.axes.Axes, optional
        Draw into these axes (default: a new figure sized to the diagram, one
        inch per unit, so its text keeps its size in points).
    title : str, optional
        Title (default: the system's name).
    labels : dict, optional
        Display names by block name, e.g. ``{"plant": "$L_a$"}`` (TeX allowed); the
        block's own name is then written under it. Default: the builder's
        ``sys.drawing_hints["labels"]`` and blocks' ``display_name`` attributes.
    groups : dict, optional
        Frames to draw: ``{frame label: [block names]}``; default
        ``sys.drawing_hints["groups"]``.
    fontsize : float
        Size of signal labels in points; block names are 2 points larger.

    Returns
    -------
    matplotlib.figure.Figure

    Notes
    -----
    ``sys.drawing_hints`` may also hold ``title``, ``sums`` (``{block: {input: sign}}``:
    the block first adds these inputs, e.g. ``F (r - h)``; drawn as a junction in front
    of it; a block's own ``junction`` attribute, ``{input: sign}``, does the same for
    that block, wherever it is wired), ``beside`` (``{block: other}``: put
    ``block`` in the column of ``other``, on a row of its own - a branch in
    parallel), ``rows`` (``{block: row}``, 0 the main row), ``notes``
    (``{block: text}``, a second line inside the block) and ``outputs`` (the
    declared outputs to draw, by label or base name; the others are named in a line
    under the drawing). Every declared output (or each one ``outputs`` names) leaves
    the diagram on the right: straight from a block of the last column, along a lane
    above the rows from one further left that also feeds blocks.

    The layout never reads the order of ``sys.syslist``: the same loop listed in any
    order is drawn the same.

    Examples
    --------
    >>> import control as ct
    >>> motor = ct.tf2ss(ct.tf([1], [1, 1]), name="motor", inputs="v", outputs="w")
    >>> pi = ct.tf2ss(ct.tf([2, 1], [1, 0]), name="pi", inputs="e", outputs="v")
    >>> error = ct.summing_junction(inputs=["w_ref", "-w"], output="e", name="error")
    >>> loop = ct.interconnect([error, pi, motor], inputs="w_ref", outputs="w")
    >>> fig = draw_block_diagram(loop, labels={"pi": "$C(s)$"})
    >>> [t.get_text() for t in fig.axes[0].texts if t.get_text() in ("+", "\u2212")]
    ['+', '−']
    """
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, FancyBboxPatch, Polygon, Rectangle

    L = layout(sys, labels=labels, groups=groups, fontsize=fontsize, title=title)
    nodes, nets, layer = L.nodes, L.nets, L.layer
    port_xy, in_xy, track_x = L.port_xy, L.in_xy, L.track_x
    lane_top, lane_bottom, local_nets = L.lane_top, L.lane_bottom, L.local_nets
    groups, graph, gap_x, x_right = L.groups, L.graph, L.gap_x, L.x_right
    f_sig, f_name, f_sub = L.fonts
    title, title_math, y_title, x_mid = L.title, L.title_math, L.y_title, L.x_mid
    width, height, y_top, y_bottom = L.width, L.height, L.y_top, L.y_bottom
    kinds = {n.get("discrete") for n in nodes.values() if not n.get("virtual")
             and n["shape"] != "sum"}
    legend = len(kinds) == 2 and bool(getattr(sys, "rates", None))  # a sampled-data diagram
    if legend:  # a line under the drawing tells the shaded discrete blocks apart
        y_bottom -= 0.4
        height += 0.4
    if ax is None:
        fig = plt.figure(figsize=(width, height))
        ax = fig.add_axes((0, 0, 1, 1))
    else:
        fig = ax.figure
    ax.set_xlim(x_mid - width / 2, x_mid + width / 2)
    ax.set_ylim(y_bottom - 0.1, y_top + 0.1)
    ax.set_aspect("equal")
    ax.axis("off")

    line = {"linewidth": 1.3, "solid_capstyle": "butt", "zorder": 2}

    def path(points, color, gid=None):
        ax.plot(*zip(*points, strict=True), color=color, gid=gid, **line)

    def head(tip, direction, color, gid=None):
        dx, dy = {"left": (1, 0), "top": (0, -1), "bottom": (0, 1), "right": (-1, 0),
                  "out": (1, 0)}[direction]
        a, b = 0.13, 0.05
        x0, y0 = tip
        pts = [(x0, y0), (x0 - dx * a - dy * b, y0 - dy * a + dx * b),
               (x0 - dx * a + dy * b, y0 - dy * a - dx * b)]
        ax.add_patch(Polygon(pts, closed=True, color=color, zorder=5, linewidth=0, gid=gid))

    def text(x, y, s, *, size=f_sig, math=False, **kw):
        return ax.text(x, y, s, fontsize=size, parse_math=bool(math), **kw)

    white = {"facecolor": "white", "edgecolor": "none", "pad": 0.5}
    segments = defaultdict(list)  # net -> [(p, q)]

    def seg(net, points, color):
        path(points, color, gid=f"net:{net.src}:{net.label}")
        segments[net] += list(zip(points[:-1], points[1:], strict=True))

    def arrive(net, b, x_track, color):
        px, py, side = in_xy[(net, b)]
        if side in ("left", "right"):
            seg(net, [(x_track, py), (px, py)], color)
        head((px, py), side, color, f"net:{net.src}:{net.label}")
        return py

    for net in nets:
        color = net.color
        if net.src in nodes:
            sx, sy = port_xy[(net, net.src)]
            if nodes[net.src].get("flip"):
                text(sx - 0.07, sy + 0.04, net.label, ha="right", va="bottom", color=color,
                     bbox=white, zorder=6)
            elif not nodes[net.src]["virtual"] and not (net.out and not net.dangling
                                                        and not net.far):
                text(sx + 0.07, sy + 0.04, net.label, ha="left", va="bottom", color=color,
                     bbox=white, zorder=6)
        else:
            sx, sy = gap_x[0], L.input_y[net]
            text(sx - 0.08, sy, net.label, ha="right", va="center", color=_GREY,
                 style="italic")
        if net.dangling:
            w, _ = _text_size(net.label, f_sig)
            seg(net, [(sx, sy), (sx + w + 0.15, sy)], _GREY)
            head((sx + w + 0.15, sy), "out", _GREY)
            continue
        xt = track_x.get((net, "exit"))
        if xt is None and not net.kinds:  # an output of the last column: out to the right
            seg(net, [(sx, sy), (x_right, sy)], color)
            head((x_right, sy), "out", color, f"net:{net.src}:{net.label}")
            text(x_right + 0.08, sy, net.label, ha="left", va="center", color=_GREY,
                 style="italic")
            continue
        if xt is None:  # one neighbour on the same row: a straight arrow
            b = next(iter(net.kinds))
            px, py, side = in_xy[(net, b)]
            xm = px - 0.2 if side == "left" else px
            seg(net, [(sx, sy), (xm, sy), (xm, py), (px, py)], color)
            head((px, py), side, color, f"net:{net.src}:{net.label}")
            continue
        ys = [sy]
        seg(net, [(sx, sy), (xt, sy)], color)
        if net.out:
            y_out = lane_top[net] if net.far else sy
            ys.append(y_out)
            seg(net, [(xt, y_out), (x_right, y_out)], color)
            head((x_right, y_out), "out", color, f"net:{net.src}:{net.label}")
            text(x_right + 0.08, y_out, net.label, ha="left", va="center", color=_GREY,
                 style="italic")
        for b, k in net.kinds.items():
            px, py, side = in_xy[(net, b)]
            if k == "next" and side in ("top", "bottom"):  # into a junction from its row
                seg(net, [(xt, sy), (px, sy), (px, py)], color)
                head((px, py), side, color, f"net:{net.src}:{net.label}")
                continue
            if k == "next":
                ys.append(py)
                arrive(net, b, xt, color)
                continue
            lane_y = lane_top[net] if k == "skip" else lane_bottom[net]
            ys.append(lane_y)
            if side in ("left", "right"):
                xe = track_x[(net, layer[b])]
                seg(net, [(xe, lane_y), (xe, py)], color)
                arrive(net, b, xe, color)
                xs_lane = xe
            else:
                seg(net, [(px, lane_y), (px, py)], color)
                head((px, py), side, color, f"net:{net.src}:{net.label}")
                xs_lane = px
            seg(net, [(xt, lane_y), (xs_lane, lane_y)], color)
        seg(net, [(xt, min(ys)), (xt, max(ys))], color)

    # branch dots where one signal splits
    for net, segs in segments.items():
        points = {pt for s in segs for pt in s}
        for pt in points:
            arms = set()
            for a, b in segs:
                for end, other in ((a, b), (b, a)):
                    if np.allclose(end, pt):
                        arms.add((np.sign(round(other[0] - pt[0], 6)),
                                  np.sign(round(other[1] - pt[1], 6))))
                if not (np.allclose(a, pt) or np.allclose(b, pt)) and _on(pt, a, b):
                    arms.add((np.sign(round(a[0] - pt[0], 6)), np.sign(round(a[1] - pt[1], 6))))
                    arms.add((np.sign(round(b[0] - pt[0], 6)), np.sign(round(b[1] - pt[1], 6))))
            arms.discard((0.0, 0.0))
            if len(arms) >= 3:
                ax.plot(*pt, marker="o", markersize=4.5, color=net.color, zorder=6,
                        gid=f"dot:{net.src}:{net.label}")

    # --- nodes
    for n, node in nodes.items():
        x, y, w, h = node["x"], node["y"], node["w"], node["h"]
        if node["shape"] == "sum":
            ax.add_patch(Circle((x, y), w / 2, facecolor="white", edgecolor=_BLUE,
                                linewidth=1.4, zorder=4))
            feeds = [net for net in nets if n in net.kinds]
            sides = {in_xy[(feed, n)][2] for feed in feeds}
            # a sign stands beside its arrow, away from the circle: a top or bottom arrow's on
            # its outer side; a left entry's above its wire, or below it (a lower entry, or
            # arrows coming from above only), and an arrow left of centre on the same side
            # as the left entry's sign has its sign further out, clear of it
            lower = "top" in sides and "bottom" not in sides
            for feed in feeds:
                px, py, side = in_xy[(feed, n)]
                # the wire's gain times, for a summing_junction block, the port's sign
                sign = next(np.sign(g) * (1.0 if node["virtual"]
                                          else node["signs"].get(ports[0], 1.0))
                            for b, ports, g in feed.dests if b == n)
                mark = "+" if sign > 0 else "\u2212"
                if side == "left":
                    below = py < y - 1e-9 or lower
                    dx, dy = -0.1, -0.13 if below else 0.13
                else:
                    up = 1 if side == "top" else -1
                    shared = "left" in sides and (side == "top") != lower and px < x - 1e-9
                    dx, dy = (-0.13 if px <= x + 1e-9 else 0.13), up * (0.25 if shared else 0.12)
                text(px + dx, py + dy, mark, size=f_sig + 1, ha="center", va="center",
                     color=_BLUE, weight="bold")
            continue
        fill = _FILL_DISCRETE if node.get("discrete") else _FILL
        if node["shape"] == "gain":
            f = -1 if node.get("flip") else 1
            ax.add_patch(Polygon([(x - f * w / 2, y - h / 2), (x - f * w / 2, y + h / 2),
                                  (x + f * w / 2, y)], closed=True, facecolor=fill,
                                 edgecolor=_BLUE, linewidth=1.4, zorder=4))
            text(x - f * w / 6, y, node["text"], size=f_name, math=node["math"], ha="center",
                 va="center", zorder=5)
            if node.get("discrete"):  # its rate, under it
                text(x, y - h / 2 - 0.14, _kind(sys.syslist[sys.syslist_index[n]]),
                     size=f_sub, ha="center", va="center", color="#555", zorder=5)
            continue
        ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h,
                                    boxstyle="round,pad=0.02,rounding_size=0.06", zorder=4,
                                    facecolor=fill, edgecolor=_BLUE, linewidth=1.4))
        if node["shape"] == "group":
            ax.add_patch(Rectangle((x - w / 2 + 0.05, y - h / 2 + 0.05), w - 0.1, h - 0.1,
                                   fill=False, edgecolor=_BLUE, linewidth=0.8, zorder=4))
        text(x, y + 0.11, node["label"], size=f_name, math=node["math"], ha="center",
             va="center", weight="bold", zorder=5)
        text(x, y - 0.17, node["sub"], size=f_sub, ha="center", va="center", color="#555",
             zorder=5)

    if L.omitted:  # declared outputs the hints leave out of the drawing, named
        text(x_mid - width / 2 + 0.2, L.y_omitted, L.omitted, size=f_sub, ha="left",
             va="center", color=_GREY, style="italic", zorder=5)
    if legend:
        x0, y0 = x_mid - width / 2 + 0.35, y_bottom + 0.2
        for i, (fill, words) in enumerate(((_FILL_DISCRETE, "discrete: updates at its instants, "
                                            "holds its output between them"),
                                           (_FILL, "continuous or static"))):
            xi = x0 + i * 5.2
            ax.add_patch(Rectangle((xi, y0 - 0.09), 0.28, 0.18, facecolor=fill,
                                   edgecolor=_BLUE, linewidth=1.0, zorder=4))
            text(xi + 0.4, y0, words, size=f_sub, ha="left", va="center", color="#333",
                 zorder=5)

    # --- loose ends
    for n, ports in graph["unconnected_inputs"].items():
        px, py = nodes[n]["spare_xy"]
        ax.plot([px - 0.45, px], [py, py], color="red", linewidth=1, zorder=3)
        ax.plot(px - 0.45, py, marker="o", markerfacecolor="white", markeredgecolor="red",
                zorder=5)
        text(px - 0.55, py, f"unconnected: {', '.join(compress_signals(ports))}", size=f_sub,
             ha="right", va="center", color="red")
    for n, ports in graph["unused_outputs"].items():
        px, py = nodes[n]["unused_xy"]
        ax.plot([px, px + 0.35], [py, py], color="red", linewidth=1, zorder=3)
        ax.plot(px + 0.35, py, marker="o", markerfacecolor="white", markeredgecolor="red",
                zorder=5)
        text(px + 0.07, py - 0.04, f"unused: {', '.join(compress_signals(ports))}",
             size=f_sub, ha="left", va="top", color="red")

    # --- frames
    for glabel, members in groups.items():
        members = [m for m in members if m in nodes]
        if not members:
            continue
        inside = [net for net in local_nets if net.src in members]
        x0 = min([nodes[m]["x"] - nodes[m]["w"] / 2 for m in members]
                 + [track_x[(net, layer[b])] for net in inside for b in net.kinds
                    if (net, layer[b]) in track_x]) - 0.08
        x1 = max(nodes[m]["x"] + nodes[m]["w"] / 2 for m in members) + 0.1
        y1 = max(nodes[m]["y"] + nodes[m]["h"] / 2 for m in members) + 0.4
        y0 = min([nodes[m]["y"] - nodes[m]["h"] / 2 for m in members]
                 + [lane_bottom[net] for net in inside]) - 0.12
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor=_RED,
                               linewidth=1.2, linestyle="--", zorder=1))
        w, h = _text_size(glabel, f_sig + 1, glabel.count("$") >= 2, "bold")
        top, bottom = y1 - 0.05, y1 - 0.05 - h
        crossing = sorted(a[0] for segs in segments.values() for a, b in segs
                          if np.isclose(a[0], b[0]) and min(a[1], b[1]) < top
                          and max(a[1], b[1]) > bottom and x0 < a[0] < x1)
        starts = [x0 + 0.08] + [x + 0.08 for x in crossing]  # leftmost spot no line crosses
        free = [x for x in starts if x + w <= x1 - 0.05
                and not any(x - 0.05 < c < x + w + 0.05 for c in crossing)]
        text(free[0] if free else x0 + 0.08, top, glabel, size=f_sig + 1, math=True,
             ha="left", va="top", color=_RED, weight="bold")

    text(x_mid, y_title, title, size=f_name + 1, math=title_math, ha="center", va="center")
    if filename is not None:
        import matplotlib as mpl

        with mpl.rc_context({"svg.fonttype": "none"}):
            fig.savefig(Path(filename), dpi=160)
    return fig


def _on(p, a, b):
    (px, py), (ax_, ay), (bx, by) = p, a, b
    if np.isclose(ax_, bx) and np.isclose(px, ax_):
        return min(ay, by) - 1e-9 <= py <= max(ay, by) + 1e-9
    if np.isclose(ay, by) and np.isclose(py, ay):
        return min(ax_, bx) - 1e-9 <= px <= max(ax_, bx) + 1e-9
    return False
