"""Layered layout of a block diagram: columns, rows, ports, tracks and lanes."""

from __future__ import annotations

from collections import defaultdict
from types import SimpleNamespace

import numpy as np

from ._graph import (
    _IN,
    _OUT,
    _kind,
    _nets,
    _require_interconnect,
    _shape,
    compress_signals,
    diagram_graph,
)

# ----------------------------------------------------------------------------- text sizes

def _text_size(text, size, math=False, weight="normal"):
    """Width and height of ``text`` in inches."""
    from matplotlib.font_manager import FontProperties
    from matplotlib.textpath import text_to_path

    prop = FontProperties(size=size, weight=weight)
    lines = text.split("\n")
    w = max(text_to_path.get_text_width_height_descent(line, prop, ismath=bool(math))[0]
            for line in lines)
    return float(w) / 72.0, len(lines) * size * 1.25 / 72.0


# ----------------------------------------------------------------------------- layout

def _columns(nodes, nets, beside):
    """Columns by longest path once the DFS back edges (feedback) are removed."""
    names = [n for n in nodes]
    succ = defaultdict(list)
    for net in nets:
        if net.src in nodes and net.src not in beside:
            for b, _, _ in net.dests:
                if b in nodes and b != net.src and b not in succ[net.src]:
                    succ[net.src].append(b)
    entries = [b for net in nets if net.src == _IN for b, _, _ in net.dests if b in nodes]
    fed = {b for a in succ for b in succ[a]}
    roots = list(dict.fromkeys(entries)) + [n for n in names if n not in fed]
    state, back = {}, set()

    def visit(n):
        state[n] = 1
        for m in succ[n]:
            if state.get(m) == 1:
                back.add((n, m))
            elif m not in state:
                visit(m)
        state[n] = 2

    for n in roots + names:
        if n not in state:
            visit(n)
    layer = dict.fromkeys(names, 0)
    for _ in names:
        for a in names:
            for b in succ[a]:
                if (a, b) not in back:
                    layer[b] = max(layer[b], layer[a] + 1)
    fed_forward = {b for a in names for b in succ[a] if (a, b) not in back}
    for n in names:  # a source (a constant gain) sits just before the block it feeds
        after = [layer[b] for b in succ[n] if (n, b) not in back]
        if n not in fed_forward and n not in entries and after:
            layer[n] = max(layer[n], min(after) - 1)
    for n, other in beside.items():
        if other in layer:
            layer[n] = layer[other]
    used = sorted(set(layer.values()))
    return {n: used.index(v) for n, v in layer.items()}, entries


def _rows(nodes, nets, layer, entries, order, row_hint):
    """Row 0 for the longest chain of neighbouring columns, parallel branches below."""
    preds = defaultdict(set)
    for net in nets:
        for b, _, _ in net.dests:
            if net.src in nodes and b in nodes and layer[b] == layer[net.src] + 1:
                preds[b].add(net.src)
    best, prev = {}, {}
    for n in sorted(nodes, key=lambda n: (layer[n], order[n])):
        cands = sorted(preds[n], key=lambda p: (-best[p], p not in entries, order[p]))
        best[n] = 1 + (best[cands[0]] if cands else 0)
        prev[n] = cands[0] if cands else None
    end = min(nodes, key=lambda n: (-best[n], -layer[n], order[n]))
    row, n = {}, end
    while n is not None:
        row[n] = 0
        n = prev[n]
    columns = defaultdict(list)
    for n in nodes:
        columns[layer[n]].append(n)
    for c in sorted(columns):
        rest = [n for n in columns[c] if n not in row]
        taken = {row[n] for n in columns[c] if n in row}

        def pull(n):
            ys = [row[p] for p in preds[n] if p in row]
            return (row_hint.get(n, 0), np.mean(ys) if ys else 0.0, order[n])

        r = 1
        for n in sorted(rest, key=pull):
            r = max(r, row_hint.get(n, r))
            while r in taken:
                r += 1
            row[n] = r
            taken.add(r)
    return row


# ----------------------------------------------------------------------------- drawing

def _hints(sys, labels, groups):
    hints = dict(getattr(sys, "drawing_hints", None) or {})
    merged_labels = dict(hints.get("labels", {}))
    for s in sys.syslist:
        if getattr(s, "display_name", None):
            merged_labels.setdefault(s.name, s.display_name)
    merged_labels.update(labels or {})
    merged_groups = dict(hints.get("groups", {}))
    merged_groups.update(groups or {})
    return (merged_labels, merged_groups, dict(hints.get("beside", {})),
            dict(hints.get("rows", {})), dict(hints.get("notes", {})))


