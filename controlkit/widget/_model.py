"""The editor's diagram as plain data: blocks, wires between their signals, and checks.

A :class:`DiagramModel` is read from any ``control.InterconnectedSystem``
(python-control's connection maps), edited (connect, disconnect, add, delete,
move, change a parameter) and turned back into a ``control.interconnect``
call, as an object (:meth:`DiagramModel.system`) and as source code
(:meth:`DiagramModel.code`). Wires join one output signal to one input signal
with a gain (python-control's ``connect_map`` entry); the editor shows them
grouped into ports (:func:`~controlkit.widget._ports.port_groups`).
"""

from __future__ import annotations

import copy
import json
import keyword
import re
import warnings
from dataclasses import dataclass, field

import control as ct
import numpy as np

from ..blocks.sampling import SampledSystem
from . import _palette
from ._ports import compress_range, next_element, port_groups, runs

FORMAT = "controlkit.widget/1"


@dataclass
class Block:
    """One block of the diagram.

    Attributes
    ----------
    system : control.InputOutputSystem
        The block itself.
    recipe : dict or None
        How to build it again: ``{"kind": palette key, "kwargs": {...}}``,
        ``{"kind": "variable", "variable": name}`` (an object of the notebook), or None
        for a block taken as it is from an opened interconnect.
    label : str or None
        Display name (TeX, e.g. ``"$L_a$"``).
    position : tuple of float or None
        Centre on the editor's canvas, in pixels.
    look : dict or None
        Size, orientation and port order the editor draws it with (``w``, ``h``,
        ``flip``, ``order``), taken from the drawing's layout when first placed.
    """

    system: ct.InputOutputSystem
    recipe: dict | None = None
    label: str | None = None
    position: tuple | None = None
    look: dict | None = None


@dataclass
class Wire:
    """Output ``src = (block, signal)`` feeds input ``dst = (block, signal)`` times ``gain``."""

    src: tuple
    dst: tuple
    gain: float = 1.0


@dataclass
class Problem:
    """A wiring mistake: ``kind`` is one of :data:`PROBLEM_KINDS`, ``blocks`` the blocks named."""

    kind: str
    severity: str
    blocks: list
    message: str

    def as_dict(self):
        return {"kind": self.kind, "severity": self.severity, "blocks": list(self.blocks),
                "message": self.message}


#: What :meth:`DiagramModel.problems` reports; ``error`` problems stop a run.
PROBLEM_KINDS = {"unconnected input": "warning", "two drivers": "error",
                 "algebraic loop": "error", "mismatched timebases": "error",
                 "unused output": "note"}


