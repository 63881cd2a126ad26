"""The editor's diagram as plain data: blocks, wires between their signals, and checks.

A :class:`DiagramModel` is read from any ``control.InterconnectedSystem``
(python-control's connection maps), edited (connect, disconnect, add, delete,
move, change a parameter) and turned back into a ``control.interconnect``
call, as an object (:meth:`DiagramModel.system`) and as source code
(:meth:`DiagramModel.code`). Wires join one output signal to one input signal
with a gain (python-control's ``connect_map`` entry); the editor shows them
grouped into ports (:func:`~controlkit.widget._ports.port_groups`).

The pieces (:class:`Block`, :class:`Wire`, :class:`Problem`) live in
:mod:`._parts`, the checks in :mod:`._problems`, the code writer in :mod:`._code` and
saving in :mod:`._saving`; this module is the model and its edits.
"""

from __future__ import annotations

import copy
import json
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import _palette, _saving
from ._calls import check_identifier
from ._code import write_code
from ._parts import FORMAT, PROBLEM_KINDS, Block, Problem, Wire, timebase
from ._ports import port_groups
from ._problems import find_problems, passes_input
from ._setup import RunSetup
from ._specs import interconnect_specs

__all__ = ["FORMAT", "PROBLEM_KINDS", "Block", "DiagramModel", "Problem", "Wire",
           "passes_input"]


