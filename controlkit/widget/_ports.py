"""Signals grouped into ports: ``q[0]..q[3]`` is one port ``q`` four signals wide."""

from __future__ import annotations

import re

_INDEXED = re.compile(r"(.*)\[(\d+)\]")


def split_index(label):
    """``("q", 2)`` for ``"q[2]"``, ``("T1", None)`` for ``"T1"``.

    Examples
    --------
    >>> split_index("q[2]"), split_index("T1")
    (('q', 2), ('T1', None))
    """
    m = _INDEXED.fullmatch(label)
    return (m.group(1), int(m.group(2))) if m else (label, None)


def port_groups(labels):
    """The ports of one side of a block: runs of consecutive elements of one vector.

    Parameters
    ----------
    labels : list of str
        The block's input (or output) labels, in order.

    Returns
    -------
    list of (str, list of str)
        ``(port name, its signals)``; the port is named by the vector's base name
        (``q`` for ``q[0]..q[3]``), or by its range (``q[0..1]``) where one base name
        makes more than one port.

    Examples
    --------
    >>> port_groups(["r[0]", "r[1]", "h[0]", "h[1]", "T1"])
    [('r', ['r[0]', 'r[1]']), ('h', ['h[0]', 'h[1]']), ('T1', ['T1'])]
    >>> port_groups(["u[0]", "u[2]"])
    [('u[0]', ['u[0]']), ('u[2]', ['u[2]'])]
    """
    runs = []
    for label in labels:
        base, index = split_index(label)
        if runs and index is not None and runs[-1][0] == base and runs[-1][2] == index - 1:
            runs[-1][1].append(label)
            runs[-1][2] = index
        else:
            runs.append([base, [label], index])
    bases = [base for base, _, _ in runs]
    ports = []
    for base, members, _ in runs:
        if bases.count(base) == 1:
            ports.append((base, members))
        elif len(members) == 1:
            ports.append((members[0], members))
        else:
            first, last = split_index(members[0])[1], split_index(members[-1])[1]
            ports.append((f"{base}[{first}..{last}]", members))
    return ports


def compress_range(labels):
    """python-control's range form of consecutive elements: ``q[0:4]`` for ``q[0]..q[3]``.

    Returns None when ``labels`` are not consecutive elements of one vector.

    Examples
    --------
    >>> compress_range(["q[1]", "q[2]"]), compress_range(["q[0]", "h[1]"])
    ('q[1:3]', None)
    """
    parts = [split_index(label) for label in labels]
    base, first = parts[0]
    if first is None or any(b != base or i != first + k for k, (b, i) in enumerate(parts)):
        return None
    return f"{base}[{first}:{first + len(labels)}]"


def runs(items, key):
    """Split ``items`` into maximal runs over which ``key(item)`` continues the previous one.

    ``key(previous, item)`` says whether ``item`` extends the run ending with ``previous``.

    Examples
    --------
    >>> runs([1, 2, 3, 5, 6], lambda a, b: b == a + 1)
    [[1, 2, 3], [5, 6]]
    """
    out = []
    for item in items:
        if out and key(out[-1][-1], item):
            out[-1].append(item)
        else:
            out.append([item])
    return out


def next_element(a, b):
    """Whether signal ``b`` is the element after ``a`` of the same vector.

    Examples
    --------
    >>> next_element("q[0]", "q[1]"), next_element("q[0]", "h[1]")
    (True, False)
    """
    (base_a, i), (base_b, j) = split_index(a), split_index(b)
    return i is not None and j is not None and base_a == base_b and j == i + 1
