"""Result figures are slide-ready: 200 dpi PNG + SVG, 12-14 pt text, legends off the data."""

import subprocess
import sys

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.ticker import LogFormatterSciNotation
from PIL import Image

from controlkit.outputs.style import PNG_DPI, PowerOfTenFormatter, save, slide_style
from controlkit.outputs.workers import FigureWorkers
from controlkit.studies.cmg import outputs as cmg_out
from controlkit.studies.cmg import scenario as cmg_scenario
from controlkit.studies.spacecraft import outputs as sc_out
from controlkit.studies.spacecraft import scenario as sc_scenario


@pytest.fixture(scope="module")
def sc_tables():
    return {name: sc_out.table(sc_scenario.run(name, horizon=50.0))
            for name in ("ideal", "without_mec", "proposed")}


@pytest.fixture(scope="module")
def cmg_tables():
    return {"thesis": cmg_out.table(cmg_scenario.run("thesis", horizon=3.0))}


def _texts(fig):
    return [t for t in fig.findobj(lambda a: hasattr(a, "get_fontsize") and hasattr(a, "get_text"))
            if t.get_text().strip()]


def _check_slide_ready(fig):
    FigureCanvasAgg(fig).draw()
    sizes = {round(t.get_fontsize(), 1) for t in _texts(fig)}
    assert sizes and min(sizes) >= 12 and max(sizes) <= 14, sizes
    renderer = fig.canvas.get_renderer()
    for legend in fig.legends:  # the legend overlaps no axes
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            assert not box.overlaps(ax.get_window_extent(renderer)), ax.get_title()


def test_pngs_are_200_dpi_with_a_vector_copy(tmp_path, sc_tables, cmg_tables):
    paths = sc_out.figures(sc_tables, tmp_path / "sc") + cmg_out.figures(cmg_tables,
                                                                          tmp_path / "cmg")
    pngs = [p for p in paths if p.suffix == ".png"]
    assert len(pngs) == 10
    for png in pngs:
        with Image.open(png) as image:
            dpi = image.info["dpi"]
            assert min(dpi) >= 199.5, (png.name, dpi)  # pHYs stores dots per metre
            assert image.size == (1600, 900)
        svg = png.with_suffix(".svg")
        assert svg in paths and svg.read_text().lstrip().startswith("<?xml")
    assert not list(tmp_path.rglob("*.partial"))


@pytest.mark.parametrize("stem", [spec[0] for spec in sc_out.FIGURES])
def test_spacecraft_figures_are_slide_ready(stem, sc_tables):
    _check_slide_ready(sc_out.figure(sc_tables, stem))


@pytest.mark.parametrize("stem", [spec[0] for spec in cmg_out.FIGURES])
def test_cmg_figures_are_slide_ready(stem, cmg_tables):
    fig = cmg_out.figure(cmg_tables, stem)
    _check_slide_ready(fig)
    # the curves are our simulation of the thesis's experiment, not its measurements
    labels = " ".join(t.get_text() for legend in fig.legends for t in legend.get_texts())
    assert "simulation" in labels and "thesis" not in labels
    assert fig.axes[0].get_title().startswith(f"Fig. {stem[3]} of the CMG thesis: ")


def test_fig7_is_logarithmic_with_the_requirement_and_ideal_on_top(sc_tables):
    ax = sc_out.figure(sc_tables, "fig07_pointing_error").axes[0]
    assert ax.get_yscale() == "log"
    flat = [line for line in ax.get_lines() if np.ptp(line.get_ydata()) == 0]
    assert [line.get_ydata()[0] for line in flat] == [0.05]
    ideal = [line for line in ax.get_lines() if line.get_label().startswith("Ideal")]
    others = [line for line in ax.get_lines() if line not in ideal + flat]
    assert ideal[0].get_linestyle() == "--"
    assert ideal[0].get_zorder() > max(line.get_zorder() for line in others)


def _value(label):
    """The number a plain-text log label such as '2×10⁻⁴' stands for."""
    superscripts = "⁰¹²³⁴⁵⁶⁷⁸⁹⁻"
    head = label.rstrip(superscripts)
    exponent = label[len(head):].translate(str.maketrans(superscripts, "0123456789-"))
    sign = -1.0 if head.startswith("−") else 1.0
    coeff, _, base = head.lstrip("−").rpartition("×")
    return sign * float(coeff or 1.0) * float(base) ** int(exponent or 0)


