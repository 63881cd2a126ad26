"""The pictures of the page *Sampled-data diagrams*: ``python docs/images/make_sampled_data.py``.

Both come from one real diagram, :func:`cascade_loop` (the page includes its source):
``sampled_data_diagram.png`` is :func:`controlkit.drawing.draw_block_diagram` of it, and
``sampled_data_timeline.png`` its step response from
:func:`controlkit.input_output_response`, zoomed on the first samples so that the two
rates and the holds can be read.
"""

from pathlib import Path

import control as ct
import matplotlib
import numpy as np

matplotlib.use("Agg")

from make_diagrams import save_cropped  # noqa: E402  (this folder's script)

import controlkit  # noqa: E402
from controlkit.outputs.style import legend_outside, new_figure, slide_style  # noqa: E402

HERE = Path(__file__).parent


def cascade_loop():
    """A motor's angle: position loop at 50 ms, speed loop at 10 ms."""
    # motor: voltage v -> speed w -> angle theta, continuous (dt = 0)
    #   w' = (k v - w) / tau,  theta' = w;  k = 4 rad/s per V, tau = 0.25 s
    k, tau = 4.0, 0.25
    motor = ct.ss([[0.0, 1.0], [0.0, -1.0 / tau]], [[0.0], [k / tau]],
                  np.eye(2), 0.0, inputs="v", outputs=["theta", "w"],
                  states=["theta", "w"], name="motor")

    # speed PI, designed in continuous time (its zero on the motor's pole:
    # a speed loop of time constant 0.05 s), discretised by Tustin at 10 ms
    speed_pi = ct.sample_system(ct.tf([1.25, 5.0], [1.0, 0.0]), 0.01,
                                method="tustin", inputs="e_w",
                                outputs="v_cmd", name="speed_pi")

    # position controller at 50 ms, an nlsys: a gain, the speed limited
    def position_law(t, x, u, params):
        kp, w_max = params["kp"], params["w_max"]
        return np.clip(kp * (u[0] - u[1]), -w_max, w_max)

    position = ct.nlsys(None, position_law, inputs=["r", "theta"],
                        outputs="w_ref", params={"kp": 5.0, "w_max": 3.0},
                        dt=0.05, name="position")

    # static blocks (dt = None joins any timebase): the speed error and
    # the amplifier, which limits the voltage to 12 V
    speed_error = ct.summing_junction(["w_ref", "-w"], "e_w",
                                      name="speed_error")
    amplifier = ct.nlsys(None, lambda t, x, u, params: np.clip(u, -12, 12),
                         inputs="v_cmd", outputs="v", dt=None,
                         name="amplifier")

    #      +--------+ w_ref     +--------+ v_cmd +-------+ v +-------+ theta
    # r -->|position|--->o----->|speed_pi|------>|amplif.|-->| motor |--+-->
    #   +->| 50 ms  |   -^ e_w  | 10 ms  |       | 12 V  |   |       |-+|-> w
    #   |  +--------+    |      +--------+       +-------+   +-------+ ||
    #   |                +------------------- w -----------------------+|
    #   +------------------------------- theta -------------------------+
    return controlkit.interconnect(
        [motor, speed_pi, position, speed_error, amplifier],
        inputs="r", outputs=["theta", "w", "w_ref", "v"], name="cascade")


def timeline(loop, path):
    """The first 0.4 s of a 1 rad step: the continuous speed, two staircases."""
    T = np.arange(0.0, 1.5 + 5e-4, 1e-3)
    resp = controlkit.input_output_response(loop, T, 1.0)
    shown = T < 0.4
    with slide_style():
        fig, axes = new_figure(2, size=(8.0, 5.2))
        for ax, period in zip(axes, (0.05, 0.01), strict=True):
            for instant in np.arange(0.0, 0.4 - 1e-9, period):
                ax.axvline(instant, color="0.85", linewidth=0.8, zorder=0)
        axes[0].plot(T[shown], resp.outputs["w"][shown], color="tab:blue",
                     label="w: motor speed (continuous)")
        axes[0].plot(T[shown], resp.outputs["w_ref"][shown], color="tab:orange",
                     drawstyle="steps-post", label="w_ref: position loop, held 50 ms")
        axes[0].set_ylabel("speed (rad/s)")
        axes[1].plot(T[shown], resp.outputs["v"][shown], color="tab:red",
                     drawstyle="steps-post", label="v: speed PI, held 10 ms")
        axes[1].set_ylabel("voltage (V)")
        axes[1].set_xlabel("time (s)")
        axes[0].set_title("Two rates: grey lines mark each block's instants")
        legend_outside(fig, ncols=2)
        fig.savefig(path, dpi=120)
    return resp


if __name__ == "__main__":
    loop = cascade_loop()
    save_cropped(controlkit.draw_block_diagram(
        loop, title="A cascade: position loop at 50 ms, speed loop at 10 ms"),
        HERE / "sampled_data_diagram.png")
    resp = timeline(loop, HERE / "sampled_data_timeline.png")
    theta = resp.outputs["theta"]
    print(f"rates {loop.rates}, base period {loop.base_period} s; theta(1.5 s) = "
          f"{theta[-1]:.4f} rad, peak {theta.max():.4f} rad")