@dataclass
class DiagramModel:
    """A block diagram being edited; see the module docstring.

    Examples
    --------
    >>> import control as ct
    >>> motor = ct.tf2ss(ct.tf([1], [1, 1]), name="motor", inputs="v", outputs="w")
    >>> pi = ct.tf2ss(ct.tf([2, 1], [1, 0]), name="pi", inputs="e", outputs="v")
    >>> error = ct.summing_junction(inputs=["w_ref", "-w"], output="e", name="error")
    >>> loop = ct.interconnect([error, pi, motor], inputs="w_ref", outputs="w")
    >>> model = DiagramModel.from_interconnect(loop)
    >>> [f"{w.src[0]}.{w.src[1]} -> {w.dst[0]}.{w.dst[1]}" for w in model.wires]
    ['motor.w -> error.w', 'error.e -> pi.e', 'pi.v -> motor.v']
    >>> np.array_equal(model.system().connect_map, loop.connect_map)
    True
    """

    name: str = "diagram"
    blocks: dict = field(default_factory=dict)
    wires: list = field(default_factory=list)
    inputs: list = field(default_factory=list)   # [(name, [(block, signal, gain), ...])]
    outputs: list = field(default_factory=list)  # [(name, [(side, block, signal, gain)])]
    summed: set = field(default_factory=set)     # inputs whose several drivers are meant
    hints: dict = field(default_factory=dict)    # groups, sums, beside, rows, notes, title
    source_name: str | None = None               # the variable holding the opened diagram

    # ------------------------------------------------------------------ reading

    @classmethod
    def from_interconnect(cls, sys, *, source_name=None):
        """The model of ``sys``: its blocks, wires, external signals and drawing hints.

        Parameters
        ----------
        sys : control.InterconnectedSystem
            Any interconnect (a builder's, or your own).
        source_name : str, optional
            The variable that holds ``sys``, used by :meth:`code`.
        """
        if not isinstance(sys, ct.InterconnectedSystem):
            raise ValueError(f"sys must be a control.InterconnectedSystem (built with "
                             f"control.interconnect), got {type(sys).__name__}")
        hints = copy.deepcopy(dict(getattr(sys, "drawing_hints", None) or {}))
        labels = dict(hints.pop("labels", {}))
        for s in sys.syslist:  # a block's own junction (r - h in front of F), as drawn
            if getattr(s, "junction", None):
                hints.setdefault("sums", {}).setdefault(s.name, dict(s.junction))
        model = cls(name=sys.name, hints=hints, source_name=source_name)
        out_owner, in_owner = [], []
        for s in sys.syslist:
            if s.name in model.blocks:
                raise ValueError(f"two blocks are named {s.name!r}; the editor needs unique "
                                 f"block names")
            label = labels.get(s.name, getattr(s, "display_name", None))
            model.blocks[s.name] = Block(s, _palette.recognise(s), label)
            out_owner += [(s.name, label) for label in s.output_labels]
            in_owner += [(s.name, label) for label in s.input_labels]
        drivers = {}
        for i, dst in enumerate(in_owner):
            for j in np.nonzero(sys.connect_map[i])[0]:
                model.wires.append(Wire(out_owner[j], dst, float(sys.connect_map[i, j])))
                drivers[dst] = drivers.get(dst, 0) + 1
        for e, name in enumerate(sys.input_labels):
            targets = [(*in_owner[i], float(sys.input_map[i, e]))
                       for i in np.nonzero(sys.input_map[:, e])[0]]
            for block, signal, _ in targets:
                drivers[(block, signal)] = drivers.get((block, signal), 0) + 1
            model.inputs.append((name, targets))
        n_out = len(out_owner)
        for r, name in enumerate(sys.output_labels):
            sources = []
            for j in np.nonzero(sys.output_map[r])[0]:
                side, (block, signal) = ("out", out_owner[j]) if j < n_out else (
                    "in", in_owner[j - n_out])
                sources.append((side, block, signal, float(sys.output_map[r, j])))
            model.outputs.append((name, sources))
        model.summed = {dst for dst, n in drivers.items() if n > 1}  # sums written in code
        return model

    # ------------------------------------------------------------------ ports

    def ports(self, block, side):
        """``[(port, [signals])]`` of one side (``"in"`` or ``"out"``) of ``block``."""
        s = self._block(block).system
        return port_groups(s.input_labels if side == "in" else s.output_labels)

    def port_signals(self, block, side, port):
        """The signals of ``port``; a single signal of the block is accepted too."""
        s = self._block(block).system
        labels = s.input_labels if side == "in" else s.output_labels
        for name, members in self.ports(block, side):
            if name == port:
                return members
        if port in labels:
            return [port]
        where = "inputs" if side == "in" else "outputs"
        names = [name for name, _ in self.ports(block, side)]
        raise ValueError(f"block {block!r} has no {where[:-1]} port {port!r}; its {where}: "
                         f"{names}")

    def _block(self, name):
        if name not in self.blocks:
            raise ValueError(f"no block named {name!r} in the diagram; blocks: "
                             f"{list(self.blocks)}")
        return self.blocks[name]

    # ------------------------------------------------------------------ edits

    def connect(self, src_block, src_port, dst_block, dst_port, gain=1.0):
        """Wire output port ``src_port`` of ``src_block`` to input port ``dst_port``.

        The ports' signals are joined element by element, so both must be equally
        wide. An input that already has a driver keeps it: :meth:`problems` then
        reports two drivers until one wire is removed.

        Returns
        -------
        list of Wire
            The new wires.
        """
        outs = self.port_signals(src_block, "out", src_port)
        ins = self.port_signals(dst_block, "in", dst_port)
        if len(outs) != len(ins):
            raise ValueError(
                f"cannot connect {src_block}.{src_port} ({len(outs)} signal"
                f"{'s' if len(outs) != 1 else ''}) to {dst_block}.{dst_port} ({len(ins)} "
                f"signal{'s' if len(ins) != 1 else ''}): the ports must be equally wide")
        new = []
        for a, b in zip(outs, ins, strict=True):
            if any(w.src == (src_block, a) and w.dst == (dst_block, b) for w in self.wires):
                continue
            new.append(Wire((src_block, a), (dst_block, b), float(gain)))
        self.wires += new
        if new:
            self._rewired()
        return new

    def disconnect(self, src_block, src_port, dst_block, dst_port):
        """Remove the wires from output port ``src_port`` to input port ``dst_port``."""
        outs = set(self.port_signals(src_block, "out", src_port))
        ins = set(self.port_signals(dst_block, "in", dst_port))
        keep = [w for w in self.wires if not (w.src[0] == src_block and w.src[1] in outs
                                              and w.dst[0] == dst_block and w.dst[1] in ins)]
        if len(keep) == len(self.wires):
            raise ValueError(f"no wire runs from {src_block}.{src_port} to "
                             f"{dst_block}.{dst_port}")
        self.wires = keep
        self._rewired()

    def delete_block(self, name):
        """Remove a block with its wires, the external signals it had and its hints."""
        self._block(name)
        del self.blocks[name]
        self.wires = [w for w in self.wires if name not in (w.src[0], w.dst[0])]
        self.inputs = [(n, [t for t in targets if t[0] != name]) for n, targets in self.inputs]
        self.inputs = [(n, targets) for n, targets in self.inputs if targets]
        self.outputs = [(n, [s for s in sources if s[1] != name]) for n, sources in self.outputs]
        self.outputs = [(n, sources) for n, sources in self.outputs if sources]
        self.summed = {dst for dst in self.summed if dst[0] != name}
        for key in ("sums", "beside", "rows", "notes"):
            table = self.hints.get(key, {})
            for other in [k for k, v in table.items() if name in (k, v)]:
                del table[other]
        for members in self.hints.get("groups", {}).values():
            if name in members:
                members.remove(name)
        self._rewired()

    def _rewired(self):
        """A wire or a block changed: the diagram is no longer the one a builder's title
        named ("Fig. 3: ..."), so it is drawn under its name. A block's own symbol and
        junction stay: they describe the block, wherever it is wired."""
        self.hints.pop("title", None)

    def unique_name(self, base):
        """``base``, or ``base2``, ``base3``... whichever no block has yet."""
        if base not in self.blocks:
            return base
        k = 2
        while f"{base}{k}" in self.blocks:
            k += 1
        return f"{base}{k}"

    def add_block(self, system, *, recipe=None, label=None, position=None):
        """Add ``system`` as a block (its name must be new in the diagram)."""
        if not _palette.is_system(system):
            raise ValueError(f"a block must be a python-control I/O system (nlsys, ss, tf, "
                             f"interconnect), got {type(system).__name__}")
        if system.name in self.blocks:
            raise ValueError(f"a block named {system.name!r} is already in the diagram; "
                             f"give the new one another name")
        self.blocks[system.name] = Block(system, recipe, label, position)
        self._rewired()
        return system.name

    def add_from_palette(self, key, *, position=None, **kwargs):
        """Add a block of palette entry ``key`` (see :data:`~controlkit.widget.PALETTE`)."""
        entry = _palette.PALETTE.get(key)
        if entry is None:
            raise ValueError(f"palette entry must be one of {sorted(_palette.PALETTE)}, "
                             f"got {key!r}")
        options = {**_palette.defaults(key, self.period()), **kwargs}
        name = self.unique_name(entry.name)
        system = _palette.build(key, name, options, self.period())
        return self.add_block(system, recipe={"kind": key, "kwargs": options},
                              position=position)

    def add_variable(self, variable, value, *, position=None):
        """Add a system of the notebook held in ``variable`` (a copy if its name is taken)."""
        if not _palette.is_system(value):
            raise ValueError(f"variable {variable!r} holds a {type(value).__name__}, not a "
                             f"python-control I/O system")
        recipe = {"kind": "variable", "variable": variable, "system_name": value.name}
        if value.name in self.blocks:
            value = value.copy(name=self.unique_name(value.name))
        return self.add_block(value, recipe=recipe, position=position)

    def parameters(self, name):
        """The numeric parameters of a block that the editor can change: ``{name: value}``.

        Those of a palette (or recognised) recipe, else the numbers in the block's
        ``params`` dict (python-control's way of giving a block parameters).
        """
        block = self._block(name)
        recipe = block.recipe
        if recipe and recipe["kind"] in _palette.PALETTE:
            return _palette.PALETTE[recipe["kind"]].parameters(recipe["kwargs"])
        params = getattr(block.system, "params", None) or {}
        return {k: float(v) for k, v in params.items() if _palette._is_number(v)}

    def set_parameter(self, name, parameter, value):
        """Rebuild block ``name`` with ``parameter = value``; its wires stay where they fit."""
        block = self._block(name)
        allowed = self.parameters(name)
        if parameter not in allowed:
            raise ValueError(f"block {name!r} has no parameter {parameter!r}; its parameters: "
                             f"{sorted(allowed)}")
        value = float(value)
        if not np.isfinite(value):
            raise ValueError(f"parameter {parameter!r} of {name!r} must be finite, got {value}")
        recipe = block.recipe
        if recipe and recipe["kind"] in _palette.PALETTE:
            kwargs = {**recipe["kwargs"], parameter: value}
            system = _palette.build(recipe["kind"], name, kwargs, self.period())
            block.recipe = {"kind": recipe["kind"], "kwargs": kwargs}
        else:
            system = copy.copy(block.system)
            system.params = {**block.system.params, parameter: value}
        self._replace(name, system)

    def _replace(self, name, system):
        block = self.blocks[name]
        block.system = system
        ins, outs = set(system.input_labels), set(system.output_labels)
        self.wires = [w for w in self.wires if (w.src[0] != name or w.src[1] in outs)
                      and (w.dst[0] != name or w.dst[1] in ins)]

    # ------------------------------------------------------------------ building

    def period(self):
        """The diagram's sampling period: the one discrete ``dt`` of its blocks, else None."""
        periods = {s.dt for s in self.systems() if _timebase(s.dt) == "discrete"}
        return periods.pop() if len(periods) == 1 else None

    def systems(self):
        return [b.system for b in self.blocks.values()]

    def _specs(self):
        """``connections``, ``inplist``, ``inputs``, ``outlist``, ``outputs`` for interconnect."""
        by_dst = {}
        for w in self.wires:
            by_dst.setdefault(w.dst, []).append(w)
        connections = []
        for name, block in self.blocks.items():
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

        for run in runs(self.inputs, input_continues):
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

        for run in runs(self.outputs, output_continues):
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

    def system(self):
        """The diagram as a ``control.interconnect`` (with ``drawing_hints`` attached).

        Raises
        ------
        ValueError
            Listing the errors of :meth:`problems` (two drivers, algebraic loop,
            mismatched timebases), which python-control would not catch or would
            report without naming the blocks.
        """
        errors = [p.message for p in self.problems() if p.severity == "error"]
        if errors:
            raise ValueError("the diagram cannot be built: " + "; ".join(errors))
        if not self.blocks:
            raise ValueError("the diagram has no blocks")
        connections, inplist, inputs, outlist, outputs = self._specs()
        with warnings.catch_warnings():  # unused signals are reported by problems()
            warnings.filterwarnings("ignore", message=r"Unused (input|output)",
                                    category=UserWarning)
            sys = ct.interconnect(self.systems(), connections=connections or False,
                                  inplist=inplist, inputs=inputs, outlist=outlist,
                                  outputs=outputs, name=self.name)
        sys.drawing_hints = self.drawing_hints()
        return sys

    def drawing_hints(self):
        """The hints :func:`~controlkit.drawing.draw_block_diagram` reads, for these blocks."""
        hints = copy.deepcopy(self.hints)
        labels = {n: b.label for n, b in self.blocks.items() if b.label}
        if labels:
            hints["labels"] = labels
        groups = {g: m for g, m in hints.get("groups", {}).items() if m}
        if groups or "groups" in hints:
            hints["groups"] = groups
        return hints

    # ------------------------------------------------------------------ code

    def code(self, variable=None):
        """The Python that builds this diagram with ``control.interconnect``.

        Blocks from the palette are written as the calls that build them, blocks of the
        notebook by their variable, and blocks taken from the opened interconnect as
        ``<source>_blocks["name"]`` (``<source>`` is :attr:`source_name`, else
        ``source``); executing the code where those names exist gives an interconnect
        equal to :meth:`system`.
        """
        variable = variable or _identifier(self.name)
        source = self.source_name or "source"
        needs, lines, names = {"ct"}, [], {}
        for name, block in self.blocks.items():
            names[name] = var = _identifier(name, taken=set(names.values()) | {variable})
            recipe = block.recipe
            if recipe and recipe["kind"] in _palette.PALETTE:
                entry = _palette.PALETTE[recipe["kind"]]
                needs |= entry.imports(self.period())
                lines.append(f"{var} = {entry.source(name, recipe['kwargs'], self.period())}")
            elif recipe and recipe["kind"] == "variable":
                expression = recipe["variable"]
                lines.append(f"{var} = {expression}" if var != expression else None)
                if block.system.name != _variable_name(recipe):
                    lines[-1] = f"{var} = {expression}.copy(name={name!r})"
            else:
                lines.append(f"{var} = {source}_blocks[{name!r}]")
        lines = [line for line in lines if line]
        aliases = list(_palette.IMPORTS)
        head = [_palette.IMPORTS[alias] for alias in sorted(needs, key=aliases.index)]
        if any(b.recipe is None for b in self.blocks.values()):
            head.append(f"{source}_blocks = {{s.name: s for s in {source}.syslist}}  "
                        f"# the blocks of the diagram you opened")
        connections, inplist, inputs, outlist, outputs = self._specs()
        body = [f"{variable} = ct.interconnect(",
                f"    [{', '.join(names.values())}],"]
        body.append("    connections=[" if connections else "    connections=False,")
        for c in connections:
            body.append(f"        {_list(c)},")
        if connections:
            body.append("    ],")
        for key, items in (("inplist", inplist), ("inputs", inputs), ("outlist", outlist),
                           ("outputs", outputs)):
            body += _argument(key, items)
        body.append(f"    name={self.name!r},")
        body.append(")")
        hints = self.drawing_hints()
        tail = [f"{variable}.drawing_hints = {_hints_literal(hints)}"] if hints else []
        return "\n".join(head + [""] + lines + [""] + body + tail) + "\n"

    # ------------------------------------------------------------------ saving

    def to_dict(self):
        """The diagram as JSON-ready data (blocks by recipe; opened blocks by name)."""
        blocks = []
        for name, b in self.blocks.items():
            s = b.system
            blocks.append({"name": name, "recipe": b.recipe, "label": b.label,
                           "position": list(b.position) if b.position else None,
                           "look": b.look,
                           "inputs": list(s.input_labels), "outputs": list(s.output_labels),
                           "dt": _dt_json(s.dt)})
        return {
            "format": FORMAT, "name": self.name, "source_name": self.source_name,
            "blocks": blocks,
            "wires": [[*w.src, *w.dst, w.gain] for w in self.wires],
            "inputs": [[n, [list(t) for t in targets]] for n, targets in self.inputs],
            "outputs": [[n, [list(s) for s in sources]] for n, sources in self.outputs],
            "summed": sorted(list(d) for d in self.summed),
            "hints": self.hints,
        }

    def to_json(self, path=None):
        """JSON text of :meth:`to_dict`; also written to ``path`` when given."""
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        return text

    @classmethod
    def from_dict(cls, data, *, systems=None, namespace=None):
        """A model saved by :meth:`to_dict`.

        Parameters
        ----------
        data : dict
        systems : control.InterconnectedSystem or dict, optional
            Where blocks saved without a recipe (taken from an opened diagram) are
            found: that diagram (its ``syslist``) or ``{name: system}``.
        namespace : dict, optional
            The notebook's variables, for blocks added by variable name.
        """
        if not isinstance(data, dict) or data.get("format") != FORMAT:
            raise ValueError(f"not a saved diagram: the data must have format {FORMAT!r}")
        if isinstance(systems, ct.InterconnectedSystem):
            systems = {s.name: s for s in systems.syslist}
        systems, namespace = dict(systems or {}), dict(namespace or {})
        model = cls(name=data["name"], hints=data.get("hints") or {},
                    source_name=data.get("source_name"))
        for saved in data["blocks"]:
            name, recipe = saved["name"], saved["recipe"]
            period = _dt_value(saved["dt"])
            if recipe and recipe["kind"] in _palette.PALETTE:
                system = _palette.build(recipe["kind"], name, recipe["kwargs"],
                                        period if _timebase(period) == "discrete" else None)
            elif recipe and recipe["kind"] == "variable":
                if recipe["variable"] not in namespace:
                    raise ValueError(f"block {name!r} was the notebook's variable "
                                     f"{recipe['variable']!r}, which is not in namespace")
                system = namespace[recipe["variable"]]
                if not _palette.is_system(system):
                    raise ValueError(f"variable {recipe['variable']!r} holds a "
                                     f"{type(system).__name__}, not a python-control system")
                if system.name != name:
                    system = system.copy(name=name)
            else:
                if name not in systems:
                    raise ValueError(f"block {name!r} was taken from an opened diagram; pass "
                                     f"that diagram (or {{name: system}}) as systems=")
                system = systems[name]
            if (list(system.input_labels), list(system.output_labels)) != (
                    saved["inputs"], saved["outputs"]):
                raise ValueError(f"block {name!r} has inputs {system.input_labels} and outputs "
                                 f"{system.output_labels}, the saved diagram expects "
                                 f"{saved['inputs']} and {saved['outputs']}")
            model.blocks[name] = Block(system, recipe, saved["label"],
                                       tuple(saved["position"]) if saved["position"] else None,
                                       saved.get("look"))
        model.wires = [Wire((a, b), (c, d), g) for a, b, c, d, g in data["wires"]]
        model.inputs = [(n, [tuple(t) for t in targets]) for n, targets in data["inputs"]]
        model.outputs = [(n, [tuple(s) for s in sources]) for n, sources in data["outputs"]]
        model.summed = {tuple(d) for d in data["summed"]}
        return model

    # ------------------------------------------------------------------ checks

    def problems(self):
        """The wiring mistakes of the diagram, each naming its blocks.

        - ``unconnected input`` (warning): an input nothing drives; python-control
          reads it as 0.
        - ``two drivers`` (error): an input fed by two signals not written as a sum in
          code; python-control would silently add them.
        - ``algebraic loop`` (error): a loop of blocks that each pass their input
          straight to their output, which no step order can compute.
        - ``mismatched timebases`` (error): continuous and discrete blocks, or two
          sampling periods, in one diagram.
        - ``unused output`` (note): an output that goes nowhere.

        Returns
        -------
        list of Problem
        """
        found = []
        drivers = {}
        for w in self.wires:
            drivers.setdefault(w.dst, []).append(f"{w.src[0]}.{w.src[1]}")
        for name, targets in self.inputs:
            for block, signal, _ in targets:
                drivers.setdefault((block, signal), []).append(f"external input {name}")
        used = {w.src for w in self.wires} | {(b, s) for _, src in self.outputs
                                              for side, b, s, _ in src if side == "out"}
        for name, block in self.blocks.items():
            s = block.system
            loose = [label for label in s.input_labels if (name, label) not in drivers]
            if loose:
                found.append(Problem(
                    "unconnected input", "warning", [name],
                    f"unconnected input: {_signals(name, loose)} of block {name!r} has no "
                    f"driver (python-control reads it as 0)"))
            for label in s.input_labels:
                feeds = drivers.get((name, label), [])
                if len(feeds) > 1 and (name, label) not in self.summed:
                    blocks = [name] + [f.split(".")[0] for f in feeds
                                       if not f.startswith("external")]
                    found.append(Problem(
                        "two drivers", "error", list(dict.fromkeys(blocks)),
                        f"two drivers on one signal: {name}.{label} is driven by "
                        f"{' and '.join(feeds)}; remove one wire, or add them in a summing "
                        f"junction"))
            unused = [label for label in s.output_labels if (name, label) not in used]
            if unused:
                found.append(Problem(
                    "unused output", "note", [name],
                    f"unused output: {_signals(name, unused)} of block {name!r} goes nowhere"))
        found += self._algebraic_loops()
        found += self._timebases()
        return found

    def _algebraic_loops(self):
        direct = {n for n, b in self.blocks.items() if passes_input(b.system)}
        succ = {n: set() for n in direct}
        for w in self.wires:
            if w.src[0] in direct and w.dst[0] in direct:
                succ[w.src[0]].add(w.dst[0])
        found = []
        for component in _strong_components(succ):
            if len(component) == 1 and component[0] not in succ[component[0]]:
                continue
            cycle = _cycle(component, succ)
            order = " -> ".join(repr(n) for n in cycle + cycle[:1])
            found.append(Problem(
                "algebraic loop", "error", cycle,
                f"algebraic loop through blocks {order}: each passes its input straight to "
                f"its output, so no order of computing them exists; put a block with a "
                f"state (a delay, a plant, a filter) in the loop"))
        return found

    def _timebases(self):
        kinds = {}
        for name, b in self.blocks.items():
            kind = _timebase(b.system.dt)
            if kind == "continuous":
                kinds.setdefault("continuous (dt = 0)", []).append(name)
            elif kind == "discrete":
                kinds.setdefault(f"dt = {b.system.dt:g} s", []).append(name)
        if len(kinds) < 2:
            return []
        parts = [f"{', '.join(repr(n) for n in names)} "
                 f"{'runs' if len(names) == 1 else 'run'} {'at ' if k.startswith('dt') else ''}"
                 f"{k.replace(' (dt = 0)', '')}" for k, names in kinds.items()]
        advice = ("sample the continuous blocks (controlkit.blocks.sampling.sample_nlsys, "
                  "control.sample_system)" if "continuous (dt = 0)" in kinds
                  else "build all discrete blocks with one dt")
        blocks = [n for names in kinds.values() for n in names]
        return [Problem("mismatched timebases", "error", blocks,
                        f"mismatched timebases: {'; '.join(parts)}; {advice}")]