def test_log_axes_label_the_same_ticks_as_matplotlib_in_plain_text(sc_tables, cmg_tables):
    for fig in (sc_out.figure(sc_tables, "fig07_pointing_error"),
                cmg_out.figure(cmg_tables, "fig3_q2")):
        FigureCanvasAgg(fig).draw()
        ax = next(a for a in fig.axes if a.get_yscale() == "log")
        reference = LogFormatterSciNotation()
        reference.set_axis(ax.yaxis)
        ticks = ax.get_yticks()
        reference.set_locs(ticks)
        labels = [t.get_text() for t in ax.get_yticklabels()]
        # labelled where matplotlib labels, with the number matplotlib writes, and no TeX
        assert [bool(label) for label in labels] == [bool(reference(v)) for v in ticks]
        shown = [(v, label) for v, label in zip(ticks, labels, strict=True) if label]
        assert len(shown) >= 3 and not any("$" in label for _, label in shown)
        for value, label in shown:
            assert _value(label) == pytest.approx(value, rel=1e-12), label


def test_power_of_ten_formatter_writes_matplotlibs_numbers():
    f = PowerOfTenFormatter(labelOnlyBase=False)
    assert [f(v) for v in (1e-8, 1e3, 1.0, 3e-4, -1e-2)] == [
        "10⁻⁸", "10³", "10⁰", "3×10⁻⁴", "−10⁻²"]


def test_saved_result_figures_need_no_mathtext(tmp_path, monkeypatch, sc_tables, cmg_tables):
    # mathtext parsing took 4-5 ms a label, twice per figure (PNG and SVG)
    from matplotlib import mathtext

    def refuse(*args, **kwargs):
        raise AssertionError("a result figure parsed mathtext")

    monkeypatch.setattr(mathtext.MathTextParser, "parse", refuse)
    paths = (sc_out.figures(sc_tables, tmp_path, stems=["fig07_pointing_error"])
             + cmg_out.figures(cmg_tables, tmp_path, stems=["fig3_q2", "fig4_q4"]))
    assert len(paths) == 6


def test_fig8_legend_is_one_row_of_k_entries(sc_tables):
    fig = sc_out.figure(sc_tables, "fig08_K")
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["K11", "K12", "K21", "K22"]
    # told apart by colour, not by dashes alone
    colours = {tuple(line.get_color()) if not isinstance(line.get_color(), str)
               else line.get_color() for line in fig.axes[0].get_lines()}
    assert len(colours) == 4


def test_fig8_with_two_compensated_cases_keeps_a_colour_per_entry_and_a_style_per_case():
    tables = {name: sc_out.table(sc_scenario.run(name, horizon=20.0))
              for name in ("mec_fixed", "proposed")}
    fig = sc_out.figure(tables, "fig08_K")
    lines = fig.axes[0].get_lines()
    by_case = {}
    for line in lines[:8]:
        by_case.setdefault(line.get_linestyle(), set()).add(line.get_color())
    assert len(by_case) == 2 and all(len(colours) == 4 for colours in by_case.values())
    assert [t.get_text() for t in fig.legends[0].get_texts()][-2:] == [
        sc_scenario.CASES["mec_fixed"].label, sc_scenario.CASES["proposed"].label]


def test_titles_say_which_publication_the_figure_number_is_from(sc_tables, cmg_tables):
    titles = [sc_out.figure(sc_tables, spec[0]).axes[0].get_title() for spec in sc_out.FIGURES]
    titles += [cmg_out.figure(cmg_tables, spec[0]).axes[0].get_title()
               for spec in cmg_out.FIGURES]
    assert sum("Fig. 5 " in t for t in titles) == 2
    assert len({t.split(":")[0] for t in titles}) == len(titles)  # no two alike


def test_fig7_shows_the_ideal_curve_down_to_its_smallest_error():
    # after 15 000 s the ideal loop's error is below 1e-4 deg, where the axis used to end
    tables = {"ideal": sc_out.table(sc_scenario.run("ideal", horizon=15000.0))}
    ax = sc_out.figure(tables, "fig07_pointing_error").axes[0]
    smallest = tables["ideal"]["pointing_error_deg"].min()
    assert smallest < 1e-4 and smallest / 10 <= ax.get_ylim()[0] <= smallest


