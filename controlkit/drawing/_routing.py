"""Where the wires of a laid-out block diagram run: ports, vertical tracks and lanes.

The stages of :func:`._layout.layout` after the blocks have their places: they decide
where each net leaves and enters a block and the runs that connect them.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from ._draft import _INPUT_PITCH, _LANE_PITCH, _PORT_PITCH, _TRACK_PITCH
from ._ordering import _vertical_ok


def _place_ports(draft):
    """Decide where each net leaves (``port_xy``) and enters (``in_xy``) a block.

    Ports are spread one pitch (0.34 in) apart and centred on the block's side,
    ``y_i = y + 0.34 ((k - 1) / 2 - i)``, ordered by where the net goes or comes from,
    top first: a net to a skip lane leaves from the top, feedback from the bottom, so
    wires do not cross next to a block. A flipped block (a sensor in the feedback path)
    takes inputs on its right and gives outputs on its left. A loose end takes the last
    place on its side (``unused_xy``, ``spare_xy``); a junction is a circle with entries
    from several sides (:func:`_sum_ports`).
    """
    nodes, pitch = draft.nodes, _PORT_PITCH
    out_ports, in_ports = defaultdict(list), defaultdict(list)
    for net in draft.nets:
        if net.src in nodes:
            out_ports[net.src].append(net)
        for b, k in net.kinds.items():
            in_ports[b].append((net, k))
    for n, node in nodes.items():
        outs = sorted(out_ports[n], key=lambda net: -draft.towards(net))
        extra_out = 1 if n in draft.graph["unused_outputs"] else 0
        k = len(outs) + extra_out
        side = -1 if node.get("flip") else 1
        for i, net in enumerate(outs):
            draft.port_xy[(net, n)] = (node["x"] + side * node["w"] / 2,
                                       node["y"] + pitch * ((k - 1) / 2 - i))
        node["unused_xy"] = (node["x"] + node["w"] / 2, node["y"] + pitch * ((k - 1) / 2 - k + 1))
        ins = sorted(in_ports[n], key=lambda port: -(1e3 if port[1] == "skip" else -1e3
                                                   if port[1] == "back"
                                                   else draft.source_y(port[0])))
        extra_in = 1 if n in draft.graph["unconnected_inputs"] else 0
        k = len(ins) + extra_in
        if node["shape"] == "sum":
            _sum_ports(n, node, ins, draft)
            continue
        xl = node["x"] - node["w"] / 2
        if node.get("flip"):
            xl = node["x"] + node["w"] / 2
        for i, (net, _) in enumerate(ins):
            draft.in_xy[(net, n)] = (xl, node["y"] + pitch * ((k - 1) / 2 - i),
                                     "right" if node.get("flip") else "left")
        node["spare_xy"] = (xl, node["y"] + pitch * ((k - 1) / 2 - k + 1))


def _sum_ports(n, node, ins, draft):
    """Where signals enter a junction: one from the left, those from other rows and
    lanes from above or below (lanes outermost), so no two entries share a line."""
    nodes, layer, row, source_y = draft.nodes, draft.layer, draft.row, draft.source_y
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
                draft.in_xy[(net, n)] = (x - r * np.sqrt(1 - t * t), y - r * t, side)
            else:
                s = -1 if side == "bottom" else 1
                draft.in_xy[(net, n)] = (x + r * t, y + s * r * np.sqrt(1 - t * t), side)


def _place_inputs(draft):
    """Decide where each external input starts, left of the first column: ``input_y``.

    An input that feeds a block of the first column starts level with its port there
    (the main row's first), so its arrow is straight; one that only skips to later
    columns runs along a lane above the rows, so it starts above the others, the one on
    the higher lane higher, and its rise crosses no other input. Names are written at
    the start, so starts at least :data:`_INPUT_PITCH` apart keep them from overlapping.
    """
    inputs = [net for net in draft.nets if net.src not in draft.nodes]
    level = {}
    for net in inputs:
        nexts = [b for b, k in net.kinds.items() if k == "next"]
        if nexts:
            first = min(nexts, key=lambda b: (draft.row[b], -draft.in_xy[(net, b)][1]))
            level[net] = draft.in_xy[(net, first)][1]
    above = max(level.values(), default=0.0)
    risers = sorted((net for net in inputs if net not in level),
                    key=lambda net: (draft.inner(net), draft.span(net)))
    for i, net in enumerate(risers):
        level[net] = above + _INPUT_PITCH * (i + 1)
    previous = None
    for net in sorted(inputs, key=lambda net: -level[net]):  # top down, pushed apart
        if previous is not None and level[net] > previous - _INPUT_PITCH:
            level[net] = previous - _INPUT_PITCH
        previous = level[net]
    draft.input_y = level


def _place_tracks(draft):
    """Decide the x of each vertical run in the gaps: ``track_x``.

    In each gap, after its labels, come the exit tracks (0.17 in apart) and then the
    entry tracks. Exits going up are ordered so the lowest port turns nearest the block
    it leaves, exits going down the other way round, and entries likewise by their port,
    so two runs in one gap never cross.
    """
    nodes, layer, track = draft.nodes, draft.layer, _TRACK_PITCH

    def exit_key(net):
        y0 = draft.port_xy[(net, net.src)][1] if net.src in nodes else draft.input_y[net]
        up = draft.towards(net) > y0
        return (0, -y0) if up else (1, y0)

    def entry_key(item):
        net, c = item
        yp = max(draft.in_xy[(net, b)][1] for b in net.kinds if layer[b] == c)
        return (0, yp) if any(net.kinds[b] == "skip" for b in net.kinds
                              if layer[b] == c) else (1, -yp)

    for g in range(draft.ncol + 1):
        gx = draft.gap_x[g]
        x0 = gx + max(draft.label_w[g], 0.15) + 0.1 if g > 0 else gx + 0.15
        for i, net in enumerate(sorted(draft.exits[g], key=exit_key)):
            draft.track_x[(net, "exit")] = x0 + track * (i + 0.5)
        x1 = x0 + track * len(draft.exits[g])
        for i, item in enumerate(sorted(draft.entries[g], key=entry_key)):
            draft.track_x[item] = x1 + track * (i + 0.5)


def _place_lanes(draft):
    """Decide the y of each horizontal run: ``lane_top``, ``lane_bottom``, ``local_nets``.

    Nets that skip columns (and a loop output leaving from further left) run above the
    rows, feedback below them, 0.22 in apart; within each, nets inside one frame and
    shorter nets go nearest the blocks so that lanes nest instead of crossing. Feedback
    inside a frame on one row runs just under that row (``local_nets``); the output of a
    sensor drawn pointing back runs along its own row when no block is in the way.
    """
    nodes, layer, row, nets = draft.nodes, draft.layer, draft.row, draft.nets
    local, lane_pitch = draft.local, _LANE_PITCH
    top_nets = sorted([n for n in nets if "skip" in n.kinds.values() or n.far],
                      key=lambda n: (draft.inner(n), draft.span(n)))
    local_nets = {net for nets_r in local.values() for net in nets_r}
    # the output of a feedback element runs back along its own row when that row is free
    own_row = {net for net in nets if nodes.get(net.src, {}).get("flip")
               and all(k == "back" for k in net.kinds.values())
               and not any(row[m] == row[net.src] and m != net.src
                           and min(layer[b] for b in net.kinds) <= layer[m] <= layer[net.src]
                           for m in nodes)}
    bottom_nets = sorted([n for n in nets if "back" in n.kinds.values()
                          and n not in local_nets and n not in own_row],
                         key=lambda n: (draft.inner(n), draft.span(n)))
    top_rows = draft.blocks_top()
    draft.lane_top = {net: top_rows + draft.frame_pad + 0.3 + lane_pitch * i
                      for i, net in enumerate(top_nets)}
    last_row = max(row.values())
    start = draft.blocks_bottom() - 0.3 - (lane_pitch * len(local[last_row]) + 0.15
                                           if local[last_row] else 0.0)
    lane_bottom = {net: start - lane_pitch * i for i, net in enumerate(bottom_nets)}
    for net in own_row:
        lane_bottom[net] = draft.port_xy[(net, net.src)][1]
    for r, nets_r in local.items():
        low = min(nodes[n]["y"] - nodes[n]["h"] / 2 for n in nodes if row[n] == r)
        for i, net in enumerate(sorted(nets_r, key=draft.span)):
            lane_bottom[net] = low - 0.3 - lane_pitch * i
    draft.lane_bottom, draft.local_nets = lane_bottom, local_nets
