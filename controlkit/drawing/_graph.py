"""The connection structure of an interconnect: python-control's maps as nets of signals."""

from __future__ import annotations

import re
from collections import defaultdict

import control as ct
import numpy as np

_IN, _OUT = "inputs", "outputs"
_BLUE, _RED, _GREY, _FILL = "#1f3b6e", "#b03a2e", "#333333", "#eef3fb"
#: Fill of a discrete block (it updates at its instants and holds its output between them),
#: told apart from a continuous or static one (:data:`_FILL`) in a sampled-data diagram.
_FILL_DISCRETE = "#fbeedd"


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


def _signal_label(names, sizes):
    """The label of a bundle: a whole vector by its base name (``h``), else compressed."""
    parts = []
    for part in compress_signals(names):
        m = re.fullmatch(r"(.*)\[0\.\.(\d+)\]", part)
        if m and sizes.get(m.group(1)) == int(m.group(2)) + 1:
            part = m.group(1)
        parts.append(part)
    return ", ".join(parts)


def _wrap(label, width=18):
    """Break a long list of signals into balanced lines of at most about ``width`` characters.

    Examples
    --------
    >>> print(_wrap("q1, q2, q4, w1, w2, w4"))
    q1, q2, q4,
    w1, w2, w4
    """
    if len(label) <= width:
        return label
    parts = label.split(", ")
    n_lines = -(-len(label) // width)
    target = len(label) / n_lines
    lines, current = [], ""
    for part in parts:
        if current and len(current) + len(part) + 2 > target + 2 and len(lines) < n_lines - 1:
            lines.append(current + ",")
            current = part
        else:
            current = f"{current}, {part}" if current else part
    return "\n".join(lines + [current])


def _base(name):
    return re.sub(r"\[\d+\]$", "", name)


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
    >>> from controlkit.studies.spacecraft.diagrams import output_zeroing_loop
    >>> g = diagram_graph(output_zeroing_loop())
    >>> g["edges"][("plant", "output")]
    ['q[0]', 'q[1]', 'q[2]', 'q[3]']
    """
    _require_interconnect(sys)
    out_owner, in_owner = _owners(sys)
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


def _require_interconnect(sys):
    if not isinstance(sys, ct.InterconnectedSystem):
        raise ValueError(
            f"sys must be a control.InterconnectedSystem (built with control.interconnect), "
            f"got {type(sys).__name__}"
        )


def _owners(sys):
    out_owner, in_owner = [], []
    for s in sys.syslist:
        out_owner += [(s.name, label) for label in s.output_labels]
        in_owner += [(s.name, label) for label in s.input_labels]
    return out_owner, in_owner


def _block_rank(sys):
    """``{block: rank}``: an order of the blocks that is the wiring's, not ``sys.syslist``'s.

    The same loop listed in another order (python-control's natural ``[plant, controller,
    error]`` or the signal's ``[error, controller, plant]``) must be drawn the same, so the
    layout never reads the list's order. Blocks are ranked breadth first along the signal:
    first those the external inputs feed (the first declared input, usually the
    reference, first), then the blocks they feed, and so on; what no input reaches
    (a constant gain) follows, breadth first from it. Ties go by name.

    Examples
    --------
    >>> import control as ct
    >>> P = ct.tf2ss(ct.tf([1], [1, 1]), name="P", inputs="u", outputs="y")
    >>> C = ct.tf2ss(ct.tf([2, 1], [1, 0]), name="C", inputs="e", outputs="u")
    >>> err = ct.summing_junction(inputs=["r", "-y"], output="e", name="err")
    >>> _block_rank(ct.interconnect([P, C, err], inputs="r", outputs="y"))
    {'err': 0, 'C': 1, 'P': 2}
    """
    names = [s.name for s in sys.syslist]
    out_block = [k for k, s in enumerate(sys.syslist) for _ in range(s.noutputs)]
    in_block = [k for k, s in enumerate(sys.syslist) for _ in range(s.ninputs)]
    succ = defaultdict(set)
    for i, j in zip(*np.nonzero(sys.connect_map), strict=True):
        succ[out_block[j]].add(in_block[i])
    first_input = {}
    for i, e in zip(*np.nonzero(sys.input_map), strict=True):
        first_input[in_block[i]] = min(first_input.get(in_block[i], e), e)
    ranked = sorted(first_input, key=lambda k: (first_input[k], names[k]))
    unreached = sorted(set(range(len(names))) - set(ranked), key=names.__getitem__)
    seen = set(ranked)
    i = 0
    while len(ranked) < len(names):
        if i == len(ranked):  # nothing left that the ranked blocks feed: start again
            start = next(k for k in unreached if k not in seen)
            ranked.append(start)
            seen.add(start)
        for m in sorted(succ[ranked[i]] - seen, key=names.__getitem__):
            ranked.append(m)
            seen.add(m)
        i += 1
    return {names[k]: r for r, k in enumerate(ranked)}


# ----------------------------------------------------------------------------- block shapes

def _static_matrix(s):
    """``D`` of a static LTI block (no states), else None."""
    if not isinstance(s, (ct.StateSpace, ct.TransferFunction)):
        return None
    try:
        ss = s if isinstance(s, ct.StateSpace) else ct.tf2ss(s)
    except Exception:  # noqa: BLE001 - an improper tf is no gain
        return None
    if ss.nstates:
        return None
    return np.asarray(ss.D, dtype=float)


def _shape(s):
    """``("sum", signs)``, ``("gain", text)``, ``("group", None)`` or ``("block", None)``."""
    if isinstance(s, ct.InterconnectedSystem):
        return "group", None
    D = _static_matrix(s)
    if D is None:
        return "block", None
    entries = set(np.unique(D).tolist())
    per_row = np.count_nonzero(D, axis=1)
    per_col = np.count_nonzero(D, axis=0)
    if entries <= {-1.0, 0.0, 1.0} and per_row.min() >= 2 and per_col.max() == 1:
        signs = {s.input_labels[c]: float(D[:, c].sum()) for c in range(D.shape[1])}
        return "sum", signs
    if D.shape[0] == D.shape[1] and np.allclose(D, D[0, 0] * np.eye(D.shape[0])):
        return "gain", f"{D[0, 0]:.4g}"
    return "block", None


def _kind(s):
    if isinstance(s, ct.InterconnectedSystem):
        names = ", ".join(sub.name for sub in s.syslist)
        return names if len(names) <= 20 else f"{len(s.syslist)} blocks"
    if _discrete(s):  # with or without states: sampled, held between its instants
        return "discrete" if s.dt is True else f"dt = {s.dt:g}"
    if not s.nstates:
        return "static"
    return "continuous"


def _discrete(s) -> bool:
    """Whether ``s`` runs at sample instants (``dt = Ts`` or ``dt = True``)."""
    return not isinstance(s, ct.InterconnectedSystem) and (
        s.dt is True or s.dt is not None and s.dt > 0)


# ----------------------------------------------------------------------------- wiring

class _Net:
    """One signal (bundle) from one source to one or more destinations."""

    def __init__(self, src, signals):
        self.src = src                 # node name, or _IN
        self.signals = list(signals)   # the source's signal names
        self.dests = []                # [(node, ports, sign)]; node may be _OUT
        self.label = ""
        self.color = _BLUE


def _nets(sys, nodes, sums=None):
    """Group the connection map into nets; implicit sums become virtual sum nodes.

    ``sums`` (``{block: {input base name: sign}}``) draws the sum a block computes
    first (``F (r - h)``: ``{"controller": {"r": 1, "h": -1}}``) as a junction in front of it.
    """
    sums = sums or {}
    out_owner, in_owner = _owners(sys)
    rank = _block_rank(sys)  # the blocks taken in the wiring's order, never the list's
    sizes = defaultdict(int)
    for _, name in out_owner:
        sizes[_base(name)] += 1
    for name in sys.input_labels:
        sizes[_base(name)] += 1
    wires = []  # (src node, src signal, dst node, dst port, sign)
    for i in sorted(range(len(in_owner)), key=lambda i: (rank[in_owner[i][0]], i)):
        block, port = in_owner[i]
        feeds = [(out_owner[j][0], out_owner[j][1], sys.connect_map[i, j])
                 for j in sorted(np.nonzero(sys.connect_map[i])[0],
                                 key=lambda j: (rank[out_owner[j][0]], j))]
        feeds += [(_IN, sys.input_labels[e], sys.input_map[i, e])
                  for e in np.nonzero(sys.input_map[i])[0]]
        if block in sums and _base(port) in sums[block]:  # a sum inside the block
            virtual = f"{block}:sum"
            nodes.setdefault(virtual, {"shape": "sum", "signs": {}, "label": "", "math": False,
                                       "sub": "", "virtual": True})
            for a, sig, g in feeds:
                wires.append((a, sig, virtual, sig, g * sums[block][_base(port)]))
            wires.append((virtual, f"sum~{port}", block, port, 1.0))
            continue
        if len(feeds) >= 2:  # the connection map sums these signals into the port
            key = "+".join(f"{a}" for a, _, _ in feeds)
            virtual = f"{block}:{_base(port)}:{key}"
            if virtual not in nodes:
                nodes[virtual] = {"shape": "sum", "signs": {}, "label": "", "math": False,
                                  "sub": "", "virtual": True}
            for a, sig, g in feeds:
                wires.append((a, sig, virtual, sig, g))
                nodes[virtual]["signs"][sig] = g
            wires.append((virtual, f"{_base(port)}~{port}", block, port, 1.0))
        for a, sig, g in feeds if len(feeds) == 1 else ():
            wires.append((a, sig, block, port, g))
    by_signal = defaultdict(list)
    for a, sig, b, port, g in wires:
        by_signal[(a, sig)].append((b, port, g))
    for r, row in enumerate(sys.output_map[:, :len(out_owner)]):
        for j in np.nonzero(row)[0]:
            by_signal[out_owner[j]].append((_OUT, sys.output_labels[r], 1.0))
    # signals of one source going to the same places with the same signs form one net
    bundles = {}
    for (a, sig), dests in by_signal.items():
        where = tuple(sorted({(b, np.sign(g)) for b, _, g in dests if b != _OUT}))
        # separate external inputs, and separate signals into a junction, keep their own
        # arrows (and signs); a vector's elements always travel together
        apart = a == _IN or any(nodes.get(b, {}).get("shape") == "sum" for b, _, _ in dests)
        key = (a, where, _base(sig.split("~")[-1]) if apart else None)
        net = bundles.setdefault(key, _Net(a, []))
        net.signals.append(sig)
        for b, port, g in dests:
            net.dests.append((b, port, g))
    nets = []
    for net in bundles.values():
        shown = [s.split("~")[-1] if "~" in s else s for s in net.signals]
        label = _signal_label(shown, sizes)
        gains = {g for _, _, g in net.dests}
        if len(gains) == 1 and (g := gains.pop()) not in (1.0,) and not any(
                nodes.get(b, {}).get("shape") == "sum" for b, _, _ in net.dests):
            label = f"-{label}" if g == -1 else f"{g:g}*{label}"
        net.label = _wrap(label)
        merged = defaultdict(list)
        for b, port, g in net.dests:
            merged[(b, np.sign(g))].append(port)
        net.dests = [(b, ports, sign) for (b, sign), ports in merged.items()]
        nets.append(net)
    return nets, sizes
