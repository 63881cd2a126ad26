"""Saved diagrams are data: a hostile file is refused, naming the field, or yields harmless code.

A course shares diagram files. Each file below is what an adversary would write (issue 33);
opening it (``DiagramModel.from_dict``), exporting its code (``.code()``) and running that
code must never run anything the file says: the marker file that the payload would
create must not exist afterwards, and the error names the field by its JSON path.
"""

from __future__ import annotations

import json

import control as ct
import numpy as np
import pytest

from controlkit.widget import DiagramModel

OUTER_INPUTS = ["r[0]", "r[1]", "h[0]", "h[1]"]


def saved(blocks, version="controlkit.widget/1", **extra):
    """A saved diagram as format 1 wrote it (the old reader reads it too)."""
    return {"format": version, "name": "shared", "source_name": None, "blocks": blocks,
            "wires": [], "inputs": [], "outputs": [], "summed": [], "hints": {}, **extra}


def block(name, kind, kwargs, inputs, outputs, dt=None, **extra):
    recipe = {"kind": kind, "kwargs": kwargs, **extra}
    return {"name": name, "recipe": recipe, "label": None, "position": None, "look": None,
            "inputs": inputs, "outputs": outputs, "dt": dt}


def payload(marker):
    """An expression that creates ``marker`` if it is ever evaluated."""
    return f"__import__('pathlib').Path({str(marker)!r}).touch()"


def open_and_run_exported(data, namespace=None):
    """What a student does with a shared file: open it, export its code, run the code.

    Returns the ValueError that refused the file, or None when everything ran.
    """
    try:
        model = DiagramModel.from_dict(json.loads(json.dumps(data)), namespace=namespace)
        code = model.code()
    except ValueError as error:
        return error
    exec(compile(code, "exported.py", "exec"), {"__name__": "exported"})  # noqa: S102
    return None


def test_a_keyword_argument_key_never_runs(tmp_path):
    """The issue's file: the outer controller's ``kwargs`` key carries a call."""
    marker = tmp_path / "ran"
    key = f"F={payload(marker)} or 0.0009, output"
    data = saved([block("controller", "outer_controller", {key: "mu"}, OUTER_INPUTS,
                        ["mu[0]", "mu[1]"])])
    error = open_and_run_exported(data)
    assert not marker.exists()
    assert str(error).startswith("blocks[0].recipe.kwargs: 'outer_controller' takes no "
                                 "keyword argument \"F=__import__(")
    assert str(error).endswith("allowed: ['F', 'output']")


@pytest.mark.parametrize("version", ["controlkit.widget/1", "controlkit.widget/2"])
@pytest.mark.parametrize("field, value, message", [
    ("kind", "__import__('os')", r"blocks\[0\]\.recipe\.kind: must be 'variable' or a "
                                 r"palette entry"),
    ("kwargs.k", "{payload}", r"blocks\[0\]\.recipe\.kwargs\.k: must be a finite number, "
                              r"got \"__import__\('pathlib'\)"),
    ("kwargs.k", float("inf"), r"blocks\[0\]\.recipe\.kwargs\.k: must be a finite number, "
                               r"got inf"),
    ("kwargs.k", [1.0, 2.0], r"blocks\[0\]\.recipe\.kwargs\.k: must be a finite number"),
    ("kwargs.k", True, r"blocks\[0\]\.recipe\.kwargs\.k: must be a finite number, got True"),
])
def test_a_recipe_value_is_checked_by_the_entrys_rules(tmp_path, version, field, value,
                                                        message):
    marker = tmp_path / "ran"
    if value == "{payload}":
        value = payload(marker)
    entry = block("gain", "gain", {"k": 2.0}, ["u"], ["y"])
    if field == "kind":
        entry["recipe"]["kind"] = value
    else:
        entry["recipe"]["kwargs"]["k"] = value
    with pytest.raises(ValueError, match=message):
        DiagramModel.from_dict(saved([entry], version))
    assert not marker.exists()


def test_a_source_name_never_reaches_the_exported_code(tmp_path):
    """``source_name`` was pasted into the exported code as a variable name."""
    marker = tmp_path / "ran"
    data = saved([block("gain", "gain", {"k": 2.0}, ["u"], ["y"]), {
        "name": "lag", "recipe": None, "label": None, "position": None, "look": None,
        "inputs": ["u"], "outputs": ["y"], "dt": 0}],
        source_name=f"[{payload(marker)}] and source")
    lag = ct.ss(-1.0, 1.0, 1.0, 0.0, name="lag", inputs="u", outputs="y")
    try:
        model = DiagramModel.from_dict(data, systems={"lag": lag})
        namespace = {"source": ct.interconnect([lag], inputs="u", outputs="y")}
        exec(model.code(), namespace)  # noqa: S102 - what a student would do with it
        error = None
    except ValueError as refused:
        error = refused
    assert not marker.exists()
    assert str(error).startswith("source_name: must be null or a Python identifier")


