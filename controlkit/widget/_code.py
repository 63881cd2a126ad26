"""The editor's diagram written back as Python (:func:`write_code`): a module that builds it
with ``control.interconnect`` (the arguments of :mod:`._specs`) and runs it as the page does.
"""

from __future__ import annotations

import ast
import json
import pprint
import re
import textwrap

import control as ct

from . import _palette
from ._calls import IMPORTS, aliases, check_identifier, is_identifier
from ._calls import source as python_source
from ._run import run_arguments, time_expression
from ._sources import describe, expression
from ._specs import interconnect_specs


def code_parameters(model):
    """``{parameter: block}``: the blocks the written code takes as arguments.

    A block the editor cannot write as a constructor call (a user's own ``nlsys``, a
    tuned controlkit block) is a parameter named by its variable; a notebook variable's
    block is a parameter named by that variable.
    """
    return _plan(model)[2]


def _plan(model, variable=None):
    """Variables of the written code: ``(diagram, {block: var}, {parameter: block})``."""
    written = {"T", "U", "X0", "response"}  # (the written code's own variables)
    if variable in written:
        raise ValueError(f"the variable {variable!r} is a name the written code uses itself "
                         f"(one of {sorted(written)}); choose another")
    variable = check_identifier(variable or _identifier(model.name, taken=written),
                                "the variable")
    taken = {variable, f"build_{variable}", f"simulate_{variable}"} | written
    names, parameters = {}, {}
    for name, block in model.blocks.items():
        recipe = block.recipe
        if recipe and recipe["kind"] == "variable":
            given = check_identifier(recipe["variable"], "a notebook variable's name")
            if given not in parameters:
                if given in taken | set(IMPORTS):
                    raise ValueError(f"the notebook variable {given!r} clashes with a name "
                                     f"of the written code; rename it")
                parameters[given] = name
                taken.add(given)
    for name, block in model.blocks.items():
        var = _identifier(name, taken=taken | set(names.values()))
        names[name] = var
        if block.recipe is None:
            parameters[var] = name
    return variable, names, parameters


def write_code(model, variable=None):
    """The Python that builds ``model`` and runs it as the page does.

    See :meth:`~controlkit.widget.DiagramModel.code`.
    """
    variable, names, parameters = _plan(model, variable)
    needs, lines = {"np", "controlkit"}, []
    for name, block in model.blocks.items():
        var, recipe = names[name], block.recipe
        if recipe and recipe["kind"] in _palette.PALETTE:
            tree = _palette.PALETTE[recipe["kind"]].tree(name, recipe["kwargs"],
                                                         recipe.get("sampled"))
            needs |= aliases(tree)
            lines.append(f"{var} = {python_source(tree)}")
        elif recipe and recipe["kind"] == "variable":
            given = recipe["variable"]
            if block.system.name != _variable_name(recipe):
                lines.append(f"{var} = {given}.copy(name={name!r})")
            elif var != given:
                lines.append(f"{var} = {given}")
    mixed = model.is_mixed()
    call = "controlkit.interconnect" if mixed else "ct.interconnect"
    needs.add("ct")
    connections, inplist, inputs, outlist, outputs = interconnect_specs(model)
    body = [f"{variable} = {call}(", f"    [{', '.join(names.values())}],"]
    body.append("    connections=[" if connections else "    connections=False,")
    body += [f"        {_list(c)}," for c in connections]
    if connections:
        body.append("    ],")
    for key, items in (("inplist", inplist), ("inputs", inputs), ("outlist", outlist),
                       ("outputs", outputs)):
        body += _argument(key, items)
    body += [f"    name={model.name!r},", ")"]
    hints = model.drawing_hints()
    if hints:
        body += _assignment(f"{variable}.drawing_hints", _plain_hints(hints))
    body.append(f"return {variable}")

    order = list(IMPORTS)
    head = _docstring(f"{model.name!r} as the controlkit diagram editor wrote it: the blocks, "
                      f"the interconnect and the run set in the editor's page.", "")
    imports = [IMPORTS[alias] for alias in sorted(needs, key=order.index)]
    third_party = [line for line in imports if "controlkit" not in line]
    head += [""] + third_party + [""] + [line for line in imports if "controlkit" in line]
    doc = f"The interconnect {model.name!r}."
    if parameters:
        doc += "\n\nParameters\n----------"
        for parameter, name in parameters.items():
            doc += (f"\n{parameter} : control.InputOutputSystem\n"
                    f"    {_parameter_note(model, name)}")
    build = [f"def build_{variable}({', '.join(parameters)}):"] + _docstring(doc, "    ")
    build += ["    " + line if line else "" for line in lines + [""] + body]

    arguments = run_arguments(model, _system_for_arguments(model))
    simulate = [f"def simulate_{variable}({variable}):",
                '    """Simulate it as the editor\'s Run button does (python-control\'s '
                'arguments)."""',
                f"    T = {time_expression(model.horizon, arguments['dt'])}"]
    if arguments["sources"]:
        simulate.append("    U = np.array([")
        for label, src in arguments["sources"]:
            simulate.append(f"        {ast.unparse(expression(src))},  # {label!r}: "
                            f"{describe(src)}")
        simulate.append("    ])")
    else:
        simulate.append("    U = 0.0  # the diagram has no external inputs")
    simulate += _initial_state(model, variable)
    simulate.append(f"    return controlkit.input_output_response({variable}, T, U, X0)")

    tail = []
    if parameters:
        source = model.source_name
        tail += ["# The blocks the editor cannot write come from your notebook; for example:"]
        if any(b.recipe is None for b in model.blocks.values()):
            tail.append(f"#   blocks = {{s.name: s for s in {source or 'opened'}.syslist}}"
                        f"  # the diagram you opened")
        passed = ", ".join(f"{p}={p}" if model.blocks[n].recipe else f"{p}=blocks[{n!r}]"
                           for p, n in parameters.items())
        tail += [f"#   {variable} = build_{variable}({passed})",
                 f"#   response = simulate_{variable}({variable})"]
    else:
        tail += [f"{variable} = build_{variable}()",
                 f"response = simulate_{variable}({variable})"]
    return "\n".join(head + ["", ""] + build + ["", ""] + simulate + ["", ""] + tail) + "\n"