# ---------------------------------------------------------------------- helpers

def passes_input(system):
    """Whether a block's output can move with its input at the same instant (feedthrough).

    A controlkit block declares it (``kernels.feedthrough``); a block sampled by
    :func:`~controlkit.blocks.sampling.sample_nlsys` has that of its continuous block; an LTI
    block has it where ``D`` is not zero; for any other block the output function is
    tried at a few points (a block whose output fails there counts as feedthrough).

    Examples
    --------
    >>> import control as ct
    >>> passes_input(ct.tf([1], [1, 1])), passes_input(ct.tf([1, 0], [1, 1]))
    (False, True)
    """
    kernels = getattr(system, "kernels", None)
    if kernels is not None and hasattr(kernels, "feedthrough"):
        return bool(kernels.feedthrough)
    if isinstance(system, SampledSystem):
        return passes_input(system.continuous)
    if not system.ninputs or not system.noutputs:
        return False
    if isinstance(system, ct.TransferFunction):
        try:
            system = ct.tf2ss(system)
        except Exception:  # noqa: BLE001 - an improper tf passes its input on
            return True
    if isinstance(system, ct.StateSpace):
        return bool(np.any(np.asarray(system.D) != 0))
    rng = np.random.default_rng(0)
    for _ in range(3):
        x = rng.uniform(-0.5, 0.5, system.nstates)
        u = rng.uniform(-0.5, 0.5, system.ninputs)
        try:
            with warnings.catch_warnings(), np.errstate(all="ignore"):
                warnings.simplefilter("ignore")
                a = np.asarray(system.output(0.0, x, np.zeros(system.ninputs)), dtype=float)
                b = np.asarray(system.output(0.0, x, u), dtype=float)
        except Exception:  # noqa: BLE001 - not defined there: assume the worst
            return True
        if not np.array_equal(a, b, equal_nan=True):
            return True
    return False


