"""Block-diagram drawing of any interconnect: every block and signal shown, loose ends marked."""

import re
import warnings

import control as ct
import numpy as np
import pytest

from controlkit.drawing import compress_signals, diagram_graph, draw_block_diagram
from controlkit.studies.cmg.diagrams import cmg_loop
from controlkit.studies.spacecraft.diagrams import linearized_plant, mec_loop, output_zeroing_loop


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
        if isinstance(s, ct.StateSpace) and s.nstates == 0:
            continue  # a summing junction is a circle (tested below)
        assert re.search(rf">{re.escape(s.name)}(<|,)", svg), s.name  # "nominal, dt = 0.1"
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


@pytest.mark.parametrize("label", ["$\\frac{$", "$" + "{" * 140 + "}" * 140 + "$"])
def test_a_label_matplotlib_cannot_read_as_tex_is_drawn_as_its_text(label, tmp_path):
    # a label from a shared file failed inside matplotlib's mathtext (a ValueError naming
    # no block, a RecursionError for nested braces), and nothing was drawn
    a = ct.nlsys(None, lambda t, x, u, p: u, inputs=["u"], outputs=["y"], name="pi")
    b = ct.nlsys(None, lambda t, x, u, p: -u, inputs=["y"], outputs=["u"], name="plant")
    sys = ct.interconnect([a, b], inputs=[], outputs=["y"], name="loop")
    with pytest.warns(UserWarning, match=r"of block 'pi' is not TeX matplotlib can draw"):
        draw_block_diagram(sys, tmp_path / "loop.svg", labels={"pi": label})
    assert (tmp_path / "loop.svg").stat().st_size > 1000


def test_single_block_is_refused():
    with pytest.raises(ValueError, match=r"sys must be a control.InterconnectedSystem"):
        diagram_graph(ct.nlsys(None, lambda t, x, u, p: u, inputs=1, outputs=1))


def test_compress_signals_keeps_order_and_gaps():
    assert compress_signals(["K[0]", "K[1]", "K[3]", "x"]) == ["K[0..1]", "K[3]", "x"]
    assert compress_signals([]) == []
    assert np.array_equal(compress_signals(["a[2]"]), ["a[2]"])


# --- paper-style drawing: measured on the rendered figure -----------------------------------

PAPER = {
    "fig2": lambda: output_zeroing_loop(),
    "fig3": lambda: mec_loop(K=0.1),
    "fig4": lambda: mec_loop(K="frit"),
    "cmg": lambda: cmg_loop(),
}


def blank_bands(fig):
    """The blank margins of the figure at its top, bottom, left and right edges (inches)."""
    fig.canvas.draw()
    ink = (np.asarray(fig.canvas.buffer_rgba())[..., :3] < 250).any(axis=-1)
    rows, cols = np.nonzero(ink.any(axis=1))[0], np.nonzero(ink.any(axis=0))[0]
    height, width = ink.shape
    return tuple(float(margin) / fig.dpi for margin in (
        rows[0], height - rows[-1] - 1, cols[0], width - cols[-1] - 1))


def rendered(fig):
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    texts = [t for t in fig.axes[0].texts if t.get_text().strip()]
    return renderer, texts


def assert_legible(fig):
    """No text cut off, overlapping another, partly under a block or crossed by a line."""
    renderer, texts = rendered(fig)
    boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts]
    page = fig.bbox
    for label, box in boxes:  # nothing cut off at the edges
        inside = page.x0 <= box.x0 <= box.x1 <= page.x1 and page.y0 <= box.y0 <= box.y1 <= page.y1
        assert inside, label
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1:]:
            assert not box_a.overlaps(box_b), (a, b)
    # no label is partly covered by a block or crossed by a line
    ax = fig.axes[0]
    blocks = [p.get_window_extent(renderer) for p in ax.patches
              if type(p).__name__ in ("FancyBboxPatch", "Circle")]
    for t in texts:
        box = t.get_window_extent(renderer)
        for b in blocks:
            within = b.x0 <= box.x0 and box.x1 <= b.x1 and b.y0 <= box.y0 and box.y1 <= b.y1
            assert within or not box.overlaps(b), t.get_text()
        inner = box.padded(-1)
        for line in ax.lines:
            if line.get_marker() == "o":
                continue
            xy = ax.transData.transform(np.column_stack([line.get_xdata(), line.get_ydata()]))
            for (x0, y0), (x1, y1) in zip(xy[:-1], xy[1:], strict=True):
                crosses = (max(x0, x1) >= inner.x0 and min(x0, x1) <= inner.x1
                           and max(y0, y1) >= inner.y0 and min(y0, y1) <= inner.y1)
                assert not crosses, t.get_text()