def layout(sys, *, labels=None, groups=None, fontsize=10.0, title=None):
    """Place every block, port, track and lane of ``sys``'s diagram, in inches.

    Returns a namespace with what :func:`~controlkit.drawing.draw_block_diagram`
    draws: ``nodes`` (shape, label, centre and size), ``nets`` (with their kinds
    of destination), ``port_xy``/``in_xy`` (where a net leaves and enters a block),
    ``track_x`` (vertical runs between columns), ``lane_top``/``lane_bottom``
    (horizontal runs above and below the rows) and the page's extent.
    """
    _require_interconnect(sys)
    labels, groups, beside, row_hint, notes = _hints(sys, labels, groups)
    sums = (getattr(sys, "drawing_hints", None) or {}).get("sums", {})
    hint_title = (getattr(sys, "drawing_hints", None) or {}).get("title")
    f_sig, f_name, f_sub = fontsize, fontsize + 2, fontsize - 0.5
    graph = diagram_graph(sys)

    # --- nodes
    nodes = {}
    order = {}
    for i, s in enumerate(sys.syslist):
        shape, extra = _shape(s)
        label = labels.get(s.name)
        nodes[s.name] = {"shape": shape, "signs": extra if shape == "sum" else {},
                         "gain": extra if shape == "gain" else None,
                         "label": label if label is not None else s.name,
                         "math": label is not None, "virtual": False,
                         "sub": notes.get(s.name) or (
                             (f"{s.name}, {_kind(s)}" if _kind(s) != "static" else s.name)
                             if label is not None else _kind(s))}
        order[s.name] = i
    nets, _ = _nets(sys, nodes, sums)
    for n in nodes:
        order.setdefault(n, len(order))
    layer, entries = _columns(nodes, nets, beside)
    row = _rows(nodes, nets, layer, entries, order, row_hint)
    for n, feeder in _feedback_elements(nodes, nets, layer, row, entries).items():
        # a sensor or gain in the feedback path: under its feeder, pointing back
        nodes[n]["flip"], nodes[n]["feeder"] = True, feeder
        layer[n] = layer[feeder]
        row[n] = max(row[m] for m in nodes if layer[m] == layer[n] and m != n) + 1
    used = sorted(set(layer.values()))
    layer = {n: used.index(c) for n, c in layer.items()}
    ncol = max(layer.values()) + 1

    # --- node sizes (inches)
    pitch = 0.34
    n_in, n_out = defaultdict(int), defaultdict(int)
    for net in nets:
        if net.src in nodes:
            n_out[net.src] += 1
        for b, _, _ in net.dests:
            if b in nodes:
                n_in[b] += 1
    for n in graph["unconnected_inputs"]:
        n_in[n] += 1
    for n in graph["unused_outputs"]:
        n_out[n] += 1
    for n, node in nodes.items():
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

    # --- net classes
    def kind_of(net, b):
        if b == _OUT:
            return "out"
        ls = layer[net.src] if net.src in nodes else -1
        if layer[b] == ls + 1 or nodes[b].get("feeder") == net.src:
            return "next"
        return "skip" if layer[b] > ls + 1 else "back"

    last = ncol - 1
    for net in nets:
        internal = [b for b, _, _ in net.dests if b != _OUT]
        net.out_ports = [p for b, ports, _ in net.dests if b == _OUT for p in ports]
        net.far = False
        net.out = any(b == _OUT for b, _, _ in net.dests) and (
            not internal or layer.get(net.src, -1) == last)
        net.dests = [d for d in net.dests if d[0] != _OUT]
        net.dangling = not net.dests and net.out and layer.get(net.src, -1) != last
        net.kinds = {b: kind_of(net, b) for b, _, _ in net.dests}
        net.virtual_src = nodes.get(net.src, {}).get("virtual", False)
    nets = [n for n in nets if n.dests or n.out]
    if sys.noutputs and not any(n.out and not n.dangling for n in nets):
        # the loop's first output leaves on the right even when its block is not last
        for net in nets:
            if sys.output_labels[0] in net.out_ports and net.dests:
                net.out, net.far, net.dangling = True, True, False

    # --- column x, row y
    col_w = [max(nodes[n]["w"] for n in nodes if layer[n] == c) for c in range(ncol)]
    row_ids = sorted(set(row.values()))
    row_h = {r: max(nodes[n]["h"] for n in nodes if row[n] == r) for r in row_ids}
    frame_of = {}
    for glabel, members in groups.items():
        for m in members:
            frame_of.setdefault(m, glabel)
    lane_pitch = 0.22

    def inner(net):  # nets inside one frame get the lanes nearest the blocks
        ends = [net.src] + list(net.kinds)
        f = {frame_of.get(e) for e in ends}
        return 0 if len(f) == 1 and None not in f else 1

    local = defaultdict(list)  # feedback inside a frame on one row: a lane under that row
    for net in nets:
        ends = [net.src] + list(net.kinds)
        if ("back" in net.kinds.values() and inner(net) == 0
                and len({row.get(e) for e in ends}) == 1):
            local[row[net.src]].append(net)
    y_row = {row_ids[0]: 0.0}
    for above, r in zip(row_ids[:-1], row_ids[1:], strict=True):
        room = 0.3 + lane_pitch * len(local[above]) if local[above] else 0.0
        y_row[r] = y_row[above] - (row_h[above] / 2 + 0.55 + room + row_h[r] / 2)

    # gap c is left of column c; exit tracks of column c-1 and entry tracks of column c
    label_w = defaultdict(float)
    exits, entries_in = defaultdict(list), defaultdict(list)
    for net in nets:
        src_col = layer[net.src] if net.src in nodes else -1
        w, _ = _text_size(net.label, f_sig)
        flip = nodes.get(net.src, {}).get("flip", False)
        if net.src in nodes and not nodes[net.src]["virtual"] and not flip and not (
                net.out and not net.dangling):  # a loop output is labelled where it leaves
            label_w[src_col + 1] = max(label_w[src_col + 1], w + 0.2)
        if net.dangling:
            continue
        needs_track = (len(net.dests) > 1 or net.out and net.dests
                       or any(k != "next" for k in net.kinds.values()))
        net.track_gap = src_col + 1
        if needs_track or net.src in nodes and any(
                row[b] != row[net.src] for b in net.kinds):
            exits[src_col if flip else src_col + 1].append(net)
        for b, k in net.kinds.items():
            if k in ("skip", "back") and not (nodes[b]["shape"] == "sum" and
                                              _vertical_ok(b, k, nodes, layer, row)):
                key = (net, layer[b])
                if key not in entries_in[layer[b]]:
                    entries_in[layer[b]].append(key)
    for n, ports in graph["unconnected_inputs"].items():
        w, _ = _text_size("unconnected: " + ", ".join(compress_signals(ports)), f_sub)
        label_w[layer[n]] = max(label_w[layer[n]], w + 0.6)
    for n, ports in graph["unused_outputs"].items():
        w, _ = _text_size("unused: " + ", ".join(compress_signals(ports)), f_sub)
        label_w[layer[n] + 1] = max(label_w[layer[n] + 1], w + 0.3)
    track = 0.17
    gap_w = {g: max(0.6, label_w[g] + 0.4 + track * (len(exits[g]) + len(entries_in[g])))
             for g in range(ncol + 1)}
    gap_w[0] = max(gap_w[0] - label_w[0], 0.55) if not graph["unconnected_inputs"] else gap_w[0]
    x_col, x = {}, 0.0
    gap_x = {}
    for c in range(ncol):
        gap_x[c] = x
        x += gap_w[c]
        x_col[c] = x + col_w[c] / 2
        x += col_w[c]
    gap_x[ncol] = x
    x_right = x + gap_w[ncol]
    for n, node in nodes.items():
        node["x"], node["y"] = x_col[layer[n]], y_row[row[n]]

    # --- ports
    top_rows = max(node["y"] + node["h"] / 2 for node in nodes.values())
    bottom_rows = min(node["y"] - node["h"] / 2 for node in nodes.values())

    def towards(net):  # where a net heads to, for ordering ports top to bottom
        ys = []
        for b, k in net.kinds.items():
            ys.append(+1e3 if k == "skip" else -1e3 if k == "back" else nodes[b]["y"])
        return max(ys) if ys else nodes[net.src]["y"]

    def source_y(net):
        return nodes[net.src]["y"] if net.src in nodes else 0.0

    out_ports, in_ports = defaultdict(list), defaultdict(list)
    for net in nets:
        if net.src in nodes:
            out_ports[net.src].append(net)
        for b, k in net.kinds.items():
            in_ports[b].append((net, k))
    port_xy, in_xy = {}, {}
    for n, node in nodes.items():
        outs = sorted(out_ports[n], key=lambda net: -towards(net))
        extra_out = 1 if n in graph["unused_outputs"] else 0
        k = len(outs) + extra_out
        side = -1 if node.get("flip") else 1
        for i, net in enumerate(outs):
            port_xy[(net, n)] = (node["x"] + side * node["w"] / 2,
                                 node["y"] + pitch * ((k - 1) / 2 - i))
        node["unused_xy"] = (node["x"] + node["w"] / 2, node["y"] + pitch * ((k - 1) / 2 - k + 1))
        ins = sorted(in_ports[n], key=lambda port: -(1e3 if port[1] == "skip" else -1e3
                                                   if port[1] == "back" else source_y(port[0])))
        extra_in = 1 if n in graph["unconnected_inputs"] else 0
        k = len(ins) + extra_in
        if node["shape"] == "sum":
            _sum_ports(n, node, ins, source_y, in_xy, nodes, layer, row)
            continue
        xl = node["x"] - node["w"] / 2
        if node.get("flip"):
            xl = node["x"] + node["w"] / 2
        for i, (net, _) in enumerate(ins):
            in_xy[(net, n)] = (xl, node["y"] + pitch * ((k - 1) / 2 - i),
                               "right" if node.get("flip") else "left")
        node["spare_xy"] = (xl, node["y"] + pitch * ((k - 1) / 2 - k + 1))

    # --- tracks and lanes
    track_x = {}
    for g in range(ncol + 1):
        x0 = gap_x[g] + max(label_w[g], 0.15) + 0.1 if g > 0 else gap_x[g] + 0.15

        def exit_key(net):
            y0 = port_xy[(net, net.src)][1] if net.src in nodes else 0.0
            up = towards(net) > y0
            return (0, -y0) if up else (1, y0)

        for i, net in enumerate(sorted(exits[g], key=exit_key)):
            track_x[(net, "exit")] = x0 + track * (i + 0.5)
        x1 = x0 + track * len(exits[g])

        def entry_key(item):
            net, c = item
            yp = max(in_xy[(net, b)][1] for b in net.kinds if layer[b] == c)
            return (0, yp) if any(net.kinds[b] == "skip" for b in net.kinds
                                  if layer[b] == c) else (1, -yp)

        for i, item in enumerate(sorted(entries_in[g], key=entry_key)):
            track_x[item] = x1 + track * (i + 0.5)

    def span(net):
        xs = [nodes[b]["x"] for b in net.kinds] + [nodes[net.src]["x"] if net.src in nodes
                                                   else 0.0]
        return max(xs) - min(xs)

    top_nets = sorted([n for n in nets if "skip" in n.kinds.values() or n.far],
                      key=lambda n: (inner(n), span(n)))
    local_nets = {net for nets_r in local.values() for net in nets_r}
    # the output of a feedback element runs back along its own row when that row is free
    own_row = {net for net in nets if nodes.get(net.src, {}).get("flip")
               and all(k == "back" for k in net.kinds.values())
               and not any(row[m] == row[net.src] and m != net.src
                           and min(layer[b] for b in net.kinds) <= layer[m] <= layer[net.src]
                           for m in nodes)}
    bottom_nets = sorted([n for n in nets if "back" in n.kinds.values()
                          and n not in local_nets and n not in own_row],
                         key=lambda n: (inner(n), span(n)))
    frame_pad = 0.45 if groups else 0.0
    lane_top = {net: top_rows + frame_pad + 0.3 + lane_pitch * i
                for i, net in enumerate(top_nets)}
    last_row = row_ids[-1]
    start = bottom_rows - 0.3 - (lane_pitch * len(local[last_row]) + 0.15 if local[last_row]
                                 else 0.0)
    lane_bottom = {net: start - lane_pitch * i for i, net in enumerate(bottom_nets)}
    for net in own_row:
        lane_bottom[net] = port_xy[(net, net.src)][1]
    for r, nets_r in local.items():
        low = min(nodes[n]["y"] - nodes[n]["h"] / 2 for n in nodes if row[n] == r)
        for i, net in enumerate(sorted(nets_r, key=span)):
            lane_bottom[net] = low - 0.3 - lane_pitch * i

    # --- figure
    title_math = title is not None or bool(hint_title)  # the system's own name is literal
    title = title if title is not None else hint_title or sys.name
    y_top = (max(lane_top.values()) if lane_top else top_rows + frame_pad) + 0.25
    y_bottom = min([bottom_rows] + list(lane_bottom.values())) - 0.2
    x_left = -max([_text_size(n.label, f_sig)[0] + 0.1 for n in nets if n.src == _IN] + [0])
    x_right_text = x_right + max([_text_size(n.label, f_sig)[0] + 0.1 for n in nets
                                  if n.out and not n.dangling] + [0])
    tw, th = _text_size(title, f_name + 1, title_math and title.count("$") >= 2)
    y_title = y_top + th * 0.6
    y_top = y_title + th * 0.6
    width = max(x_right_text - x_left, tw + 0.4) + 0.3
    height = y_top - y_bottom + 0.2
    x_mid = (x_left + x_right_text) / 2
    if width / height > 2.5:  # room under the title: keep a slide's proportions
        extra = width / 2.5 - height
        y_top += extra / 2
        y_bottom -= extra / 2
        height = width / 2.5
    return SimpleNamespace(
        nodes=nodes, nets=nets, layer=layer, row=row, port_xy=port_xy, in_xy=in_xy,
        track_x=track_x, lane_top=lane_top, lane_bottom=lane_bottom, local_nets=local_nets,
        groups=groups, graph=graph, gap_x=gap_x, x_right=x_right, fonts=(f_sig, f_name, f_sub),
        title=title, title_math=title_math, y_title=y_title, x_mid=x_mid, width=width,
        height=height, y_top=y_top, y_bottom=y_bottom)