@pytest.mark.parametrize("variable", ["lag\nimport os", "lag; x", "lambda", "1lag"])
def test_a_notebook_variable_must_be_an_identifier(variable):
    data = saved([{"name": "lag", "recipe": {"kind": "variable", "variable": variable},
                   "label": None, "position": None, "look": None, "inputs": ["u"],
                   "outputs": ["y"], "dt": 0}])
    lag = ct.ss(-1.0, 1.0, 1.0, 0.0, name="lag", inputs="u", outputs="y")
    with pytest.raises(ValueError, match=r"blocks\[0\]\.recipe\.variable: must be a Python "
                                         r"identifier"):
        DiagramModel.from_dict(data, namespace={variable: lag})


@pytest.mark.parametrize("name", ["gain\n__import__('os')", "gain\r", "gain\x00", "g.ain",
                                  "", "g" * 101])
def test_a_block_name_with_a_newline_or_a_dot_is_refused(name):
    """python-control accepts any name without a dot; a file's names are also printable
    and short (a newline in a name reached generated code's comments)."""
    data = saved([block(name, "gain", {"k": 2.0}, ["u"], ["y"])])
    with pytest.raises(ValueError, match=r"blocks\[0\]\.name: must be a name of 1 to 100 "
                                         r"characters without '\.' or control characters"):
        DiagramModel.from_dict(data)


@pytest.mark.parametrize("name", ["it's", 'say "hi"', "x') or __import__('os') #",
                                  "back\\slash", "ünï cødé"])
def test_quotes_in_names_reach_the_code_as_strings(tmp_path, name):
    """A name the schema accepts goes into the exported code only through repr."""
    data = saved([block(name, "pi", {"kp": 2.0, "ki": 1.0}, ["u"], ["y"]),
                  block("sum", "summing_junction", {"signs": "+-"}, ["u1", "u2"], ["y"])],
                 wires=[[name, "y", "sum", "u2", 1.0]], inputs=[["r", [["sum", "u1", 1.0]]]],
                 outputs=[["y", [["out", name, "y", 1.0]]]],
                 hints={"labels": {name: f"$K$ {name}"}, "title": name})
    model = DiagramModel.from_dict(data)
    namespace = {}
    exec(model.code("loop"), namespace)  # noqa: S102
    built = namespace["loop"]
    assert [s.name for s in built.syslist] == [name, "sum"]
    assert built.drawing_hints["labels"] == {name: f"$K$ {name}"}
    np.testing.assert_array_equal(built.connect_map, model.system().connect_map)


@pytest.mark.parametrize("field, value, message", [
    ("signs", "+" * 100_000, r"blocks\[0\]\.recipe\.kwargs\.signs: must be a string of 2 to "
                             r"16 characters"),
    ("den", [1.0] * 200_000, r"blocks\[0\]\.recipe\.kwargs\.den: must be a list of 1 to 30 "
                             r"items"),
    ("position", [1e308, 0.0], r"blocks\[0\]\.position\[0\]: must be a finite number in "
                               r"\[-1e\+06, 1e\+06\]"),
    ("inputs", ["u"] * 3000, r"blocks\[0\]\.inputs: must be a list of at most 2000 items"),
])
def test_huge_sizes_are_refused_before_anything_is_built(field, value, message):
    if field == "signs":
        entry = block("sum", "summing_junction", {"signs": value},
                      [f"u{i + 1}" for i in range(len(value))], ["y"])
    elif field == "den":
        entry = block("tf", "transfer_function", {"num": [1.0], "den": value}, ["u"], ["y"])
    else:
        entry = block("gain", "gain", {"k": 2.0}, ["u"], ["y"])
        entry[field] = value
    with pytest.raises(ValueError, match=message):
        DiagramModel.from_dict(saved([entry]))


def test_a_file_too_large_to_be_a_diagram_is_not_parsed():
    text = json.dumps(saved([])) + " " * 5_000_001
    with pytest.raises(ValueError, match=r"a saved diagram is at most 5,000,000 characters"):
        DiagramModel.from_json(text)