def _system_for_arguments(model):
    try:
        return model.system()
    except ValueError:  # a diagram with wiring errors is still written out
        return None


def _parameter_note(model, name):
    block = model.blocks[name]
    recipe, s = block.recipe, block.system
    if recipe and recipe["kind"] == "variable":
        copy = "" if s.name == _variable_name(recipe) else f", copied as block {name!r}"
        return f"The notebook's variable (block {_variable_name(recipe)!r}){copy}."
    what = ("an nlsys of your own, whose functions" if type(s) is ct.NonlinearIOSystem
            else "a block whose construction")
    return (f"Block {name!r} ({_count(s.ninputs, 'input')}, {_count(s.noutputs, 'output')}, "
            f"{_count(s.nstates, 'state')}): {what} the editor cannot write as a constructor "
            f"call; pass the block itself.")


def _count(n, noun):
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _docstring(text, indent):
    """A docstring's lines (written by ast.unparse, so any text stays a string)."""
    paragraphs = text.split("\n")
    text = "\n".join(textwrap.fill(p, 88 - len(indent), subsequent_indent=" " * (
        len(p) - len(p.lstrip()))) if p.strip() else "" for p in paragraphs)
    if "\n" in text:
        text += "\n"  # the closing quotes on a line of their own
    module = ast.Module([ast.Expr(ast.Constant(text)), ast.Pass()], [])
    literal = ast.unparse(module).rsplit("\n", 1)[0]
    return [indent + line if line else "" for line in literal.splitlines()]


def _initial_state(model, variable):
    """``X0 = controlkit.initial_state(...)`` with the states set in the page."""
    given = {k: [float(v) for v in values] for k, values in model.initial.items()}
    if not given:
        return [f"    X0 = controlkit.initial_state({variable})  # each block's own"]
    named = [f"{k}={v!r}" for k, v in given.items() if is_identifier(k) and k != "sys"]
    others = {k: v for k, v in given.items() if not is_identifier(k) or k == "sys"}
    if others:  # names that are no keyword argument: a dict, unpacked
        named.append(f"**{others!r}")
    line = f"    X0 = controlkit.initial_state({variable}, {', '.join(named)})"
    if len(line) <= 95:
        return [line]
    return (["    X0 = controlkit.initial_state(", f"        {variable},"]
            + [f"        {item}," for item in named] + ["    )"])


def _plain_hints(hints):
    return json.loads(json.dumps(hints))


def _assignment(target, value, width=95):
    """``target = value`` (a repr), broken over lines by pprint when it is long."""
    text = pprint.pformat(value, width=width - len(target) - 3, sort_dicts=False)
    first, *rest = text.splitlines()
    pad = " " * (len(target) + 3)
    return [f"{target} = {first}"] + [pad + line for line in rest]


def _list(items):
    return "[" + ", ".join(_list(i) if isinstance(i, list) else repr(i) for i in items) + "]"


def _argument(key, items, width=95):
    """``    key=[...],`` on one line, or one item a line when that is too long."""
    line = f"    {key}={_list(items)},"
    if len(line) <= width:
        return [line]
    return [f"    {key}=["] + [f"        {_list(i) if isinstance(i, list) else repr(i)},"
                              for i in items] + ["    ],"]


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