@pytest.mark.parametrize("name", sorted(PAPER))
def test_paper_diagrams_fit_a_slide_with_readable_separate_text(name):
    import matplotlib.pyplot as plt

    fig = draw_block_diagram(PAPER[name]())
    _, texts = rendered(fig)
    width, height = fig.get_size_inches()
    # the page is the drawing: no blank band pads it (to a slide's proportions or else)
    top, bottom, left, right = blank_bands(fig)
    assert max(top, bottom) < 0.35 and max(left, right) < 0.8, blank_bands(fig)
    # scaled to fit a 1280 x 720 slide, the smallest font must still be 10 px
    px_per_inch = min(1280 / width, 720 / height)
    smallest = min(t.get_fontsize() for t in texts) / 72 * px_per_inch
    assert smallest >= 10.0, smallest
    assert_legible(fig)
    plt.close(fig)


def test_fig4_draws_the_nominal_model_in_parallel_to_the_plant_and_K_as_a_block():
    import matplotlib.pyplot as plt

    fig = draw_block_diagram(mec_loop(K="frit"))
    pos = {t.get_text(): t.get_position() for t in fig.axes[0].texts}
    (x_plant, y_plant), (x_nominal, y_nominal) = pos["plant"], pos["$L_n$"]
    assert abs(x_plant - x_nominal) < 1e-9 and y_nominal < y_plant - 0.5
    assert "FRIT" in pos and "$L_a$: linearized plant (Fig. 2)" in pos
    fig3 = draw_block_diagram(mec_loop(K=0.1))
    assert "$K$" in [t.get_text() for t in fig3.axes[0].texts]
    plt.close("all")


def sampled_loop():
    """A user's loop: python-control's sampled names (``p$sampled``) and an implicit sum."""
    p = ct.sample_system(ct.tf2ss(ct.tf([1], [1, 1]), name="p", inputs="u", outputs="y"), 0.1)
    c = ct.sample_system(ct.tf2ss(ct.tf([2, 1], [1, 0]), name="c", inputs="e", outputs="u"),
                         0.1, name="c")
    k = ct.ss([], [], [], [[3.0]], inputs="y", outputs="yk", name="k", dt=None)
    return ct.interconnect([p, c, k],
                           connections=[["c.e", "-k.yk"], ["k.y", "p$sampled.y"],
                                        ["p$sampled.u", "c.u"]],
                           inplist=["c.e"], inputs="r", outlist=["p$sampled.y"], outputs="y",
                           name="sampled")


def test_dollar_names_are_literal_and_implicit_sums_and_gains_have_their_shapes(tmp_path):
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    sys = sampled_loop()
    assert "p$sampled" in [s.name for s in sys.syslist]
    fig = draw_block_diagram(sys, tmp_path / "sampled.svg", labels={"c": "$C(z)$"})
    texts = {t.get_text(): t for t in fig.axes[0].texts}
    assert not texts["p$sampled"].get_parse_math()  # drawn as written, not as maths
    assert texts["$C(z)$"].get_parse_math()  # an explicit label is TeX
    assert ">p$sampled<" in (tmp_path / "sampled.svg").read_text()
    assert not texts["sampled"].get_parse_math()  # the default title is the name, literal
    ax = fig.axes[0]
    circles = [p for p in ax.patches if isinstance(p, Circle)]
    triangles = [p for p in ax.patches if isinstance(p, Polygon) and len(p.get_xy()) == 4
                 and p.get_facecolor()[:3] != p.get_edgecolor()[:3]]
    assert len(circles) == 1  # r - 3 y is summed by the connection map: one junction
    assert sorted(t for t in texts if t in ("+", "\u2212")) == ["+", "\u2212"]
    assert len(triangles) == 1 and "3" in texts  # the static gain k is a triangle "3"
    plt.close(fig)


def test_summing_junction_block_is_a_circle_with_its_signs():
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    fig = draw_block_diagram(user_loop())
    ax = fig.axes[0]
    assert len([p for p in ax.patches if isinstance(p, Circle)]) == 1
    signs = sorted(t.get_text() for t in ax.texts if t.get_text() in ("+", "\u2212"))
    assert signs == ["+", "\u2212"]
    assert "error" not in [t.get_text() for t in ax.texts]  # drawn as a junction, not a box
    plt.close(fig)


