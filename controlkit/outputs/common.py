"""Helpers every study's outputs share: reading a signal by name, choosing figures."""

from __future__ import annotations

import numpy as np


def signal(resp, label: str) -> np.ndarray:
    """One output of a response, by label (``resp.outputs[label]`` as an array).

    Works on :class:`control.TimeResponseData` and on anything with ``outputs`` and
    ``output_labels`` (such as a chunk of a streamed run).

    Examples
    --------
    >>> from controlkit.studies.spacecraft import scenario as spacecraft
    >>> resp = spacecraft.run("ideal", horizon=0.2)
    >>> signal(resp, "q[0]").round(4).tolist()
    [0.9659, 0.9659, 0.9659]
    """
    try:
        index = list(resp.output_labels).index(label)
    except ValueError:
        raise ValueError(
            f"the response has no output {label!r}; outputs: {list(resp.output_labels)}"
        ) from None
    return np.atleast_2d(resp.outputs)[index]


def select_stems(specs, stems) -> list[str]:
    """The file stems of ``specs`` to draw: all (``stems=None``) or the requested ones.

    Examples
    --------
    >>> select_stems([("a", 1), ("b", 2)], ["b"])
    ['b']
    """
    known = [spec[0] for spec in specs]
    if stems is None:
        return known
    unknown = [stem for stem in stems if stem not in known]
    if unknown:
        raise ValueError(f"stems must be among {known}, got {unknown}")
    return [stem for stem in known if stem in stems]


def figure_spec(specs, stem: str) -> tuple:
    """The row of a study's ``FIGURES`` table (rows starting with their stem) for ``stem``.

    Examples
    --------
    >>> figure_spec([("fig1", "Title"), ("fig2", "Other")], "fig2")
    ('fig2', 'Other')
    """
    for spec in specs:
        if spec[0] == stem:
            return spec
    raise ValueError(f"stem must be one of {[spec[0] for spec in specs]}, got {stem!r}")
