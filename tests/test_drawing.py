"""Block-diagram drawing of any interconnect: every block and signal shown, loose ends marked."""

import re
import warnings

import control as ct
import numpy as np
import pytest

from controlkit.diagrams.cmg import cmg_loop
from controlkit.diagrams.spacecraft import linearized_plant, mec_loop, output_zeroing_loop
from controlkit.drawing import compress_signals, diagram_graph, draw_block_diagram


def svg_text(sys, tmp_path):
    path = tmp_path / f"{sys.name}.svg"
    draw_block_diagram(sys, path)
    return path.read_text()


def base(name):
    return re.sub(r"\[\d+\]$", "", name)


def user_loop():
    plant = ct.tf2ss(ct.tf([1], [1, 1]), name="motor", inputs="v", outputs="w")
    pi = ct.tf2ss(ct.tf([2, 1], [1, 0]), name="pi", inputs="e", outputs="v")
    error = ct.summing_junction(inputs=["w_ref", "-w"], output="e", name="error")
    return ct.interconnect([plant, pi, error], inputs="w_ref", outputs="w", name="speed_loop")


@pytest.mark.parametrize("build", [
    lambda: output_zeroing_loop(),          # Fig. 2
    lambda: linearized_plant(),             # Fig. 2, red frame
    lambda: mec_loop(K=0.1),                # Fig. 3
    lambda: mec_loop(K="frit"),             # Fig. 4
    lambda: cmg_loop(),                     # thesis
    user_loop,
])
def test_every_block_and_connected_signal_appears_in_the_svg(build, tmp_path):
    sys = build()
    svg = svg_text(sys, tmp_path)
    for s in sys.syslist:
        assert f">{s.name}<" in svg, s.name
    graph = diagram_graph(sys)
    for signals in graph["edges"].values():
        for name in signals:
            assert base(name) in svg, name


def test_feedback_and_external_signals_are_in_the_graph():
    g = diagram_graph(output_zeroing_loop())
    assert g["edges"][("output", "controller")] == ["h[0]", "h[1]"]
    assert g["edges"][("inputs", "controller")] == ["r[0]", "r[1]"]
    assert ("linearizer", "plant") in g["edges"]
    assert not g["unconnected_inputs"]


def test_unconnected_ports_and_algebraic_loops_are_still_drawn(tmp_path):
    a = ct.nlsys(None, lambda t, x, u, p: u[0:1], inputs=["x", "spare"], outputs=["y"],
                 name="a", dt=None)
    b = ct.nlsys(None, lambda t, x, u, p: -u, inputs=["y"], outputs=["x"], name="b", dt=None)
    c = ct.nlsys(None, lambda t, x, u, p: u, inputs=["y"], outputs=["z", "extra"], name="c",
                 dt=None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # python-control warns about the loose ends
        sys = ct.interconnect([a, b, c], inputs=[], outputs=["z"], name="loose")
    g = diagram_graph(sys)
    assert g["unconnected_inputs"] == {"a": ["spare"]}
    assert g["unused_outputs"] == {"c": ["extra"]}
    svg = svg_text(sys, tmp_path)
    assert "unconnected: spare" in svg and "unused: extra" in svg
    assert ">a<" in svg and ">b<" in svg


def test_png_is_written(tmp_path):
    draw_block_diagram(mec_loop(K="frit"), tmp_path / "fig4.png")
    assert (tmp_path / "fig4.png").stat().st_size > 20_000


def test_single_block_is_refused():
    with pytest.raises(ValueError, match=r"sys must be a control.InterconnectedSystem"):
        diagram_graph(ct.nlsys(None, lambda t, x, u, p: u, inputs=1, outputs=1))


def test_compress_signals_keeps_order_and_gaps():
    assert compress_signals(["K[0]", "K[1]", "K[3]", "x"]) == ["K[0..1]", "K[3]", "x"]
    assert compress_signals([]) == []
    assert np.array_equal(compress_signals(["a[2]"]), ["a[2]"])