def test_a_signal_with_three_destinations_is_one_branching_line():
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    fig = draw_block_diagram(mec_loop(K="frit"))
    ax = fig.axes[0]
    assert [t.get_text() for t in ax.texts].count("h") == 1  # labelled once, as the output
    # h goes to the controller, the compensator and the tuner, and out of the loop
    segments = [list(zip(line.get_xdata(), line.get_ydata(), strict=True))
                for line in ax.lines if line.get_gid() == "net:output:h"]
    parts = list(range(len(segments)))

    def root(i):
        while parts[i] != i:
            i = parts[i]
        return i

    def touches(a, b):  # an end of polyline a lies on polyline b
        for px, py in (a[0], a[-1]):
            for (x0, y0), (x1, y1) in zip(b[:-1], b[1:], strict=True):
                if (min(x0, x1) - 1e-9 <= px <= max(x0, x1) + 1e-9
                        and min(y0, y1) - 1e-9 <= py <= max(y0, y1) + 1e-9):
                    return True
        return False

    for i, a in enumerate(segments):
        for j, b in enumerate(segments):
            if i != j and touches(a, b):
                parts[root(i)] = root(j)
    assert len({root(i) for i in range(len(segments))}) == 1  # one connected line
    heads = [p for p in ax.patches if isinstance(p, Polygon) and p.get_gid() == "net:output:h"]
    assert len(heads) == 4
    dots = [line for line in ax.lines if line.get_gid() == "dot:output:h"]
    assert len(dots) >= 2  # it branches (at least twice for four ends)
    plt.close(fig)


def test_a_sensor_in_the_feedback_path_is_drawn_under_the_plant():
    import matplotlib.pyplot as plt

    P = ct.tf2ss(ct.tf([1], [1, 2, 1]), name="P", inputs="u", outputs="y")
    C = ct.tf2ss(ct.tf([5, 1], [1, 0]), name="C", inputs="e", outputs="u")
    H = ct.tf2ss(ct.tf([1], [0.1, 1]), name="H", inputs="y", outputs="ym")
    err = ct.summing_junction(inputs=["r", "-ym"], output="e", name="err")
    fig = draw_block_diagram(ct.interconnect([err, C, P, H], inputs="r", outputs="y"))
    pos = {t.get_text(): t.get_position() for t in fig.axes[0].texts}
    assert pos["H"][0] == pytest.approx(pos["P"][0]) and pos["H"][1] < pos["P"][1] - 0.5
    assert pos["y"][0] > pos["P"][0]  # the loop output leaves on the right
    plt.close(fig)


def test_parallel_branches_get_rows_of_their_own():
    import matplotlib.pyplot as plt

    Kp = ct.ss([], [], [], [[2.0]], inputs="e", outputs="up", name="Kp")
    Ki = ct.tf2ss(ct.tf([0.5], [1, 0]), name="I", inputs="e", outputs="ui")
    D = ct.tf2ss(ct.tf([0.1, 0], [0.01, 1]), name="D", inputs="e", outputs="ud")
    pid = ct.summing_junction(inputs=["up", "ui", "ud"], output="u", name="pid")
    P = ct.tf2ss(ct.tf([1], [1, 2, 1]), name="P", inputs="u", outputs="y")
    err = ct.summing_junction(inputs=["r", "-y"], output="e", name="err")
    fig = draw_block_diagram(ct.interconnect([err, Kp, Ki, D, pid, P], inputs="r", outputs="y"))
    texts = fig.axes[0].texts
    pos = {t.get_text(): t.get_position() for t in texts}
    ys = [pos["I"][1], pos["D"][1]]
    assert pos["I"][0] == pytest.approx(pos["D"][0])  # one column
    assert len({round(y, 6) for y in ys + [pos["2"][1]]}) == 3  # three rows
    assert [t.get_text() for t in texts].count("+") == 4  # r and the three branches
    plt.close(fig)


