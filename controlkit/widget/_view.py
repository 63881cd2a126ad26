"""What the editor's front end draws: blocks with ports, edges, frames, in pixels.

Blocks of an opened diagram are placed where :func:`controlkit.drawing.draw_block_diagram`
places them (its layout, read once through :func:`_drawing_layout`), so the editor
opens looking like the drawing; blocks added later sit where they were dropped.
"""

from __future__ import annotations

import warnings

import control as ct
import numpy as np

from . import _palette, _sources
from ._ports import port_groups
from ._problems import passes_input

#: Pixels per inch of the drawing's layout.
SCALE = 80.0
PORT_PITCH = 22.0


def _drawing_layout(sys):
    """The drawing's layout of ``sys`` (the one place this module reads controlkit.drawing).

    Uses the fields ``nodes`` (``x``, ``y``, ``w``, ``h``, ``flip``, ``virtual``),
    ``nets`` (``src``, ``signals``, ``dests``), ``in_xy`` and ``port_xy``.
    """
    from controlkit.drawing._layout import layout

    return layout(sys)


def shape_of(system):
    """``("sum", {input: sign})``, ``("gain", text)``, ``("group", None)`` or ``("block", None)``.

    Examples
    --------
    >>> import control as ct
    >>> shape_of(ct.summing_junction(inputs=["r", "-y"], output="e"))
    ('sum', {'r': 1.0, 'y': -1.0})
    >>> shape_of(ct.tf(2.5, 1, dt=None))
    ('gain', '2.5')
    """
    if isinstance(system, ct.InterconnectedSystem):
        return "group", None
    if not isinstance(system, (ct.StateSpace, ct.TransferFunction)):
        return "block", None
    try:
        ss = system if isinstance(system, ct.StateSpace) else ct.tf2ss(system)
    except Exception:  # noqa: BLE001 - an improper tf is drawn as a block
        return "block", None
    if ss.nstates:
        return "block", None
    D = np.asarray(ss.D, dtype=float)
    if (D.size and set(np.unique(D).tolist()) <= {-1.0, 0.0, 1.0} and D.shape[1] >= 2
            and np.count_nonzero(D, axis=1).min() >= 2
            and np.count_nonzero(D, axis=0).max() == 1):
        return "sum", {label: float(D[:, c].sum()) for c, label in enumerate(system.input_labels)}
    if D.shape[0] == D.shape[1] and D.size and np.allclose(D, D[0, 0] * np.eye(D.shape[0])):
        return "gain", f"{D[0, 0]:.4g}"
    return "block", None


def states_of(system):
    """Number of states (a transfer function's, of its state-space realisation)."""
    if isinstance(system, ct.TransferFunction):
        try:
            return int(ct.tf2ss(system).nstates)
        except Exception:  # noqa: BLE001 - an improper tf has no realisation
            return 0
    return int(system.nstates or 0)


def kind_of(system):
    """How a block runs in time, written as the static drawing writes it under its name:
    ``dt = 0.1`` (discrete, states or not: it holds its output between its instants),
    ``discrete`` (``dt=True``), ``static``, ``continuous``, or ``n blocks``.

    Examples
    --------
    >>> import control as ct
    >>> kind_of(ct.tf(2.0, 1, 0.1)), kind_of(ct.tf(2.0, 1, None)), kind_of(ct.tf(1, [1, 1]))
    ('dt = 0.1', 'static', 'continuous')
    """
    if isinstance(system, ct.InterconnectedSystem):
        return f"{len(system.syslist)} blocks"
    if is_discrete(system):
        return "discrete" if system.dt is True else f"dt = {system.dt:g}"
    return "continuous" if states_of(system) else "static"


def is_discrete(system):
    """Whether a block runs at sample instants (``dt = Ts`` or ``dt = True``)."""
    return system.dt is True or (system.dt is not None and system.dt > 0)


