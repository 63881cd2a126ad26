"""Regenerate the block-diagram pictures in this folder: ``python docs/images/make_diagrams.py``.

Each picture is :func:`controlkit.drawing.draw_block_diagram` of the builder that the
simulations use, so the pictures show the wiring that runs.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from controlkit.drawing import draw_block_diagram  # noqa: E402
from controlkit.studies.cmg.diagrams import cmg_loop  # noqa: E402
from controlkit.studies.spacecraft.diagrams import mec_loop, output_zeroing_loop  # noqa: E402

HERE = Path(__file__).parent
DIAGRAMS = {
    "fig2_diagram.png": output_zeroing_loop,
    "fig3_diagram.png": lambda: mec_loop(K=0.1),
    "fig4_diagram.png": lambda: mec_loop(K="frit"),
    "cmg_diagram.png": cmg_loop,
}

if __name__ == "__main__":
    for name, build in DIAGRAMS.items():
        fig = draw_block_diagram(build(), HERE / name)
        width, height = fig.get_size_inches()
        print(f"{name}: {width:.1f} x {height:.1f} in, aspect {width / height:.2f}")