def test_two_external_inputs_into_a_junction_keep_their_own_arrows_and_signs():
    import matplotlib.pyplot as plt
    from matplotlib.patches import Polygon

    g = ct.tf2ss(ct.tf([1], [1, 1]), name="g", inputs="u", outputs="y")
    diff = ct.summing_junction(inputs=["a", "-b"], output="c", name="diff")
    sys = ct.interconnect([diff, g], connections=[["g.u", "diff.c"]],
                          inplist=["diff.a", "diff.b"], inputs=["a", "b"], outlist=["g.y"],
                          outputs="y")
    fig = draw_block_diagram(sys)
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert "a" in texts and "b" in texts and "a, b" not in texts
    assert sorted(t for t in texts if t in ("+", "\u2212")) == ["+", "\u2212"]
    into_junction = [p for p in ax.patches if isinstance(p, Polygon)
                     and (p.get_gid() or "").startswith("net:inputs:")]
    assert len(into_junction) == 2
    plt.close(fig)


# --- the layout's invariants, on the numbers it hands to the renderer -----------------------

def feedforward_loop_with_sensor():
    """A prefilter, a feedforward gain in parallel, a disturbance and a sensor H in the loop."""
    F = ct.tf2ss(ct.tf([1], [0.5, 1]), name="prefilter", inputs="r", outputs="rf")
    FF = ct.ss([], [], [], [[0.8]], inputs="r", outputs="uff", name="ff")
    C = ct.tf2ss(ct.tf([2, 1], [1, 0]), name="C", inputs="e", outputs="ufb")
    err = ct.summing_junction(inputs=["rf", "-ym"], output="e", name="err")
    usum = ct.summing_junction(inputs=["ufb", "uff", "d"], output="u", name="usum")
    P = ct.tf2ss(ct.tf([1], [1, 2, 1]), name="P", inputs="u", outputs="y")
    H = ct.tf2ss(ct.tf([1], [0.02, 1]), name="H", inputs="y", outputs="ym")
    return ct.interconnect([F, FF, err, C, usum, P, H], inputs=["r", "d"], outputs=["y", "u"],
                           name="feedforward")


@pytest.mark.parametrize("build", [feedforward_loop_with_sensor, user_loop, sampled_loop,
                                   PAPER["fig4"], PAPER["cmg"]])
def test_layout_keeps_blocks_apart_ports_on_edges_and_runs_outside_blocks(build):
    from controlkit.drawing._layout import layout

    L = layout(build())
    nodes, eps = L.nodes, 1e-9
    box = {n: (d["x"] - d["w"] / 2, d["x"] + d["w"] / 2, d["y"] - d["h"] / 2, d["y"] + d["h"] / 2)
           for n, d in nodes.items()}
    names = list(nodes)
    for i, a in enumerate(names):  # no two blocks overlap: a gap of at least 0.4 in
        for b in names[i + 1:]:
            (ax0, ax1, ay0, ay1), (bx0, bx1, by0, by1) = box[a], box[b]
            apart = max(bx0 - ax1, ax0 - bx1, by0 - ay1, ay0 - by1)
            assert apart >= 0.4, (a, b, apart)
    for (_net, n), (x, y) in L.port_xy.items():  # outputs leave from the block's side
        x0, x1, y0, y1 = box[n]
        assert x == pytest.approx(x0 if nodes[n].get("flip") else x1) and y0 < y < y1, n
    for (_net, n), (x, y, side) in L.in_xy.items():  # inputs arrive on the block's edge
        x0, x1, y0, y1 = box[n]
        if nodes[n]["shape"] == "sum":
            assert np.hypot(x - nodes[n]["x"], y - nodes[n]["y"]) == pytest.approx(0.2), n
        else:
            assert x == pytest.approx(x1 if side == "right" else x0) and y0 < y < y1, n
    for net in L.nets:  # a "next" arrow goes one column right (or into a flipped sensor)
        for b, kind in net.kinds.items():
            src = L.layer.get(net.src, -1)
            expected = {"next": L.layer[b] == src + 1 or nodes[b].get("feeder") == net.src,
                        "skip": L.layer[b] > src + 1, "back": L.layer[b] <= src}[kind]
            assert expected, (net.label, b, kind)
    for x in L.track_x.values():  # vertical runs lie in the gaps, through no block
        assert not any(x0 - eps <= x <= x1 + eps for x0, x1, _, _ in box.values()), x
    top = max(y1 for *_, y1 in box.values())
    bottom = min(y0 for _, _, y0, _ in box.values())
    assert all(y > top for y in L.lane_top.values())
    assert all(y < bottom for net, y in L.lane_bottom.items()
               if net not in L.local_nets and not nodes[net.src].get("flip"))
    left, right = L.x_mid - L.width / 2, L.x_mid + L.width / 2
    for n, (x0, x1, y0, y1) in box.items():  # every block on the page
        assert left < x0 and x1 < right and L.y_bottom < y0 and y1 < L.y_top, n