@dataclass
class DiagramModel(RunSetup):
    """A block diagram being edited; see the module docstring.

    Examples
    --------
    A PI controller acting on ``r - y`` (one state-space block) around a first-order plant:

    >>> import control as ct
    >>> plant = ct.ss(-1.0, 1.0, 1.0, 0.0, name="plant", inputs="u", outputs="y")
    >>> pi = ct.ss(0.0, [[1.0, -1.0]], 2.0, [[3.0, -3.0]], name="pi", inputs=["r", "y"],
    ...            outputs="u")
    >>> loop = ct.interconnect([pi, plant], inputs="r", outputs="y")
    >>> model = DiagramModel.from_interconnect(loop)
    >>> [f"{w.src[0]}.{w.src[1]} -> {w.dst[0]}.{w.dst[1]}" for w in model.wires]
    ['plant.y -> pi.y', 'pi.u -> plant.u']
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
    horizon: float = 10.0                        # the run: simulated time (s),
    sources: dict = field(default_factory=dict)  # what drives each external input,
    initial: dict = field(default_factory=dict)  # initial states by block

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
        return _saving.from_interconnect(cls, sys, source_name=source_name)

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
        """Remove a block with its wires, its outputs to the outside and its hints; the
        external inputs it had stay, unattached, with their sources."""
        self._block(name)
        del self.blocks[name]
        self.wires = [w for w in self.wires if name not in (w.src[0], w.dst[0])]
        # the external inputs stay (unattached, with their sources), to be wired again
        self.inputs = [(n, [t for t in targets if t[0] != name]) for n, targets in self.inputs]
        self.initial.pop(name, None)
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
        options = entry.check_kwargs({**_palette.defaults(key, self.period()), **kwargs})
        name = self.unique_name(entry.name)
        recipe = {"kind": key, "kwargs": options}
        if entry.follows_period and self.period():  # joins a discrete diagram under ZOH
            recipe["sampled"] = {"Ts": float(self.period())}
        system = _palette.build(key, name, options, recipe.get("sampled"))
        return self.add_block(system, recipe=recipe, position=position)

    def add_variable(self, variable, value, *, position=None):
        """Add a system of the notebook held in ``variable`` (a copy if its name is taken)."""
        check_identifier(variable, "a notebook variable's name")
        if not _palette.is_system(value):
            raise ValueError(f"variable {variable!r} holds a {type(value).__name__}, not a "
                             f"python-control I/O system")
        recipe = {"kind": "variable", "variable": variable, "system_name": value.name}
        if value.name in self.blocks:
            value = value.copy(name=self.unique_name(value.name))
        return self.add_block(value, recipe=recipe, position=position)

    def paste(self, names, offset=(40.0, 60.0)):
        """Copies of blocks ``names`` (new names), with the wires between them.

        A block with a recipe is built again under its new name; any other block is
        copied (``system.copy(name=...)``). Returns the new names, in order.
        """
        renamed = {}
        for name in names:
            block = self._block(name)
            new = self.unique_name(name)
            recipe = block.recipe
            if recipe and recipe["kind"] in _palette.PALETTE:
                system = _palette.build(recipe["kind"], new, recipe["kwargs"],
                                        recipe.get("sampled"))
            else:
                system = block.system.copy(name=new)
            position = None if block.position is None else (
                block.position[0] + offset[0], block.position[1] + offset[1])
            self.add_block(system, recipe=copy.deepcopy(recipe), label=block.label,
                           position=position)
            self.blocks[new].look = copy.deepcopy(block.look)
            renamed[name] = new
        self.wires += [Wire((renamed[w.src[0]], w.src[1]), (renamed[w.dst[0]], w.dst[1]), w.gain)
                       for w in list(self.wires)
                       if w.src[0] in renamed and w.dst[0] in renamed]
        for name, new in renamed.items():
            if name in self.initial:
                self.initial[new] = list(self.initial[name])
        return list(renamed.values())

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
        return {k: float(v) for k, v in params.items() if _palette.is_number(v)}

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
            system = _palette.build(recipe["kind"], name, kwargs, recipe.get("sampled"))
            block.recipe = {**recipe, "kwargs": kwargs}
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

    def timebases(self):
        """``{"continuous": [blocks], period: [blocks]}``: the blocks that run in time."""
        kinds = {}
        for name, b in self.blocks.items():
            kind = timebase(b.system.dt)
            if kind == "continuous":
                kinds.setdefault("continuous", []).append(name)
            elif kind == "discrete" and b.system.dt is not True:
                kinds.setdefault(float(b.system.dt), []).append(name)
        return kinds

    def is_mixed(self):
        """Continuous and discrete blocks, or several periods: a sampled-data diagram
        (:func:`controlkit.interconnect`)."""
        return len(self.timebases()) > 1

    def period(self):
        """The sampling period of a discrete diagram (new palette blocks join it sampled),
        else None (continuous, static or sampled-data)."""
        kinds = self.timebases()
        return next(iter(kinds)) if len(kinds) == 1 and "continuous" not in kinds else None

    def systems(self):
        return [b.system for b in self.blocks.values()]

    def system(self, *, outlist=None, outputs=None, name=None):
        """The diagram as :func:`controlkit.interconnect` builds it (``drawing_hints`` on).

        One timebase: python-control's ``control.interconnect`` result; continuous and
        discrete blocks together: a sampled-data diagram, which
        :func:`controlkit.input_output_response` simulates. ``outlist``, ``outputs`` and
        ``name`` replace the diagram's own (the editor records every block output).

        Raises
        ------
        ValueError
            Listing the errors of :meth:`problems` (two drivers, algebraic loop,
            mismatched timebases), which python-control would not catch or would
            report without naming the blocks.
        """
        from controlkit.sampled_data import interconnect

        errors = [p.message for p in self.problems() if p.severity == "error"]
        if errors:
            raise ValueError("the diagram cannot be built: " + "; ".join(errors))
        if not self.blocks:
            raise ValueError("the diagram has no blocks")
        connections, inplist, inputs, own_outlist, own_outputs = interconnect_specs(self)
        with warnings.catch_warnings():  # unused signals are reported by problems()
            warnings.filterwarnings("ignore", message=r"Unused (input|output)",
                                    category=UserWarning)
            sys = interconnect(self.systems(), connections=connections or False,
                               inplist=inplist, inputs=inputs,
                               outlist=own_outlist if outlist is None else outlist,
                               outputs=own_outputs if outputs is None else outputs,
                               name=name or self.name)
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
        """A module that builds this diagram and runs it as the page does, standing alone.

        It has its imports; a function ``build_<variable>`` that builds every block from
        its constructor (palette blocks and the blocks of an opened diagram that the
        editor rebuilds exactly: state-space blocks, summing junctions, controlkit's
        factories) and returns the interconnect; a function ``simulate_<variable>`` that
        calls :func:`controlkit.input_output_response` with the page's time points,
        inputs (sources) and initial state; and the two calls. A block the editor
        cannot write (a user's own ``nlsys``) or a notebook variable is a parameter of
        ``build_<variable>``, named and described in its docstring; the calls are then
        written as comments to fill in. Names reach the code as checked identifiers and
        values as ``repr``.

        Parameters
        ----------
        variable : str, optional
            Python name of the diagram (default: from its name).
        """
        return write_code(self, variable)

    # ------------------------------------------------------------------ saving

    def to_dict(self):
        """The diagram as JSON-ready data (blocks by recipe; opened blocks by name)."""
        return _saving.to_dict(self)

    def to_json(self, path=None):
        """JSON text of :meth:`to_dict`; also written to ``path`` when given."""
        text = json.dumps(self.to_dict(), indent=1)
        if path is not None:
            with open(path, "w", encoding="utf-8") as f:
                f.write(text)
        return text

    @classmethod
    def from_json(cls, text, *, systems=None, namespace=None):
        """A model from the JSON text :meth:`to_json` wrote (see :meth:`from_dict`)."""
        return cls.from_dict(_saving.parse(text), systems=systems, namespace=namespace)

    @classmethod
    def from_dict(cls, data, *, systems=None, namespace=None):
        """A model saved by :meth:`to_dict`, read by the schema (:mod:`._schema`).

        Every field is checked - names, identifiers, finite numbers, sizes - and palette
        recipes are rebuilt from the editor's fixed constructors; nothing in ``data`` is
        evaluated. A field that breaks the format raises a ValueError naming it by its
        JSON path and saying what is allowed there.

        Parameters
        ----------
        data : dict
        systems : control.InterconnectedSystem or dict, optional
            Where blocks saved without a recipe (taken from an opened diagram) are
            found: that diagram (its ``syslist``) or ``{name: system}``.
        namespace : dict, optional
            The notebook's variables, for blocks added by variable name.
        """
        return _saving.from_dict(cls, data, systems=systems, namespace=namespace)

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
        - ``unused input`` (note): an external input wired to no block (it is left out
          of the interconnect until it is).

        Returns
        -------
        list of Problem
        """
        return find_problems(self)