def place(model):
    """Give every block without a position (or look) the drawing's, in pixels.

    On opening (or :func:`relayout`) every block is where
    :func:`~controlkit.drawing.draw_block_diagram` puts it. A block added later without a
    position starts where the drawing would put it and moves to the nearest spot that
    overlaps no other block (:func:`free_spot`).
    """
    missing = [n for n, b in model.blocks.items() if b.position is None or b.look is None]
    if not missing:
        return
    fresh = len(missing) == len(model.blocks)
    unplaced = [n for n in missing if model.blocks[n].position is None]
    L = _layout_of(model)
    if L is None:  # nothing can be built: a row in the order the signals flow
        for k, n in enumerate(flow_order(model)):
            block = model.blocks[n]
            if n in missing:
                block.position = block.position or (180.0 * k, 0.0)
                block.look = block.look or {}
    else:
        order = _port_order(L)
        for n in missing:
            block, node = model.blocks[n], L.nodes.get(n, {})
            if block.position is None:
                block.position = (node.get("x", 0.0) * SCALE, -node.get("y", 0.0) * SCALE)
            heights = order.get(n, {})
            block.look = {"w": node.get("w", 0.0) * SCALE, "h": node.get("h", 0.0) * SCALE,
                          "flip": bool(node.get("flip", False)),
                          "order": {side: {sig: y for (s, sig), y in heights.items()
                                           if s == side} for side in ("in", "out")}}
    if not fresh:
        for n in unplaced:
            model.blocks[n].position = free_spot(model, n, model.blocks[n].position)


def relayout(model):
    """Place every block again as the static drawing places it (the *re-layout* button);
    blocks wired to nothing go in a row under the diagram, clear of its feedback lanes."""
    for block in model.blocks.values():
        block.position = block.look = None
    place(model)
    wired = {w.src[0] for w in model.wires} | {w.dst[0] for w in model.wires} | {
        b for _, targets in model.inputs for b, _, _ in targets} | {
        s[1] for _, sources in model.outputs for s in sources}
    loose = [n for n in flow_order(model) if n not in wired]
    placed = [_rect(model, n) for n in model.blocks if n in wired]
    if loose and placed:
        x = min(r[0] for r in placed) + 60.0
        y = max(r[3] for r in placed) + 160.0
        for name in loose:
            x0, _, x1, _ = _rect(model, name, (0.0, 0.0))
            model.blocks[name].position = (x - x0, y)
            x += x1 - x0 + 60.0


def _layout_of(model):
    """The drawing's layout of the model, built as well as it can be (None: it cannot)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return _drawing_layout(model.system())
        except ValueError:  # wiring errors: python-control builds it anyway, for the picture
            pass
        try:
            from controlkit.sampled_data import interconnect

            from ._specs import interconnect_specs

            connections, inplist, inputs, outlist, outputs = interconnect_specs(model)
            sys = interconnect(model.systems(), connections=connections or False,
                               inplist=inplist, inputs=inputs, outlist=outlist,
                               outputs=outputs, name=model.name)
            sys.drawing_hints = model.drawing_hints()
            return _drawing_layout(sys)
        except (ValueError, TypeError, KeyError):
            return None


def flow_order(model):
    """Blocks in the order signals flow: from the ones the external inputs drive, along the
    wires (breadth first, names sorted), whatever order the blocks were given in.

    Examples
    --------
    >>> import control as ct
    >>> from controlkit.widget import DiagramModel
    >>> a = ct.ss(-1.0, 1.0, 1.0, 0.0, name="a", inputs="u", outputs="y")
    >>> b = ct.ss(-2.0, 1.0, 1.0, 0.0, name="b", inputs="y", outputs="z")
    >>> flow_order(DiagramModel.from_interconnect(ct.interconnect([b, a], inputs="u",
    ...                                                           outputs="z")))
    ['a', 'b']
    """
    successors = {n: set() for n in model.blocks}
    for w in model.wires:
        successors[w.src[0]].add(w.dst[0])
    driven = {w.dst[0] for w in model.wires}
    start = sorted({b for _, targets in model.inputs for b, _, _ in targets}) or sorted(
        set(model.blocks) - driven) or sorted(model.blocks)[:1]
    order, queue = [], list(start)
    while queue or len(order) < len(model.blocks):
        if not queue:
            queue = [min(set(model.blocks) - set(order))]
        n = queue.pop(0)
        if n in order:
            continue
        order.append(n)
        queue += sorted(successors[n] - set(order))
    return order


def block_size(model, name):
    """A block's width and height on the canvas: the drawing's, grown to fit its ports and
    its names at the editor's font sizes (pixels)."""
    b = model.blocks[name]
    shape = shape_of(b.system)[0]
    look = b.look or {}
    w = look.get("w") or (40.0 if shape == "sum" else 120.0)
    h = look.get("h") or (40.0 if shape == "sum" else 60.0)
    if shape != "sum":
        ports = max(len(model.ports(name, "in")), len(model.ports(name, "out")), 1)
        kind = kind_of(b.system)
        h = max(h, PORT_PITCH * ports + 14.0)
        w = max(w, 6.2 * len(kind if b.label is None else f"{name}, {kind}") + 26.0,
                96.0 if shape != "gain" else 56.0)
    return w, h