def test_the_feedback_sensor_and_the_feedforward_get_rows_below_the_main_path():
    from controlkit.drawing._layout import layout

    L = layout(feedforward_loop_with_sensor())
    main = [n for n in L.nodes if L.row[n] == 0]
    assert [n for n in sorted(main, key=L.layer.get)] == ["prefilter", "err", "C", "usum", "P"]
    assert L.nodes["H"].get("flip") and L.layer["H"] == L.layer["P"] and L.row["H"] == 1
    assert L.layer["ff"] == L.layer["prefilter"] and L.row["ff"] == 1
    ym = next(net for net in L.nets if net.src == "H")
    assert ym.kinds == {"err": "back"}


def test_a_sampled_data_diagram_tells_discrete_blocks_apart_and_shows_their_rates():
    from matplotlib.colors import to_hex

    import controlkit

    plant = ct.tf([1.0], [1.0, 1.0], name="plant", inputs="u", outputs="y")
    pi = ct.sample_system(ct.tf([1.0, 0.5], [1.0, 0.0]), 0.1, name="pi", inputs="e",
                          outputs="v")
    gain = ct.ss([], [], [], [[2.0]], dt=0.2, name="k", inputs="v", outputs="u")
    error = ct.summing_junction(["r", "-y"], "e", name="error")
    loop = controlkit.interconnect([plant, pi, gain, error], inputs="r", outputs="y")
    fig = draw_block_diagram(loop)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "dt = 0.1" in texts and "dt = 0.2" in texts and "continuous" in texts
    assert any(t.startswith("discrete: updates at its instants") for t in texts)
    fills = {to_hex(p.get_facecolor()) for p in fig.axes[0].patches}
    assert {"#fbeedd", "#eef3fb"} <= fills


# ------------------------------------------------------------ builders draw what they built


def my_pd(Ts=0.1):
    """A discrete PD on the error r - h, written the way a python-control user writes it."""

    def update(t, x, u, params):
        return u[0:2] - u[2:4]  # remember this sample's error

    def output(t, x, u, params):
        kp, kd = params["kp"], params["kd"]
        error = u[0:2] - u[2:4]
        return kp * error + kd * (error - x) / Ts

    return ct.nlsys(update, output, inputs=["r[0]", "r[1]", "h[0]", "h[1]"],
                    outputs=["mu_n[0]", "mu_n[1]"], states=["e[0]", "e[1]"], dt=Ts,
                    params={"kp": 0.002, "kd": 0.05}, name="my_pd")


def drawn_texts(sys):
    import matplotlib.pyplot as plt

    fig = draw_block_diagram(sys)
    texts = [t.get_text() for t in fig.axes[0].texts]
    plt.close(fig)
    return texts


def test_a_rewired_mec_loop_is_drawn_with_the_users_block_and_name():
    from controlkit.studies.spacecraft import scenario

    plant = scenario.true_plant(model_error=True)
    paper = drawn_texts(mec_loop(plant, K=0.1))
    assert "Fig. 3: MEC with a constant gain K" in paper
    assert "$F$" in paper and sorted(t for t in paper if t in ("+", "\u2212")) == ["+", "\u2212"]

    texts = drawn_texts(mec_loop(plant, controller=my_pd(), K=0.1, name="my_pd_mec"))
    assert texts[-1] == "my_pd_mec" or "my_pd_mec" in texts  # the title is the name given
    assert not [t for t in texts if "Fig." in t and "linearized plant" not in t]
    assert "my_pd" in texts and "$F$" not in texts  # the student's block, by its own name
    assert not [t for t in texts if t in ("+", "\u2212")]  # no r - h junction in front of it
    # the blocks the builder made are still drawn with the paper's symbols
    assert {"$K$", "$L_n$", r"$\mu_n + K\,(h_n - h)$"} <= set(texts)


def test_a_renamed_factory_block_is_drawn_by_its_name():
    from controlkit.blocks import spacecraft as sc

    texts = drawn_texts(output_zeroing_loop(controller=sc.outer_controller(0.003, name="fast")))
    assert "fast" in texts and "$F$" not in texts
    assert "fig2_loop" in texts  # the default name, but not the paper's controller
    assert "Fig. 2: the linearized plant closed by the outer loop" in drawn_texts(
        output_zeroing_loop(controller=sc.outer_controller(0.003)))  # another F, same figure


