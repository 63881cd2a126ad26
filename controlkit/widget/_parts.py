"""The pieces of the editor's diagram: blocks, wires, problems, and a block's timebase."""

from __future__ import annotations

from dataclasses import dataclass

import control as ct

from ._rules import FORMAT

__all__ = ["FORMAT", "PROBLEM_KINDS", "Block", "Problem", "Wire", "timebase"]


@dataclass
class Block:
    """One block of the diagram.

    Attributes
    ----------
    system : control.InputOutputSystem
        The block itself.
    recipe : dict or None
        How to build it again: ``{"kind": palette key, "kwargs": {...}}`` (with
        ``"sampled": {"Ts": period}`` for a block under zero-order hold),
        ``{"kind": "variable", "variable": name}`` (an object of the notebook), or None
        for a block the editor cannot rebuild (taken as it is from an opened interconnect).
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
                 "unused output": "note", "unused input": "note"}



def timebase(dt):
    """``"continuous"``, ``"discrete"`` or ``"any"`` (``dt`` None or True) for a block's dt.

    Examples
    --------
    >>> timebase(0), timebase(0.1), timebase(None)
    ('continuous', 'discrete', 'any')
    """
    if dt is None or dt is True:
        return "any"
    return "continuous" if dt == 0 else "discrete"