def _rect(model, name, position=None, margin=0.0):
    x, y = position or model.blocks[name].position
    w, h = block_size(model, name)
    return (x - w / 2 - margin, y - h / 2 - margin, x + w / 2 + margin, y + h / 2 + margin)


def free_spot(model, name, near, margin=30.0):
    """The position nearest ``near`` where block ``name`` overlaps no other block (with
    ``margin`` pixels around it for wires and labels), on a 20-pixel grid."""
    others = [_rect(model, n) for n, b in model.blocks.items() if n != name and b.position]

    def free(position):
        x0, y0, x1, y1 = _rect(model, name, position, margin)
        return not any(x0 < r[2] and r[0] < x1 and y0 < r[3] and r[1] < y1 for r in others)

    x, y = near
    for ring in range(0, 80):
        for dx in range(-ring, ring + 1):
            for dy in (range(-ring, ring + 1) if abs(dx) == ring else (-ring, ring)):
                candidate = (x + 20.0 * dx, y + 20.0 * dy)
                if free(candidate):
                    return candidate
    return near


def view(model):
    """The payload of the editor's ``diagram`` trait (see the front end's ``render``)."""
    blocks = []
    sums = model.hints.get("sums", {})
    external_in = {}
    for name, targets in model.inputs:
        for block, signal, gain in targets:
            external_in.setdefault((block, signal), []).append((name, gain))
    external_out = {}
    for name, sources in model.outputs:
        for side, block, signal, _ in sources:
            if side == "out":
                external_out.setdefault((block, signal), []).append(name)
    driven = {w.dst for w in model.wires} | set(external_in)
    for name, b in model.blocks.items():
        s = b.system
        shape, extra = shape_of(s)
        node = b.look or {}
        ins = model.ports(name, "in")
        outs = model.ports(name, "out")
        order = node.get("order", {})  # top to bottom as in the drawing
        ins.sort(key=lambda p: min(order.get("in", {}).get(sig, 0.0) for sig in p[1]))
        outs.sort(key=lambda p: min(order.get("out", {}).get(sig, 0.0) for sig in p[1]))
        w, h = block_size(model, name)
        hint_signs = sums.get(name, {})
        inputs = []
        for k, (port, signals) in enumerate(ins):
            base = port.split("[")[0]
            sign = None
            if shape == "sum":
                sign = extra.get(signals[0], 1.0)
            elif base in hint_signs:
                sign = float(hint_signs[base])
            inputs.append({
                "port": port, "signals": signals, "sign": sign,
                "side": _sum_side(k, len(ins)) if shape == "sum" else "left",
                "junction": base in hint_signs,
                "loose": any((name, sig) not in driven for sig in signals),
                "external": sorted({e for sig in signals for e, _ in
                                    external_in.get((name, sig), [])})})
        outputs = [{"port": port, "signals": signals,
                    "external": sorted({e for sig in signals
                                        for e in external_out.get((name, sig), [])})}
                   for port, signals in outs]
        label = b.label
        kind = kind_of(s)
        sub = (f"{name}, {kind}" if kind != "static" else name) if label else kind
        params = model.parameters(name)
        blocks.append({
            "name": name, "label": label or name, "math": bool(label), "sub": sub,
            "shape": shape, "gain": extra if shape == "gain" else None,
            "x": float(b.position[0]), "y": float(b.position[1]), "w": float(w), "h": float(h),
            "flip": bool(node.get("flip", False)), "inputs": inputs, "outputs": outputs,
            "params": {k: float(v) for k, v in params.items()},
            "recipe": (b.recipe or {}).get("kind"), "nstates": states_of(s),
            "dt": None if s.dt is None or s.dt is True else float(s.dt),
            "discrete": is_discrete(s) and not isinstance(s, ct.InterconnectedSystem),
            "feedthrough": passes_input(s),
        })
    return {"name": model.name, "title": model.hints.get("title") or model.name,
            "mixed": model.is_mixed(),
            "blocks": blocks, "edges": _edges(model), "inputs": _external_inputs(model),
            "setup": _setup(model),
            "groups": [{"label": g, "members": [m for m in members if m in model.blocks]}
                       for g, members in model.hints.get("groups", {}).items()],
            "signals": [f"{n}.{label}" for n, b in model.blocks.items()
                        for label in b.system.output_labels],
            "palette": palette_entries()}


def _sum_side(k, n):
    """Inputs of a junction: the first from the left, the second from below, then above."""
    return ("left", "bottom", "top")[k] if n <= 3 else "left"


def _port_of(model, block, side, signal):
    for port, signals in model.ports(block, side):
        if signal in signals:
            return port, signals
    raise ValueError(f"{block}.{signal} is in no port")


