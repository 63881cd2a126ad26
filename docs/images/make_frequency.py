"""The pictures of *MEC in the frequency domain*: ``python docs/images/make_frequency.py``.

They are the figures ``controlkit reproduce spacecraft`` writes (``freq01``, ``freq02``,
``freq03``), drawn from the loops linearized at the target with the gain FRIT converges to
in the ``proposed`` case over the paper's 20 000 s.
"""

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

from controlkit.studies.spacecraft import frequency_outputs, outputs, scenario  # noqa: E402

HERE = Path(__file__).parent
PICTURES = {"freq01_loop_gain": "mec_frequency_loop_gain.png",
            "freq02_sensitivity": "mec_frequency_sensitivity.png",
            "freq03_tolerance": "mec_frequency_tolerance.png"}


def main():
    metrics = {"proposed": outputs.metrics(scenario.run("proposed"))}
    _, tables = frequency_outputs.analyse(metrics)
    for stem, name in PICTURES.items():
        frequency_outputs.figure(tables, stem).savefig(HERE / name, dpi=160)


if __name__ == "__main__":
    main()
