"""The editor's diagram written back as python-control: the arguments of
``control.interconnect`` (:func:`interconnect_specs`) and the Python that builds it
(:func:`write_code`).

Consecutive elements of one vector wired alike are written as one range
(``"plant.q[0:3]"``), as a person would write them.
"""

from __future__ import annotations

import json
import re

from . import _palette
from ._calls import IMPORTS, aliases, check_identifier, is_identifier
from ._calls import source as python_source
from ._ports import compress_range, next_element, runs


def interconnect_specs(model):
    """``connections``, ``inplist``, ``inputs``, ``outlist``, ``outputs`` for interconnect."""
    by_dst = {}
    for w in model.wires:
        by_dst.setdefault(w.dst, []).append(w)
    connections = []
    for name, block in model.blocks.items():
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

    for run in runs(model.inputs, input_continues):
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

    for run in runs(model.outputs, output_continues):
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


def write_code(model, variable=None):
    """The Python that builds ``model`` with ``control.interconnect``.

    See :meth:`~controlkit.widget.DiagramModel.code`.
    """
    variable = check_identifier(variable or _identifier(model.name), "the variable")
    source = check_identifier(model.source_name or "source", "source_name")
    needs, lines, names = {"ct"}, [], {}
    for name, block in model.blocks.items():
        names[name] = var = _identifier(name, taken=set(names.values()) | {variable})
        recipe = block.recipe
        if recipe and recipe["kind"] in _palette.PALETTE:
            tree = _palette.PALETTE[recipe["kind"]].tree(name, recipe["kwargs"],
                                                         recipe.get("sampled"))
            needs |= aliases(tree)
            lines.append(f"{var} = {python_source(tree)}")
        elif recipe and recipe["kind"] == "variable":
            expression = check_identifier(recipe["variable"], "a notebook variable's name")
            lines.append(f"{var} = {expression}" if var != expression else None)
            if block.system.name != _variable_name(recipe):
                lines[-1] = f"{var} = {expression}.copy(name={name!r})"
        else:
            lines.append(f"{var} = {source}_blocks[{name!r}]")
    lines = [line for line in lines if line]
    order = list(IMPORTS)
    head = [IMPORTS[alias] for alias in sorted(needs, key=order.index)]
    if any(b.recipe is None for b in model.blocks.values()):
        head.append(f"{source}_blocks = {{s.name: s for s in {source}.syslist}}  "
                    f"# the blocks of the diagram you opened")
    connections, inplist, inputs, outlist, outputs = interconnect_specs(model)
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
    body.append(f"    name={model.name!r},")
    body.append(")")
    hints = model.drawing_hints()
    tail = [f"{variable}.drawing_hints = {_hints_literal(hints)}"] if hints else []
    return "\n".join(head + [""] + lines + [""] + body + tail) + "\n"


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
    var = re.sub(r"[^A-Za-z0-9_]", "_", name) or "block"
    if not is_identifier(var) or var in IMPORTS:
        var = f"{var}_block"
    if not is_identifier(var):  # a digit first
        var = f"block_{var}"
    base, k = var, 2
    while var in taken:
        var, k = f"{base}_{k}", k + 1
    return var


def _variable_name(recipe):
    return recipe.get("system_name", recipe["variable"])