def test_cmg_tracking_has_a_log_error_panel_and_t2_states_its_limits(cmg_tables):
    fig = cmg_out.figure(cmg_tables, "fig3_q2")
    assert fig.axes[1].get_yscale() == "log" and "q2d" in fig.axes[1].get_ylabel()
    t2 = cmg_out.figure(cmg_tables, "fig6_T2").axes[0]
    assert "2.4 N m" in t2.get_title()
    assert t2.get_ylim()[1] < 0.5  # scaled to the data, not to the 2.4 N m range
    t1 = cmg_out.figure(cmg_tables, "fig5_T1")
    assert "switches every sample" in t1.axes[1].get_title()


def test_window_stats_bounds_the_mean():
    t = np.arange(0, 1, 0.001)
    x = np.sign(np.sin(2 * np.pi * 250 * t)) + t
    _, mean, low, high = cmg_out.window_stats(t, x, 0.05)
    assert mean.size == 20 and np.all(low <= mean) and np.all(mean <= high)
    with pytest.raises(ValueError, match="width must be > 0"):
        cmg_out.window_stats(t, x, 0.0)


def test_bad_stems_and_paths_are_named(sc_tables, tmp_path):
    with pytest.raises(ValueError, match="stem must be one of"):
        sc_out.figure(sc_tables, "fig99")
    with pytest.raises(ValueError, match="path must end in .png"):
        save(sc_out.figure(sc_tables, "fig05_h1"), tmp_path / "a.pdf")
    assert PNG_DPI >= 200


def test_library_never_switches_the_backend():
    code = ("import matplotlib; matplotlib.use('svg'); "
            "from controlkit.studies.spacecraft import outputs as o; "
            "from controlkit.studies.spacecraft import scenario as s; import tempfile; "
            "o.figures({'ideal': o.table(s.run('ideal', horizon=1.0))}, tempfile.mkdtemp()); "
            "print(matplotlib.get_backend())")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "svg"


def _broken_figures(tables, outdir, *, stems=None):
    raise RuntimeError(f"cannot draw {stems}")


def test_worker_processes_write_the_same_files_as_the_caller(tmp_path, sc_tables):
    stems = [spec[0] for spec in sc_out.FIGURES]
    names = {}
    for workers in (0, 2):
        with FigureWorkers(workers) as pool:
            # the slowest figure is handed out first; the files keep the figures' order
            pool.submit(sc_out.figures, sc_tables, tmp_path / str(workers), stems,
                        first=["fig07_pointing_error"])
            names[workers] = [p.name for p in pool.results()]
    assert names[0] == names[2] and len(names[2]) == 12
    assert names[2][:2] == ["fig05_h1.png", "fig05_h1.svg"]
    for png in (tmp_path / "0").glob("*.png"):  # the same pixels from either process
        with Image.open(png) as a, Image.open(tmp_path / "2" / png.name) as b:
            assert np.array_equal(np.asarray(a), np.asarray(b)), png.name


def test_saved_png_has_the_pixels_and_tags_of_savefig(tmp_path, sc_tables, cmg_tables):
    import io

    for fig in (sc_out.figure(sc_tables, "fig07_pointing_error"),
                cmg_out.figure(cmg_tables, "fig3_q2")):
        reference = io.BytesIO()
        FigureCanvasAgg(fig)
        with slide_style():
            fig.savefig(reference, format="png", dpi=PNG_DPI)
        ours = save(fig, tmp_path / "figure.png")[0]
        with Image.open(reference) as a, Image.open(ours) as b:
            assert np.array_equal(np.asarray(a), np.asarray(b))
            assert a.info == b.info  # dpi and the Software tag


def test_figure_workers_run_background_work_outside_the_drawing_slots(tmp_path):
    marker = tmp_path / "done"
    with FigureWorkers(2) as pool:
        pool.run_in_background(marker.write_text, "yes")
    assert marker.read_text() == "yes"  # close() waited for it
    with FigureWorkers(0) as pool:  # no workers: nothing runs
        pool.run_in_background(marker.write_text, "no")
    assert marker.read_text() == "yes"


def test_a_failing_figure_raises_in_the_caller(tmp_path, sc_tables):
    with FigureWorkers(2) as pool, pytest.raises(RuntimeError, match=r"cannot draw \['a'\]"):
        pool.submit(_broken_figures, sc_tables, tmp_path, ["a"])
        pool.results()
    with pytest.raises(ValueError, match="workers must be an integer >= 0"):
        FigureWorkers(-1)
