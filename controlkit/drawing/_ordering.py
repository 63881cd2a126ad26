"""The reading order of a block diagram: each block's column and row, before any length.

This is the combinatorial half of a layered (Sugiyama-style) layout: columns by longest
path once the feedback edges are removed, rows by the longest chain of neighbouring
columns. :mod:`._layout` turns these integers into inches.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np

from ._graph import _IN


def _columns(nodes, nets, beside):
    """Columns by longest path once the feedback edges are removed.

    Feedback is found as a reader of a control diagram finds it: first the signals
    subtracted at a junction (``r - y``) that close a loop, then, for loops without
    one, the edges a depth-first search from the blocks the external inputs feed finds
    closing a loop. Without them the graph is acyclic and ``column(b) = max(column(a) +
    1)`` over the blocks ``a`` feeding ``b``, so every forward arrow points right. A
    source (a constant gain) sits just before the block it feeds; ``beside`` puts a block
    in another's column. Returns ``({block: column}, [blocks fed by external inputs])``.
    """
    names = [n for n in nodes]
    succ = defaultdict(list)
    subtracted = []  # (a, b): a's signal enters the junction b with a minus sign
    for net in nets:
        if net.src in nodes and net.src not in beside:
            for b, ports, sign in net.dests:
                if b in nodes and b != net.src and b not in succ[net.src]:
                    succ[net.src].append(b)
                if b in nodes and nodes[b]["shape"] == "sum" and sign * (
                        1.0 if nodes[b]["virtual"] else nodes[b]["signs"].get(ports[0], 1.0)
                ) < 0:
                    subtracted.append((net.src, b))
    entries = [b for net in nets if net.src == _IN for b, _, _ in net.dests if b in nodes]
    fed = {b for a in succ for b in succ[a]}
    roots = list(dict.fromkeys(entries)) + [n for n in names if n not in fed]
    state, back = {}, set()

    def reaches(start, goal):
        """Whether ``goal`` is downstream of ``start`` along edges not yet called back."""
        seen, stack = {start}, [start]
        while stack:
            n = stack.pop()
            for m in succ[n]:
                if (n, m) not in back and m not in seen:
                    if m == goal:
                        return True
                    seen.add(m)
                    stack.append(m)
        return False

    for a, b in subtracted:  # y fed back into e = r - y closes the loop: feedback
        if reaches(b, a):
            back.add((a, b))

    def visit(n):
        state[n] = 1
        for m in succ[n]:
            if (n, m) in back:
                continue
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
    """Row 0 for the longest chain of neighbouring columns, parallel branches below.

    The main path of a loop reads left to right on one line; a block off that chain
    takes the free row nearest the mean row of its feeders (or the row ``row_hint``
    asks for), so parallel branches stack under the main path.
    """
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