def test_the_cmg_loop_is_titled_by_its_name_once_rewired():
    from controlkit.blocks import cmg

    assert "CMG: adaptive backstepping SMC, sampled at Ts" in drawn_texts(cmg_loop())
    texts = drawn_texts(cmg_loop(saturation=cmg.torque_saturation(0.3, 1.0, name="weak")))
    assert "cmg_loop" in texts and "weak" in texts and "torque limits" not in texts


# ------------------------------------------- the order of the blocks is not the layout's


def cruise_blocks():
    """python-control's cruise control, simplified: a vehicle on a slope under a PI."""
    vehicle = ct.nlsys(
        lambda t, x, u, params: (u[0] - 0.5 * 1.3 * 0.32 * 2.4 * x[0] ** 2
                                 - 1600 * 9.8 * np.sin(u[1])) / 1600,
        lambda t, x, u, params: x, inputs=["F", "theta"], outputs="v", states="v",
        name="vehicle")
    ctrl = ct.tf2ss(ct.tf([500.0, 50.0], [1.0, 0.0]), inputs="e", outputs="F", name="ctrl")
    err = ct.summing_junction(inputs=["vref", "-v"], output="e", name="err")
    return [vehicle, ctrl, err], {"inputs": ["vref", "theta"], "outputs": ["v", "F"]}


def speed_loop_blocks():
    """Notebook 0's first loop: a motor under a PI, both the speed and the voltage out."""
    motor = ct.nlsys(lambda t, x, u, params: (-x[0] + 2.0 * u[0]) / 0.5,
                     lambda t, x, u, params: x[0], inputs="v", outputs="w", states="w",
                     name="motor")
    pi = ct.tf2ss(ct.tf([2.5, 5.0], [1, 0]), inputs="e", outputs="v", name="pi")
    error = ct.summing_junction(["w_ref", "-w"], "e", name="error")
    return [motor, pi, error], {"inputs": "w_ref", "outputs": ["w", "v"]}


def pid_blocks():
    """Three branches in parallel between two junctions, the plant's input an output."""
    Kp = ct.ss([], [], [], [[2.0]], inputs="e", outputs="up", name="Kp")
    Ki = ct.tf2ss(ct.tf([0.5], [1, 0]), name="I", inputs="e", outputs="ui")
    D = ct.tf2ss(ct.tf([0.1, 0], [0.01, 1]), name="D", inputs="e", outputs="ud")
    pid = ct.summing_junction(inputs=["up", "ui", "ud"], output="u", name="pid")
    P = ct.tf2ss(ct.tf([1], [1, 2, 1]), name="P", inputs="u", outputs="y")
    err = ct.summing_junction(inputs=["r", "-y"], output="e", name="err")
    return [P, pid, D, Ki, Kp, err], {"inputs": "r", "outputs": ["y", "u", "e"]}


def feedforward_blocks():
    sys = feedforward_loop_with_sensor()
    return list(sys.syslist), {"inputs": ["r", "d"], "outputs": ["y", "u"]}


LOOPS = {"cruise": cruise_blocks, "speed_loop": speed_loop_blocks, "pid": pid_blocks,
         "feedforward": feedforward_blocks}


def in_orders(name):
    """The loop's blocks in every order (three blocks) or in four of them."""
    import itertools

    blocks, _ = LOOPS[name]()
    orders = list(itertools.permutations(range(len(blocks))))
    return orders if len(orders) <= 6 else [orders[0], orders[-1], orders[7], orders[100]]


def wired(name, order):
    blocks, signals = LOOPS[name]()
    return ct.interconnect([blocks[i] for i in order], name=name, **signals)


