"""The papers' studies, one folder each, and the registry that lists them.

A study's folder holds its ``scenario`` (published parameters and cases),
``diagrams`` (the papers' block diagrams), ``outputs`` (CSV columns, metrics,
figures) and, where it has one, ``robustness`` (a sweep over model errors); its
``__init__`` defines ``STUDY``, a :class:`~controlkit.studies.registry.Study`.
:mod:`.reproduce` runs studies for ``controlkit reproduce``, :mod:`.robustness` their
sweeps for ``controlkit sweep``.

To add a study: write its folder as the others are written and add its ``STUDY`` to
:data:`STUDIES` below (one line).
"""

from __future__ import annotations

from . import cmg, frit, spacecraft
from .registry import Study

#: Every study by name, in the order ``controlkit reproduce all`` lists them.
STUDIES: dict[str, Study] = {s.name: s for s in (spacecraft.STUDY, cmg.STUDY, frit.STUDY)}
