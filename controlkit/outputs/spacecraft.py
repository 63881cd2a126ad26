"""Tables, metrics and the paper-style Fig. 5-10 of the spacecraft study."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..blocks.spacecraft import POINTING_REQUIREMENT_DEG, pointing_error_deg
from ..scenarios import spacecraft as scenario
from .export import save_figure

#: CSV columns of ``controlkit reproduce spacecraft``, in order.
COLUMNS = ("time", "h1", "h2", "pointing_error_deg", "u1", "u2",
           "K11", "K12", "K21", "K22", "q0", "q1", "q2", "q3")


def signal(resp, label: str) -> np.ndarray:
    """One output of a response, by label (``resp.outputs[label]`` as an array).

    Examples
    --------
    >>> resp = scenario.run("ideal", horizon=0.2)
    >>> signal(resp, "q[0]").round(4).tolist()
    [0.9659, 0.9659, 0.9659]
    """
    try:
        index = list(resp.output_labels).index(label)
    except ValueError:
        raise ValueError(
            f"the response has no output {label!r}; outputs: {list(resp.output_labels)}"
        ) from None
    return np.atleast_2d(resp.outputs)[index]


def table(resp) -> dict[str, np.ndarray]:
    """The CSV columns of :data:`COLUMNS` from a closed-loop response.

    ``K`` columns are 0 where the loop has no compensator.

    Examples
    --------
    >>> list(table(scenario.run("ideal", horizon=0.2))) == list(COLUMNS)
    True
    """
    q = np.vstack([signal(resp, f"q[{i}]") for i in range(4)])
    labels = list(resp.output_labels)
    K = [signal(resp, f"K[{i}]") if f"K[{i}]" in labels else np.zeros_like(resp.time)
         for i in range(4)]
    columns = [resp.time, q[1], q[2], pointing_error_deg(q),
               signal(resp, "u[0]"), signal(resp, "u[1]"), *K, *q]
    return dict(zip(COLUMNS, columns, strict=True))


def metrics(resp) -> dict:
    """Headline numbers of one case.

    Returns
    -------
    dict
        ``final_pointing_error_deg``, ``max_pointing_error_last_half_deg``,
        ``requirement_met_last_half`` (``<= 0.05`` deg), ``peak_abs_u1_rad_s``,
        ``peak_abs_u2_rad_s``, ``final_h``, ``final_K`` (row-major, 0 without MEC),
        ``horizon_s``.

    Examples
    --------
    >>> m = metrics(scenario.run("ideal", horizon=1.0))
    >>> round(m["horizon_s"], 6)
    1.0
    """
    cols = table(resp)
    t, err = cols["time"], cols["pointing_error_deg"]
    last_half = t >= t[-1] / 2
    worst = float(err[last_half].max())
    return {
        "horizon_s": float(t[-1]),
        "final_pointing_error_deg": float(err[-1]),
        "max_pointing_error_last_half_deg": worst,
        "requirement_deg": POINTING_REQUIREMENT_DEG,
        "requirement_met_last_half": bool(worst <= POINTING_REQUIREMENT_DEG),
        "peak_abs_u1_rad_s": float(np.abs(cols["u1"]).max()),
        "peak_abs_u2_rad_s": float(np.abs(cols["u2"]).max()),
        "final_h": [float(cols["h1"][-1]), float(cols["h2"][-1])],
        "final_K": [float(cols[k][-1]) for k in ("K11", "K12", "K21", "K22")],
    }


# (file stem, title, y label, columns)
FIGURES = (
    ("fig05_h1", "Fig. 5  Output h1", "h1 = q1 [-]", ("h1",)),
    ("fig06_h2", "Fig. 6  Output h2", "h2 = q2 [-]", ("h2",)),
    ("fig07_pointing_error", "Fig. 7  Pointing error of antenna", "pointing error [deg]",
     ("pointing_error_deg",)),
    ("fig08_K", "Fig. 8  Compensation gain K", "K [1/s]", ("K11", "K12", "K21", "K22")),
    ("fig09_u1", "Fig. 9  Input u1", "u1 [rad/s]", ("u1",)),
    ("fig10_u2", "Fig. 10  Input u2", "u2 [rad/s]", ("u2",)),
)


def figures(tables: dict[str, dict[str, np.ndarray]], outdir) -> list[Path]:
    """Draw the paper's figures for the cases in ``tables`` and save them as PNG.

    Fig. 8 (``K``) is drawn only when a case with a compensator is present.

    Parameters
    ----------
    tables : dict
        Case name to its :func:`table` columns.
    outdir : str or pathlib.Path
        Folder for ``fig05_h1.png`` and the others.

    Returns
    -------
    list of pathlib.Path
        The files written.

    Examples
    --------
    >>> import tempfile
    >>> paths = figures({"ideal": table(scenario.run("ideal", horizon=1.0))}, tempfile.mkdtemp())
    >>> [p.name for p in paths][:2]
    ['fig05_h1.png', 'fig06_h2.png']
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    styles = {"K11": "-", "K12": "--", "K21": "-.", "K22": ":"}
    for stem, title, ylabel, cols in FIGURES:
        shown = tables
        if stem == "fig08_K":  # only the cases that have a compensator
            shown = {n: c for n, c in tables.items() if scenario.CASES[n].compensator != "none"}
            if not shown:
                continue
        zoom = stem == "fig07_pointing_error"
        fig, axes = plt.subplots(2 if zoom else 1, 1, figsize=(7, 6.5 if zoom else 4),
                                 squeeze=False)
        for ax in axes[:, 0]:
            for name, columns in shown.items():
                case = scenario.CASES[name]
                # ~4 000 points per curve: identical at this size, and quick to draw
                every = slice(None, None, max(1, len(columns["time"]) // 4000))
                for col in cols:
                    label = case.label if len(cols) == 1 else f"{case.label}: {col}"
                    ax.plot(columns["time"][every], columns[col][every], color=case.color,
                            label=label, linestyle=styles.get(col, "-"), linewidth=1.2)
            ax.set_xlabel("Time [s]")
            ax.set_ylabel(ylabel)
            ax.grid(True, alpha=0.3)
        if zoom:
            bottom = axes[1, 0]
            bottom.axhline(POINTING_REQUIREMENT_DEG, color="k", linestyle="--", linewidth=1,
                           label=f"requirement {POINTING_REQUIREMENT_DEG} deg")
            late = [c["pointing_error_deg"][c["time"] >= c["time"][-1] / 2]
                    for c in tables.values()]
            top = max([4 * POINTING_REQUIREMENT_DEG] + [1.15 * v.max() for v in late if v.size])
            bottom.set_ylim(0, top)
            bottom.set_title("detail around the 0.05 deg requirement", fontsize=9)
            bottom.legend(loc="upper right", fontsize=8)
        axes[0, 0].set_title(title)
        axes[0, 0].legend(loc="upper right", fontsize=8)
        written.append(save_figure(fig, outdir / f"{stem}.png"))
    return written