def _sum_ports(n, node, ins, source_y, in_xy, nodes, layer, row):
    """Where signals enter a junction: one from the left, those from other rows and
    lanes from above or below (lanes outermost), so no two entries share a line."""
    r, x, y = node["w"] / 2, node["x"], node["y"]
    vertical = [port for port in ins if port[1] in ("skip", "back")
                and _vertical_ok(n, port[1], nodes, layer, row)]
    rest = [port for port in ins if port not in vertical]
    left = sorted(rest, key=lambda port: abs(source_y(port[0]) - y))[:1]
    below = sorted([port for port in rest if port not in left and port[1] == "next"
                    and source_y(port[0]) < y - r], key=lambda port: -source_y(port[0]))
    above = sorted([port for port in rest if port not in left and port[1] == "next"
                    and source_y(port[0]) > y + r], key=lambda port: source_y(port[0]))
    left = [port for port in rest if port not in below and port not in above]
    sides = (("left", left), ("bottom", below + [port for port in vertical if port[1] == "back"]),
             ("top", above + [port for port in vertical if port[1] == "skip"]))
    for side, ports in sides:
        m = len(ports)
        for j, (net, _) in enumerate(ports):
            t = 0.0 if m == 1 else 0.7 * (2 * j / (m - 1) - 1)
            if side == "left":
                in_xy[(net, n)] = (x - r * np.sqrt(1 - t * t), y - r * t, side)
            else:
                s = -1 if side == "bottom" else 1
                in_xy[(net, n)] = (x + r * t, y + s * r * np.sqrt(1 - t * t), side)


def _feedback_elements(nodes, nets, layer, row, entries):
    """Blocks at the end of the main row whose outputs only feed back: ``{block: feeder}``.

    A sensor or a gain in the feedback path of a textbook loop. Such a block is drawn
    under the block that feeds it, pointing back.
    """
    found = {}
    last = max(layer.values())
    for n, node in nodes.items():
        outs = [net for net in nets if net.src == n]
        ins = [net for net in nets if any(b == n for b, _, _ in net.dests)]
        if (node["virtual"] or node["shape"] == "sum" or n in entries or row[n] != 0
                or layer[n] != last or not outs or len(ins) != 1 or ins[0].src not in nodes):
            continue
        feeder = ins[0].src
        if layer[feeder] != layer[n] - 1 or row[feeder] != 0:
            continue
        dests = [b for net in outs for b, _, _ in net.dests]
        if all(b in nodes and layer[b] < layer[feeder] for b in dests):
            found[n] = feeder
    return found


def _vertical_ok(n, kind, nodes, layer, row):
    """A sum fed from a lane takes it from above/below unless a block sits in the way."""
    side = 1 if kind == "skip" else -1
    return not any(layer[m] == layer[n] and m != n and np.sign(row[n] - row[m]) == side
                   for m in nodes)