def geometry(L):
    """Everything the renderer is told, keyed by names only (never by a position in a list)."""
    def net(n):
        return (n.src, n.label)

    def r(v):
        return round(float(v), 9)

    return {
        "nodes": {n: tuple(r(d[k]) for k in ("x", "y", "w", "h")) for n, d in L.nodes.items()},
        "ports": sorted((*net(n), b, r(x), r(y)) for (n, b), (x, y) in L.port_xy.items()),
        "entries": sorted((*net(n), b, r(x), r(y), side)
                          for (n, b), (x, y, side) in L.in_xy.items()),
        "inputs": sorted((*net(n), r(y)) for n, y in L.input_y.items()),
        "tracks": sorted((*net(n), str(k), r(x)) for (n, k), x in L.track_x.items()),
        "lanes": sorted((*net(n), r(y)) for n, y in L.lane_top.items())
        + sorted((*net(n), r(-y)) for n, y in L.lane_bottom.items()),
        "kinds": sorted((*net(n), tuple(sorted(n.kinds.items())), n.out, n.far)
                        for n in L.nets),
        "page": (r(L.width), r(L.height)),
    }


@pytest.mark.parametrize("name", sorted(LOOPS))
def test_the_same_loop_in_any_block_order_is_drawn_the_same(name):
    from controlkit.drawing._layout import layout

    orders = in_orders(name)
    first = geometry(layout(wired(name, orders[0])))
    for order in orders[1:]:
        assert geometry(layout(wired(name, order))) == first, order


@pytest.mark.parametrize("name", sorted(PAPER))
def test_the_papers_loops_rebuilt_from_their_blocks_in_other_orders_are_drawn_the_same(name):
    from controlkit.drawing._layout import layout

    built = PAPER[name]()
    blocks = list(built.syslist)
    for order in (blocks[::-1], blocks[1:] + blocks[:1]):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # python-control's notes on the loose ends
            again = ct.interconnect(order, inputs=built.input_labels,
                                    outputs=built.output_labels, name=built.name)
        again.drawing_hints = built.drawing_hints
        assert [s.name for s in again.syslist] != [s.name for s in blocks]
        assert geometry(layout(again)) == geometry(layout(built))


@pytest.mark.parametrize("name", sorted(LOOPS))
def test_every_declared_output_leaves_the_drawing_and_nothing_overlaps(name):
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    from controlkit.drawing._layout import layout

    for order in in_orders(name)[:2]:
        sys = wired(name, order)
        L = layout(sys)
        assert {p for net in L.nets if net.out for p in net.out_ports} == set(
            sys.output_labels)
        assert not L.omitted
        fig = draw_block_diagram(sys)
        # each output named once, in grey italics, right of every block
        right = max(d["x"] + d["w"] / 2 for d in L.nodes.values())
        leaving = sorted(t.get_text() for t in fig.axes[0].texts if t.get_style() == "italic"
                         and t.get_position()[0] > right and to_hex(t.get_color()) == "#333333")
        assert leaving == sorted(base(o) for o in sys.output_labels), leaving
        assert_legible(fig)
        plt.close(fig)


def test_the_cruise_loop_reads_from_the_reference_whatever_the_order():
    """python-control's natural order [vehicle, ctrl, err]: the junction still comes first,
    the slope theta enters above the reference, and both v and F leave on the right."""
    import matplotlib.pyplot as plt

    from controlkit.drawing._layout import layout

    L = layout(wired("cruise", (0, 1, 2)))
    assert [n for n in sorted(L.nodes, key=L.layer.get)] == ["err", "ctrl", "vehicle"]
    y = {net.label: value for net, value in L.input_y.items()}
    assert y["theta"] - y["vref"] >= 0.25
    fig = draw_block_diagram(wired("cruise", (0, 1, 2)))
    texts = {t.get_text(): t for t in fig.axes[0].texts}
    x_vehicle = L.nodes["vehicle"]["x"] + L.nodes["vehicle"]["w"] / 2
    assert texts["v"].get_position()[0] > x_vehicle and texts["F"].get_position()[0] > x_vehicle
    plt.close(fig)


def test_an_outputs_hint_draws_some_outputs_and_names_the_others_under_the_drawing():
    import matplotlib.pyplot as plt

    sys = wired("pid", range(6))
    sys.drawing_hints = {"outputs": ["y"]}
    fig = draw_block_diagram(sys)
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert "also outputs: u, e" in texts
    assert_legible(fig)
    plt.close(fig)
    assert "also outputs: u, q, mu" in drawn_texts(PAPER["fig2"]())  # Fig. 2 draws h only
    # a hint left from before a rewiring: what it names that is gone is passed over, and
    # it never hides every output
    sys.drawing_hints = {"outputs": ["y", "z"]}
    assert "also outputs: u, e" in drawn_texts(sys)
    sys.drawing_hints = {"outputs": ["z"]}
    assert not [t for t in drawn_texts(sys) if t.startswith("also outputs")]
