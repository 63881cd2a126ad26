"""The arguments of ``control.interconnect`` that build the editor's diagram.

Consecutive elements of one vector wired alike are written as one range
(``"plant.q[0:3]"``), as a person would write them.
"""

from __future__ import annotations

from ._ports import compress_range, next_element, runs


def interconnect_specs(model):
    """``connections``, ``inplist``, ``inputs``, ``outlist``, ``outputs`` for interconnect."""
    by_dst = {}
    for w in model.wires:
        by_dst.setdefault(w.dst, []).append(w)
    connections = []
    for name, block in model.blocks.items():
        items = [(label, by_dst[(name, label)]) for label in block.system.input_labels
                 if (name, label) in by_dst]

        def continues(a, b):
            (la, wa), (lb, wb) = a, b
            return (len(wa) == len(wb) == 1 and next_element(la, lb)
                    and wa[0].src[0] == wb[0].src[0] and wa[0].gain == wb[0].gain
                    and next_element(wa[0].src[1], wb[0].src[1]))

        for run in runs(items, continues):
            if len(run) == 1:
                label, feeds = run[0]
                connections.append([_spec(name, label)]
                                   + [_spec(*w.src, w.gain) for w in feeds])
            else:
                first = run[0][1][0]
                connections.append([
                    _spec(name, compress_range([label for label, _ in run])),
                    _spec(first.src[0], compress_range([f[0].src[1] for _, f in run]),
                          first.gain)])
    inplist, inputs = [], []

    def input_continues(a, b):
        (na, ta), (nb, tb) = a, b
        return (len(ta) == len(tb) == 1 and ta[0][0] == tb[0][0] and ta[0][2] == tb[0][2]
                and next_element(ta[0][1], tb[0][1]) and next_element(na, nb))

    for run in runs([(n, t) for n, t in model.inputs if t], input_continues):
        names = [n for n, _ in run]
        if len(run) > 1:
            block, _, gain = run[0][1][0]
            inplist.append(_spec(block, compress_range([t[0][1] for _, t in run]), gain))
        else:
            targets = run[0][1]
            specs = [_spec(b, s, g) for b, s, g in targets]
            inplist.append(specs[0] if len(specs) == 1 else specs)
        inputs += names
    outlist, outputs = [], []

    def output_continues(a, b):
        (na, sa), (nb, sb) = a, b
        return (len(sa) == len(sb) == 1 and sa[0][:2] == sb[0][:2]
                and sa[0][3] == sb[0][3] and next_element(sa[0][2], sb[0][2])
                and next_element(na, nb))

    for run in runs(model.outputs, output_continues):
        names = [n for n, _ in run]
        if len(run) > 1:
            _, block, _, gain = run[0][1][0]
            outlist.append(_spec(block, compress_range([s[0][2] for _, s in run]), gain))
        else:
            sources = run[0][1]
            specs = [_spec(b, s, g) for _, b, s, g in sources]
            outlist.append(specs[0] if len(specs) == 1 else specs)
        outputs += names
    return connections, inplist, inputs, outlist, outputs


def _spec(block, signal, gain=1.0):
    """python-control's spec of a signal: ``"sys.sig"``, ``"-sys.sig"`` or a tuple."""
    if "." in block or block.startswith("-"):
        return (block, signal, gain)
    if gain == 1:
        return f"{block}.{signal}"
    if gain == -1:
        return f"-{block}.{signal}"
    return (block, signal, gain)