@pytest.mark.parametrize("data, message", [
    (saved([], wires=[["ghost", "y", "other", "u", 1.0]]),
     r"wires\[0\]: names no block of the file: 'ghost'"),
    (saved([block("gain", "gain", {"k": 2.0}, ["u"], ["y"])],
           inputs=[["r", [["gain", "nope", 1.0]]]]),
     r"inputs\[0\]\[1\]\[0\]: block 'gain' has no input signal 'nope'"),
    (saved([], hints={"title": "x", "script": "alert(1)"}),
     r"hints: unknown field 'script'; allowed: \['beside', 'groups', 'labels'"),
    (saved([], surprise=1), r"diagram: unknown field 'surprise'"),
    ({"format": "controlkit.widget/2", "name": "x"}, r"diagram: missing field 'blocks'"),
    ([1, 2], r"a saved diagram must be a JSON object, got list"),
])
def test_every_field_is_checked_and_named(data, message):
    with pytest.raises(ValueError, match=message):
        DiagramModel.from_dict(data)


_V2 = '{"format": "controlkit.widget/2", "name": "x", "blocks": [], "setup": {"horizon": '


@pytest.mark.parametrize("text, message", [
    (_V2 + "1" + "0" * 400 + "}}", r"setup\.horizon: must be a finite number"),
    (_V2 + "1" + "0" * 5000 + "}}", r"setup\.horizon: must be a finite number"),
    (json.dumps(saved([block("g", ["gain"], {"k": 1.0}, ["u"], ["y"])])),
     r"blocks\[0\]\.recipe\.kind: must be 'variable' or a palette entry"),
    (json.dumps(saved([block("g", "gain", {"k": 1.0}, ["u"], ["y"])],
                      version="controlkit.widget/2", inputs=[["r", [["g", "u", 1.0]]]],
                      setup={"sources": {"r": {"kind": ["step"]}}})),
     r"setup\.sources\['r'\]\.kind: must be one of"),
    (json.dumps(saved([block("pi", "pi", {"kp": 1.0, "ki": 1.0}, ["u"], ["y"],
                             sampled={"Ts": 1e308})], version="controlkit.widget/2")),
     r"blocks\[0\]\.recipe\.sampled\.Ts: must be a finite number > 0 <= 1e\+06"),
])
def test_numbers_beyond_floats_and_kinds_that_are_not_names_are_refused_by_field(text,
                                                                                message):
    # a review's files: OverflowError, Python's digit limit, "unhashable type" and numpy's
    # LinAlgError from deep inside, naming no field
    with pytest.raises(ValueError, match=message):
        DiagramModel.from_json(text)


def test_an_integer_beyond_str_s_digit_limit_is_refused_by_field():
    # (from Python, not JSON: the message's digit count was Python's str() of it, limited
    # to 4 300 digits, which raised its own ValueError naming no field)
    data = {"format": "controlkit.widget/2", "name": "x", "blocks": [],
            "setup": {"horizon": 10 ** 5000}}
    with pytest.raises(ValueError, match=r"setup\.horizon: .* got an integer of 5001 digits"):
        DiagramModel.from_dict(data)


@pytest.mark.parametrize("name", ["T", "U", "X0", "response"])
def test_a_diagram_named_as_the_written_code_s_own_variables_exports_code_that_runs(name):
    # simulate_T(T) made the time grid the diagram's variable: the exported code failed
    data = saved([block("lag", "transfer_function", {"num": [1.0], "den": [1.0, 1.0]},
                        ["u"], ["y"])], version="controlkit.widget/2",
                 inputs=[["r", [["lag", "u", 1.0]]]], outputs=[["y", [["out", "lag", "y",
                                                                       1.0]]]],
                 setup={"horizon": 1.0})
    data["name"] = name
    model = DiagramModel.from_dict(data)
    namespace = {}
    exec(compile(model.code(), "exported.py", "exec"), namespace)
    assert namespace["response"].outputs.shape[-1] > 1
    with pytest.raises(ValueError, match="a name the written code uses itself"):
        model.code(variable="T")


def test_a_format_1_file_of_a_discrete_diagram_loads_sampled():
    """Format 1 sampled follow-the-period palette blocks by the block's saved dt."""
    data = saved([block("pi", "pi", {"kp": 1.0, "ki": 0.5}, ["u"], ["y"], dt=0.1)])
    model = DiagramModel.from_dict(data)
    assert model.blocks["pi"].system.dt == 0.1
    assert model.blocks["pi"].recipe["sampled"] == {"Ts": 0.1}
    assert model.to_dict()["format"] == "controlkit.widget/2"