def _timebase(dt):
    if dt is None or dt is True:
        return "any"
    return "continuous" if dt == 0 else "discrete"


def _dt_json(dt):
    return dt if dt is None or dt is True else float(dt)


def _dt_value(dt):
    return dt


def _signals(block, labels):
    from ._ports import port_groups as groups

    return ", ".join(f"{block}.{p}" for p, _ in groups(labels))


def _spec(block, signal, gain=1.0):
    """python-control's spec of a signal: ``"sys.sig"``, ``"-sys.sig"`` or a tuple."""
    if "." in block or block.startswith("-"):
        return (block, signal, gain)
    if gain == 1:
        return f"{block}.{signal}"
    if gain == -1:
        return f"-{block}.{signal}"
    return (block, signal, gain)


def _list(items):
    return "[" + ", ".join(_list(i) if isinstance(i, list) else repr(i) for i in items) + "]"


def _argument(key, items, width=95):
    """``    key=[...],`` on one line, or one item a line when that is too long."""
    line = f"    {key}={_list(items)},"
    if len(line) <= width:
        return [line]
    return [f"    {key}=["] + [f"        {_list(i) if isinstance(i, list) else repr(i)},"
                              for i in items] + ["    ],"]


def _hints_literal(hints):
    return repr(json.loads(json.dumps(hints)))


def _identifier(name, taken=()):
    """A Python variable name for a block name (``plant$sampled`` -> ``plant_sampled``)."""
    var = re.sub(r"\W", "_", name) or "block"
    if var[0].isdigit() or keyword.iskeyword(var) or var in _palette.IMPORTS:
        var = f"{var}_block"
    base, k = var, 2
    while var in taken:
        var, k = f"{base}_{k}", k + 1
    return var


def _variable_name(recipe):
    return recipe.get("system_name", recipe["variable"])


def _strong_components(succ):
    """Tarjan's strongly connected components of a graph ``{node: successors}``."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(succ[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            out.append(component)

    for v in sorted(succ):
        if v not in index:
            visit(v)
    return out


def _cycle(component, succ):
    """One cycle through the first node of a strongly connected component, in order."""
    members = set(component)
    start = min(component)
    path, seen = [start], {start}

    def walk(v):
        for w in sorted(succ[v] & members):
            if w == start:
                return True
            if w not in seen:
                seen.add(w)
                path.append(w)
                if walk(w):
                    return True
                path.pop()
        return False

    walk(start)
    return path
