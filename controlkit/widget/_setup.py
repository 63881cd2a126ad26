"""The run a page sets up: the horizon, what drives each external input, initial states.

:class:`RunSetup` holds the methods; :class:`~controlkit.widget.DiagramModel` holds the
data (``horizon``, ``sources``, ``initial``) and saves it with the diagram. Together they
are python-control's ``input_output_response`` arguments
(:func:`~controlkit.widget._run.run_arguments`).
"""

from __future__ import annotations

import numpy as np

from . import _sources


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
