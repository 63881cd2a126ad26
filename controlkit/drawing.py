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
  or from a ``display_name`` attribute of a block.

Block and signal names are drawn literally (python-control's ``plant$sampled``
stays as it is); only labels given explicitly as display names are TeX.
Unconnected inputs and unused outputs are marked in red. No Graphviz or other
system package is needed.
"""

from __future__ import annotations

import re
from collections import defaultdict
from pathlib import Path

import control as ct
import numpy as np

_IN, _OUT = "inputs", "outputs"
_BLUE, _RED, _GREY, _FILL = "#1f3b6e", "#b03a2e", "#333333", "#eef3fb"


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
    >>> from controlkit.diagrams.spacecraft import output_zeroing_loop
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
    if not s.nstates:
        return "static"
    return "continuous" if s.isctime(strict=True) else f"dt = {s.dt:g}"


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
    sizes = defaultdict(int)
    for _, name in out_owner:
        sizes[_base(name)] += 1
    for name in sys.input_labels:
        sizes[_base(name)] += 1
    wires = []  # (src node, src signal, dst node, dst port, sign)
    for i, (block, port) in enumerate(in_owner):
        feeds = [(out_owner[j][0], out_owner[j][1], sys.connect_map[i, j])
                 for j in np.nonzero(sys.connect_map[i])[0]]
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
        net = bundles.setdefault((a, where), _Net(a, []))
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
    of it), ``beside`` (``{block: other}``: put
    ``block`` in the column of ``other``, on a row of its own - a branch in
    parallel), ``rows`` (``{block: row}``, 0 the main row) and ``notes``
    (``{block: text}``, a second line inside the block). External outputs that
    are signals already drawn inside the diagram are not drawn again; those of
    blocks in the last column leave it on the right.

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
        ins = sorted(in_ports[n], key=lambda p: -(1e3 if p[1] == "skip" else -1e3
                                                   if p[1] == "back" else source_y(p[0])))
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
        x0 = gap_x[g] + label_w[g] + 0.1 if g > 0 else gap_x[g] + 0.15

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
            elif not nodes[net.src]["virtual"] and not (net.out and not net.dangling):
                text(sx + 0.07, sy + 0.04, net.label, ha="left", va="bottom", color=color,
                     bbox=white, zorder=6)
        else:
            sx = gap_x[0]
            firsts = [in_xy[(net, b)][1] for b in net.kinds]
            sy = firsts[0]
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
        points = {p for s in segs for p in s}
        for p in points:
            arms = set()
            for a, b in segs:
                for end, other in ((a, b), (b, a)):
                    if np.allclose(end, p):
                        arms.add((np.sign(round(other[0] - p[0], 6)),
                                  np.sign(round(other[1] - p[1], 6))))
                if not (np.allclose(a, p) or np.allclose(b, p)) and _on(p, a, b):
                    arms.add((np.sign(round(a[0] - p[0], 6)), np.sign(round(a[1] - p[1], 6))))
                    arms.add((np.sign(round(b[0] - p[0], 6)), np.sign(round(b[1] - p[1], 6))))
            arms.discard((0.0, 0.0))
            if len(arms) >= 3:
                ax.plot(*p, marker="o", markersize=4.5, color=net.color, zorder=6,
                        gid=f"dot:{net.src}:{net.label}")

    # --- nodes
    for n, node in nodes.items():
        x, y, w, h = node["x"], node["y"], node["w"], node["h"]
        if node["shape"] == "sum":
            ax.add_patch(Circle((x, y), w / 2, facecolor="white", edgecolor=_BLUE,
                                linewidth=1.4, zorder=4))
            for feed in [net for net in nets if n in net.kinds]:
                px, py, side = in_xy[(feed, n)]
                # the wire's gain times, for a summing_junction block, the port's sign
                sign = next(np.sign(g) * (1.0 if node["virtual"]
                                          else node["signs"].get(ports[0], 1.0))
                            for b, ports, g in feed.dests if b == n)
                mark = "+" if sign > 0 else "\u2212"
                dx, dy = {"left": (-0.1, 0.13), "bottom": (-0.13, -0.12),
                          "top": (-0.13, 0.12)}[side]
                text(px + dx, py + dy, mark, size=f_sig + 1, ha="center", va="center",
                     color=_BLUE, weight="bold")
            continue
        if node["shape"] == "gain":
            f = -1 if node.get("flip") else 1
            ax.add_patch(Polygon([(x - f * w / 2, y - h / 2), (x - f * w / 2, y + h / 2),
                                  (x + f * w / 2, y)], closed=True, facecolor=_FILL,
                                 edgecolor=_BLUE, linewidth=1.4, zorder=4))
            text(x - f * w / 6, y, node["text"], size=f_name, math=node["math"], ha="center",
                 va="center", zorder=5)
            continue
        ax.add_patch(FancyBboxPatch((x - w / 2, y - h / 2), w, h,
                                    boxstyle="round,pad=0.02,rounding_size=0.06", zorder=4,
                                    facecolor=_FILL, edgecolor=_BLUE, linewidth=1.4))
        if node["shape"] == "group":
            ax.add_patch(Rectangle((x - w / 2 + 0.05, y - h / 2 + 0.05), w - 0.1, h - 0.1,
                                   fill=False, edgecolor=_BLUE, linewidth=0.8, zorder=4))
        text(x, y + 0.11, node["label"], size=f_name, math=node["math"], ha="center",
             va="center", weight="bold", zorder=5)
        text(x, y - 0.17, node["sub"], size=f_sub, ha="center", va="center", color="#555",
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
        x1 = max(nodes[m]["x"] + nodes[m]["w"] / 2 for m in members) + 0.2
        y1 = max(nodes[m]["y"] + nodes[m]["h"] / 2 for m in members) + 0.4
        y0 = min([nodes[m]["y"] - nodes[m]["h"] / 2 for m in members]
                 + [lane_bottom[net] for net in inside]) - 0.12
        ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, edgecolor=_RED,
                               linewidth=1.2, linestyle="--", zorder=1))
        text(x0 + 0.08, y1 - 0.05, glabel, size=f_sig + 1, math=True, ha="left", va="top",
             color=_RED, weight="bold")

    text(x_mid, y_title, title, size=f_name + 1, math=title_math, ha="center", va="center")
    if filename is not None:
        import matplotlib as mpl

        with mpl.rc_context({"svg.fonttype": "none"}):
            fig.savefig(Path(filename), dpi=160)
    return fig


def _sum_ports(n, node, ins, source_y, in_xy, nodes, layer, row):
    """Where signals enter a junction: one from the left, those from other rows and
    lanes from above or below (lanes outermost), so no two entries share a line."""
    r, x, y = node["w"] / 2, node["x"], node["y"]
    vertical = [p for p in ins if p[1] in ("skip", "back")
                and _vertical_ok(n, p[1], nodes, layer, row)]
    rest = [p for p in ins if p not in vertical]
    left = sorted(rest, key=lambda p: abs(source_y(p[0]) - y))[:1]
    below = sorted([p for p in rest if p not in left and p[1] == "next"
                    and source_y(p[0]) < y - r], key=lambda p: -source_y(p[0]))
    above = sorted([p for p in rest if p not in left and p[1] == "next"
                    and source_y(p[0]) > y + r], key=lambda p: source_y(p[0]))
    left = [p for p in rest if p not in below and p not in above]
    sides = (("left", left), ("bottom", below + [p for p in vertical if p[1] == "back"]),
             ("top", above + [p for p in vertical if p[1] == "skip"]))
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


def _on(p, a, b):
    (px, py), (ax_, ay), (bx, by) = p, a, b
    if np.isclose(ax_, bx) and np.isclose(px, ax_):
        return min(ay, by) - 1e-9 <= py <= max(ay, by) + 1e-9
    if np.isclose(ay, by) and np.isclose(py, ay):
        return min(ax_, bx) - 1e-9 <= px <= max(ax_, bx) + 1e-9
    return False
