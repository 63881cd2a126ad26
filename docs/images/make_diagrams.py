"""Regenerate the pictures in this folder: ``python docs/images/make_diagrams.py [name ...]``.

Each block diagram is :func:`controlkit.drawing.draw_block_diagram` of a real interconnect:
the builders that the simulations use, so the pictures show the wiring that runs, and for
the theory pages a small loop of python-control LTI blocks (the MEC principle) whose
transfer functions the page derives. The other theory figures are plotted from the
transfer functions derived on their pages. With names, only those pictures are redrawn.
"""

import sys
from pathlib import Path

import control as ct
import matplotlib
import numpy as np

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.transforms import Bbox  # noqa: E402

from controlkit.drawing import draw_block_diagram  # noqa: E402
from controlkit.studies.cmg.diagrams import cmg_loop  # noqa: E402
from controlkit.studies.spacecraft.diagrams import mec_loop, output_zeroing_loop  # noqa: E402

HERE = Path(__file__).parent
F_PAPER = 0.0009            # outer-loop gain, Table 3 (1/s)
OMEGA_H0 = 2 * np.pi * 1e-4  # frequency of the paper's H0(t) (rad/s)


def mec_principle(K=0.1, F=F_PAPER):
    """The MEC of eq. (13)-(15) around the linearized plant ``h' = mu + d``, in LTI blocks.

    ``r -> h`` is ``F / (s + F)`` for every ``K`` and ``d -> h`` is
    ``s / ((s + F)(s + K))`` (``docs/theory/mec.md``).
    """
    blocks = [
        ct.ss([], [], [], [[F, -F]], inputs=["r", "h"], outputs="mu_n", name="controller"),
        ct.tf2ss(ct.tf([1], [1, 0]), inputs="mu_n", outputs="hn", name="nominal"),
        ct.ss([], [], [], [[1, K, -K]], inputs=["mu_n", "hn", "h"], outputs="mu",
              name="compensator"),
        ct.ss([[0]], [[1, 1]], [[1]], [[0, 0]], inputs=["mu", "d"], outputs="h", name="plant"),
    ]
    loop = ct.interconnect(blocks, inputs=["r", "d"], outputs=["h", "hn"],
                           name="mec_principle")
    loop.drawing_hints = {
        "labels": {"controller": "$F$", "nominal": r"$L_n:\ \dot h_n = \mu_n$",
                   "compensator": r"$\mu_n + K\,(h_n - h)$",
                   "plant": r"$L_a:\ \dot h = \mu + d$"},
        "sums": {"controller": {"r": 1, "h": -1}},
        "beside": {"nominal": "compensator"},
        "title": "The MEC principle (eq. 13-15) around a plant with model error d",
    }
    return loop


def cmg_loop_two_rows():
    """``cmg_loop()`` drawn on two rows: the gyroscope under the controller, in the feedback.

    On one row the loop is about 6:1 and its labels shrink on a page; the builder's own
    hints are kept, only the gyroscope's place changes.
    """
    loop = cmg_loop()
    loop.drawing_hints = {**loop.drawing_hints, "beside": {"cmg": "smc"}}
    return loop


def save_cropped(fig, path, pad=0.12):
    """Save ``fig`` cut to its drawn content (no blank bands around a wide diagram)."""
    fig.canvas.draw()
    pixels = np.asarray(fig.canvas.buffer_rgba())[..., :3]
    rows, cols = np.nonzero((pixels < 250).any(axis=-1))
    dpi, height = fig.dpi, pixels.shape[0]
    box = Bbox([[cols.min() / dpi - pad, (height - rows.max()) / dpi - pad],
                [cols.max() / dpi + pad, (height - rows.min()) / dpi + pad]])
    fig.savefig(path, bbox_inches=box, dpi=160)  # as draw_block_diagram saves
    return fig


def mec_disturbance(path):
    """Gain from the model error ``d`` to ``h``: ``1/(s+F)`` without MEC, with MEC for three K."""
    w = np.logspace(-6, 0, 600)
    s = 1j * w
    with plt.rc_context({"font.size": 12, "legend.fontsize": 11}):
        fig, ax = plt.subplots(figsize=(8.0, 4.4), layout="constrained")
        ax.loglog(w, np.abs(1 / (s + F_PAPER)), color="tab:green", lw=2.5,
                  label=r"without MEC: $1/(s+F)$")
        for K, color in ((0.01, "tab:orange"), (0.1, "tab:red"), (1.0, "tab:purple")):
            ax.loglog(w, np.abs(s / ((s + F_PAPER) * (s + K))), color=color, lw=2.5,
                      label=rf"MEC, $K = {K:g}$: $s/((s+F)(s+K))$")
        ax.axvline(OMEGA_H0, color="0.4", ls="--", lw=1.2)
        ax.annotate(r"$\omega$ of $H_0(t)$" "\n(period 10 000 s)", (OMEGA_H0, 1.5e-3),
                    xytext=(-8, 0), textcoords="offset points", ha="right", va="bottom",
                    color="0.3")
        ax.set_xlabel(r"frequency $\omega$ (rad/s)")
        ax.set_ylabel(r"$|h(j\omega)\,/\,d(j\omega)|$ (s)")
        ax.set_ylim(1e-3, 3e3)
        ax.grid(True, which="major", alpha=0.4)
        ax.set_title(r"Gain from the model error $d$ to the output $h$ ($F = 0.0009$ 1/s)")
        ax.legend(loc="lower right", frameon=True, framealpha=0.95)
        fig.savefig(path, dpi=120)
    return fig


DIAGRAMS = {
    "fig2_diagram.png": output_zeroing_loop,
    "fig3_diagram.png": lambda: mec_loop(K=0.1),
    "fig4_diagram.png": lambda: mec_loop(K="frit"),
    "cmg_diagram.png": cmg_loop_two_rows,
}
CROPPED_DIAGRAMS = {"mec_principle.png": mec_principle}
PLOTS = {"mec_disturbance.png": mec_disturbance}

if __name__ == "__main__":
    wanted = set(sys.argv[1:]) or set(DIAGRAMS) | set(CROPPED_DIAGRAMS) | set(PLOTS)
    unknown = wanted - set(DIAGRAMS) - set(CROPPED_DIAGRAMS) - set(PLOTS)
    if unknown:
        raise SystemExit(f"unknown picture(s) {sorted(unknown)}; known: "
                         f"{sorted(DIAGRAMS) + sorted(CROPPED_DIAGRAMS) + sorted(PLOTS)}")
    for name in sorted(wanted):
        if name in DIAGRAMS:
            fig = draw_block_diagram(DIAGRAMS[name](), HERE / name)
        elif name in CROPPED_DIAGRAMS:
            fig = save_cropped(draw_block_diagram(CROPPED_DIAGRAMS[name]()), HERE / name)
        else:
            fig = PLOTS[name](HERE / name)
        width, height = fig.get_size_inches()
        print(f"{name}: {width:.1f} x {height:.1f} in, aspect {width / height:.2f}")
