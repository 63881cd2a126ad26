"""Tables, metrics and the thesis-style Fig. 3-6 of the CMG study."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..blocks.cmg import T1_MAX, T2_MAX
from .export import save_figure
from .spacecraft import signal

#: CSV columns of ``controlkit reproduce cmg``, in order.
COLUMNS = ("time", "q1", "q2", "q4", "w1", "w2", "w4", "q2d", "q4d", "T1", "T2",
           "a1", "a2", "a3", "a4")


def table(resp) -> dict[str, np.ndarray]:
    """CSV columns (:data:`COLUMNS`); ``T1, T2`` are the torques applied after saturation.

    Examples
    --------
    >>> from controlkit.scenarios.cmg import run
    >>> list(table(run(horizon=0.005)))[:4]
    ['time', 'q1', 'q2', 'q4']
    """
    cols = {"time": resp.time}
    cols.update({name: signal(resp, name) for name in COLUMNS[1:]})
    cols["_T1_cmd"], cols["_T2_cmd"] = signal(resp, "T1_cmd"), signal(resp, "T2_cmd")
    return cols


def csv_columns(cols):
    """The public CSV columns of a :func:`table` (drops the commanded torques).

    Examples
    --------
    >>> list(csv_columns({"time": [0.0], "_T1_cmd": [1.0]}))
    ['time']
    """
    return {k: v for k, v in cols.items() if not k.startswith("_")}


def metrics(resp) -> dict:
    """Tracking after 1 s, torque use and final estimates of one run.

    Examples
    --------
    >>> from controlkit.scenarios.cmg import run
    >>> sorted(metrics(run(horizon=0.01)))[:2]
    ['final_estimates', 'final_q2_error_rad']
    """
    c = table(resp)
    after = c["time"] >= min(1.0, c["time"][-1])
    return {
        "horizon_s": float(c["time"][-1]),
        "max_abs_q2_error_after_1s_rad": float(np.abs(c["q2"] - c["q2d"])[after].max()),
        "max_abs_q4_error_after_1s_rad": float(np.abs(c["q4"] - c["q4d"])[after].max()),
        "final_q2_error_rad": float(c["q2"][-1] - c["q2d"][-1]),
        "final_q4_error_rad": float(c["q4"][-1] - c["q4d"][-1]),
        "peak_abs_T1_applied_Nm": float(np.abs(c["T1"]).max()),
        "peak_abs_T2_applied_Nm": float(np.abs(c["T2"]).max()),
        "peak_abs_T1_commanded_Nm": float(np.abs(c["_T1_cmd"]).max()),
        "peak_abs_T2_commanded_Nm": float(np.abs(c["_T2_cmd"]).max()),
        "fraction_T1_saturated": float(np.mean(np.abs(c["_T1_cmd"]) > T1_MAX)),
        "fraction_T2_saturated": float(np.mean(np.abs(c["_T2_cmd"]) > T2_MAX)),
        "final_estimates": [float(c[f"a{i}"][-1]) for i in range(1, 5)],
        "max_abs_estimates": [float(np.abs(c[f"a{i}"]).max()) for i in range(1, 5)],
    }


FIGURES = (
    ("fig3_q2", "Fig. 3  Gimbal 2 angle q2", "q2 [rad]", "q2", "q2d", None),
    ("fig4_q4", "Fig. 4  Gimbal 4 angle q4", "q4 [rad]", "q4", "q4d", None),
    ("fig5_T1", "Fig. 5  Motor 1 torque T1", "T1 [N m]", "T1", None, T1_MAX),
    ("fig6_T2", "Fig. 6  Motor 2 torque T2", "T2 [N m]", "T2", None, T2_MAX),
)
_COLORS = {"thesis": "tab:blue", "strong_friction": "tab:orange"}


def figures(tables, outdir) -> list[Path]:
    """Draw Fig. 3-6 (response solid, reference dashed, torque limits dotted) as PNG.

    Examples
    --------
    >>> import tempfile
    >>> from controlkit.scenarios.cmg import run
    >>> [p.name for p in figures({"thesis": table(run(horizon=0.01))}, tempfile.mkdtemp())]
    ['fig3_q2.png', 'fig4_q4.png', 'fig5_T1.png', 'fig6_T2.png']
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    written = []
    for stem, title, ylabel, col, ref, limit in FIGURES:
        fig, ax = plt.subplots(figsize=(7, 4))
        for name, c in tables.items():
            color = _COLORS.get(name, "tab:green")
            ax.plot(c["time"], c[col], color=color, linewidth=1.0, label=f"{col} ({name})")
        if ref is not None:
            first = next(iter(tables.values()))
            ax.plot(first["time"], first[ref], "k--", linewidth=1.2, label=f"{ref} (reference)")
        if limit is not None:
            for sign in (1, -1):
                ax.axhline(sign * limit, color="r", linestyle=":", linewidth=1,
                           label="motor range" if sign == 1 else None)
        ax.set_xlabel("Time [s]")
        ax.set_ylabel(ylabel)
        ax.set_title(title)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize=8)
        written.append(save_figure(fig, outdir / f"{stem}.png"))
    return written