def _edges(model):
    """Wires grouped by the ports they join (one edge per port pair and sign)."""
    groups = {}
    for w in model.wires:
        sport, ssig = _port_of(model, w.src[0], "out", w.src[1])
        dport, dsig = _port_of(model, w.dst[0], "in", w.dst[1])
        key = (w.src[0], sport, w.dst[0], dport, float(np.sign(w.gain)))
        groups.setdefault(key, {"pairs": [], "gains": set(), "swidth": len(ssig),
                                "dwidth": len(dsig), "ssig": ssig, "dsig": dsig})
        groups[key]["pairs"].append((w.src[1], w.dst[1]))
        groups[key]["gains"].add(w.gain)
    edges = []
    for (src, sport, dst, dport, sign), g in groups.items():
        whole = (g["swidth"] == g["dwidth"] == len(g["pairs"])
                 and all(a == g["ssig"][i] and b == g["dsig"][i]
                         for i, (a, b) in enumerate(sorted(
                             g["pairs"], key=lambda p: g["dsig"].index(p[1])))))
        label = sport.split("[")[0] if whole else ", ".join(a for a, _ in g["pairs"])
        gains = g["gains"]
        gain = gains.pop() if len(gains) == 1 else None
        if gain not in (None, 1.0, -1.0):
            label = f"{gain:g}*{label}"
        edges.append({"id": f"{src}|{sport}|{dst}|{dport}|{'-' if sign < 0 else '+'}",
                      "source": src, "sourcePort": sport, "target": dst, "targetPort": dport,
                      "label": label, "sign": sign, "whole": whole,
                      "signals": [list(p) for p in g["pairs"]]})
    return edges


def _external_inputs(model):
    """External inputs as the diagram draws them: one terminal per target port
    (``{id, label, groups, names, target, port, sign, source}``), and one per input that
    drives nothing yet (``target`` None)."""
    out = {}
    for name, targets in model.inputs:
        for block, signal, gain in targets:
            port, _ = _port_of(model, block, "in", signal)
            entry = out.setdefault((block, port), {"names": [], "target": block, "port": port,
                                                   "sign": float(np.sign(gain))})
            entry["names"].append(name)
    result = []
    for (block, port), entry in out.items():
        entry["id"] = f"in:{block}:{port}"
        result.append(entry)
    attached = dict(model.inputs)
    for label, names in model.input_groups():
        if not any(attached[n] for n in names):
            result.append({"id": f"in:free:{label}", "names": names, "target": None,
                           "port": None, "sign": 1.0})
    for entry in result:
        groups = port_groups(entry["names"])
        entry["groups"] = [g for g, _ in groups]
        entry["label"] = ", ".join(entry["groups"])
        texts = {_sources.short(model.source_of(n)) for n in entry["names"]}
        entry["source"] = texts.pop() if len(texts) == 1 else "sources"
    return result


def _setup(model):
    """The run's setup as the page edits it: sources by input, initial states by block."""
    sources = {}
    for name, _ in model.inputs:
        src = model.source_of(name)
        sources[name] = {**src, "text": _sources.describe(src)}
    initial = {}
    for name, b in model.blocks.items():
        n = b.system.nstates
        if n:
            given = model.initial.get(name)
            own = getattr(b.system, "x0", None)
            shown = given if given is not None else (
                np.zeros(n) if own is None else np.asarray(own, dtype=float).reshape(-1))
            initial[name] = {"values": [float(v) for v in shown], "set": given is not None,
                             "states": list(b.system.state_labels)}
    return {"horizon": model.horizon, "sources": sources, "kinds": _sources.KINDS,
            "initial": initial}


def _port_order(L):
    """Height of each signal's port in the drawing: ``{block: {(side, signal): -y}}``."""
    order = {}
    for net in L.nets:
        if (net, net.src) in L.port_xy and not L.nodes.get(net.src, {}).get("virtual"):
            y = L.port_xy[(net, net.src)][1]
            for sig in net.signals:
                order.setdefault(net.src, {})[("out", sig)] = -y
        for b, ports, _ in net.dests:
            if (net, b) not in L.in_xy:
                continue
            y = L.in_xy[(net, b)][1]
            owner = b.split(":")[0] if L.nodes.get(b, {}).get("virtual") else b
            for sig in ports:
                order.setdefault(owner, {})[("in", sig.split("~")[-1])] = -y
    return order


def palette_entries():
    """The palette as the front end lists it."""
    return [{"key": e.key, "title": e.title, "group": e.group,
             "tip": e.source(e.name, _palette.defaults(e.key, None))}
            for e in _palette.ENTRIES if e.shown]
