"""The run a page sets up: the horizon, the external inputs and what drives each of them
(sources), initial states.

:class:`RunSetup` holds the methods; :class:`~controlkit.widget.DiagramModel` holds the
data (``horizon``, ``sources``, ``initial``) and saves it with the diagram. Together they
are python-control's ``input_output_response`` arguments
(:func:`~controlkit.widget._run.run_arguments`).
"""

from __future__ import annotations

import numpy as np

from . import _sources
from ._ports import port_groups
from ._rules import NAME


class RunSetup:
    """The run's setup of a :class:`~controlkit.widget.DiagramModel` (a mixin)."""

    def run_period(self):
        """The period of a run's time grid: a discrete diagram's, else 0 (continuous time)."""
        return self.period() or 0

    def source_of(self, name):
        """The source driving external input ``name`` (a constant 0 unless one was set)."""
        return self.sources.get(name) or _sources.source("constant", value=0.0)

    def set_source(self, name, kind="constant", **fields):
        """Drive external input ``name`` by a source (see :mod:`~controlkit.widget._sources`):
        ``constant`` (``value``), ``step`` (``value``, ``time``, ``initial``), ``ramp``
        (``slope``, ``time``, ``initial``), ``sine`` (``amplitude``, ``frequency`` in Hz,
        ``phase``, ``offset``) or ``pulse`` (``value``, ``time``, ``width``, ``period``,
        ``initial``)."""
        if name not in [n for n, _ in self.inputs]:
            raise ValueError(f"the diagram has no external input {name!r}; its inputs: "
                             f"{[n for n, _ in self.inputs]}")
        self.sources[name] = _sources.SOURCE.check({"kind": kind, **fields},
                                                   f"source of {name!r}")

    def set_initial(self, name, values):
        """The initial state of block ``name`` (``None``: its own ``x0``, else zero)."""
        system = self._block(name).system
        if values is None:
            self.initial.pop(name, None)
            return
        values = np.asarray(values, dtype=float).reshape(-1)
        if values.size != system.nstates:
            raise ValueError(f"initial state of block {name!r} must have {system.nstates} "
                             f"values ({', '.join(system.state_labels) or 'no states'}), "
                             f"got {values.size}")
        if not np.all(np.isfinite(values)):
            raise ValueError(f"initial state of block {name!r} must be finite, got "
                             f"{values.tolist()}")
        self.initial[name] = values.tolist()

    def set_horizon(self, horizon):
        """The simulated time of a run, in seconds (> 0, at most 2 000 000 samples)."""
        from ._run import time_points

        time_points(horizon, self.run_period())  # checks it
        self.horizon = float(horizon)

    # ------------------------------------------------------------------ external inputs

    def input_groups(self):
        """The external inputs grouped as ports: ``[(label, [names])]`` (``r[0], r[1]`` is
        ``r``), attached to blocks or not."""
        return port_groups([name for name, _ in self.inputs])

    def input_names(self, label):
        """The external inputs of a group label (or a single input's name)."""
        for group, names in self.input_groups():
            if group == label:
                return names
        if label in dict(self.inputs):
            return [label]
        raise ValueError(f"the diagram has no external input {label!r}; its inputs: "
                         f"{[g for g, _ in self.input_groups()]}")

    def add_input(self, name, block=None, port=None):
        """A new external input ``name``, driven by a constant 0 until a source is set.

        With ``block`` and ``port`` it is wired to that input port at once, one signal
        per element (``name[0]``, ``name[1]``... for a vector port). Without, it waits,
        unattached, to be connected (:meth:`connect_input`).

        Returns
        -------
        list of str
            The new inputs' names.
        """
        NAME.check(name, "the input's name")
        width = 1 if block is None else len(self.port_signals(block, "in", port))
        names = [name] if width == 1 else [f"{name}[{i}]" for i in range(width)]
        taken = [n for n in names if n in dict(self.inputs)]
        if taken:
            raise ValueError(f"the diagram already has an external input {taken[0]!r}")
        self.inputs += [(n, []) for n in names]
        if block is not None:
            self.connect_input(name, block, port)
        return names

    def connect_input(self, label, block, port, gain=1.0):
        """Wire external input ``label`` (a name, or a group such as ``r``) to an input
        port of ``block``, element by element."""
        names = self.input_names(label)
        signals = self.port_signals(block, "in", port)
        if len(names) != len(signals):
            raise ValueError(f"cannot connect the external input {label} ({len(names)} "
                             f"signal{'s' if len(names) != 1 else ''}) to {block}.{port} "
                             f"({len(signals)} signal{'s' if len(signals) != 1 else ''}): "
                             f"the widths must be equal")
        targets = dict(self.inputs)
        for name, signal in zip(names, signals, strict=True):
            if not any(t[:2] == (block, signal) for t in targets[name]):
                targets[name] = [*targets[name], (block, signal, float(gain))]
        self.inputs = [(n, targets[n]) for n, _ in self.inputs]
        self._rewired()

    def disconnect_input(self, label, block, port):
        """Unwire external input ``label`` from a port; the input stays, unattached."""
        names = set(self.input_names(label))
        signals = set(self.port_signals(block, "in", port))
        before = sum(len(t) for _, t in self.inputs)
        self.inputs = [(n, [t for t in targets if n not in names or t[0] != block
                            or t[1] not in signals]) for n, targets in self.inputs]
        if sum(len(t) for _, t in self.inputs) == before:
            raise ValueError(f"the external input {label} does not drive {block}.{port}")
        self._rewired()

    def remove_input(self, label):
        """Remove an external input (or group) with its source."""
        names = set(self.input_names(label))
        self.inputs = [(n, t) for n, t in self.inputs if n not in names]
        self.sources = {n: s for n, s in self.sources.items() if n not in names}
        self._rewired()
