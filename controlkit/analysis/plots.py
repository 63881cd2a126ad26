"""Frequency responses side by side on one slide-sized figure.

python-control's :func:`~control.bode_plot` draws one system per call into pyplot's
current figure; a lecture wants several loops on one figure, labelled, with the Nyquist
frequency of a sampled loop and the band where one beats another.
:func:`compare_frequency_responses` draws that, in the look of every controlkit result
figure (:mod:`controlkit.outputs.style`).
"""

from __future__ import annotations

import control as ct
import numpy as np

#: Okabe-Ito colours, told apart in colour-blind vision and in greyscale print.
COLORS = ("#009E73", "#CC79A7", "#D55E00", "#0072B2", "#E69F00", "#56B4E9", "#000000")


def frequency_response(G, omega) -> np.ndarray:
    """``G`` at ``s = j w`` (continuous) or ``z = exp(j w dt)`` (discrete), shape
    ``(len(omega), noutputs, ninputs)``: one batched solve, no loop over frequencies.

    Examples
    --------
    >>> G = ct.ss(-1.0, 1.0, 1.0, 0.0)
    >>> complex(frequency_response(G, [1.0])[0, 0, 0])
    (0.5-0.5j)
    """
    G = ct.ss(G)
    omega = np.atleast_1d(np.asarray(omega, dtype=float))
    points = np.exp(1j * omega * G.dt) if G.isdtime(strict=True) else 1j * omega
    if G.nstates == 0:
        return np.broadcast_to(G.D, (omega.size, *G.D.shape)).astype(complex)
    shifted = points[:, None, None] * np.eye(G.nstates) - G.A
    return G.C @ np.linalg.solve(shifted, np.broadcast_to(G.B, (omega.size, *G.B.shape))) \
        + G.D


def gain(G, omega) -> np.ndarray:
    """``|G|`` of a SISO system, or its largest singular value, at each ``omega``.

    Examples
    --------
    >>> gain(ct.tf([1], [1, 1]), [1.0]).round(6).tolist()  # 1 / sqrt(2)
    [0.707107]
    """
    response = frequency_response(G, omega)
    if response.shape[1:] == (1, 1):
        return np.abs(response[:, 0, 0])
    return np.linalg.svd(response, compute_uv=False)[:, 0]


def compare_frequency_responses(systems, omega=None, *, title=None, phase=True, bands=(),
                                lines=(), ylabel="gain [dB]"):
    """Bode plots of several systems on one slide-sized figure.

    Parameters
    ----------
    systems : dict
        Legend label to a system (anything :func:`control.ss` takes). A SISO system is
        drawn as its gain and phase; a MIMO one as its largest singular value (no phase).
    omega : array_like, optional
        Frequencies in rad/s; default 400 points from 1e-3 below the slowest pole to the
        Nyquist frequency of the first discrete system (or 1e3 above the fastest pole).
    title : str, optional
        The figure's title.
    phase : bool
        Draw the phase (SISO systems) under the gain.
    bands : sequence of (float, float, str)
        Frequency intervals to shade on every axis, with their legend label.
    lines : sequence of (float, str)
        Gains (absolute, not dB) to mark with a dotted horizontal line and a label.
    ylabel : str
        Label of the gain axis.

    Returns
    -------
    matplotlib.figure.Figure
        Magnitude in dB against frequency in rad/s (log), the phase in degrees below;
        a discrete system's Nyquist frequency ``pi / dt`` is a dashed vertical line.

    Examples
    --------
    >>> fig = compare_frequency_responses({"1/(s+1)": ct.tf([1], [1, 1]),
    ...                                    "10/(s+10)": ct.tf([10], [1, 10])})
    >>> [ax.get_ylabel() for ax in fig.axes]
    ['gain [dB]', 'phase [deg]']
    """
    from ..outputs.style import legend_outside, log_scale, new_figure, slide_style

    if not isinstance(systems, dict) or not systems:
        raise ValueError(f"systems must be a dict of label -> system, got {systems!r}")
    systems = {str(label): ct.ss(G) for label, G in systems.items()}
    omega = _default_omega(systems.values()) if omega is None else np.asarray(omega, float)
    if omega.ndim != 1 or omega.size < 2 or not np.all(np.isfinite(omega)) or np.any(
            omega <= 0):
        raise ValueError("omega must be at least two finite frequencies > 0 (rad/s)")
    siso = [G for G in systems.values() if G.ninputs == G.noutputs == 1]
    with slide_style():
        fig, axes = new_figure(2 if phase and siso else 1,
                               height_ratios=(3, 2) if phase and siso else None)
        for i, (label, G) in enumerate(systems.items()):
            color = COLORS[i % len(COLORS)]
            response = frequency_response(G, omega)
            style = dict(color=color, linewidth=2.0, linestyle=("-", "--", "-.", ":")[i % 4])
            axes[0].plot(omega, 20 * np.log10(np.maximum(gain(G, omega), 1e-300)),
                         label=label, **style)
            if len(axes) > 1 and response.shape[1:] == (1, 1):
                axes[1].plot(omega, np.degrees(np.unwrap(np.angle(response[:, 0, 0]))),
                             **style)
        for ax in axes:  # tick labels without mathtext: a third of the time to save
            log_scale(ax, "x")
        nyquist = sorted({np.pi / G.dt for G in systems.values() if G.isdtime(strict=True)
                          and G.dt is not True})
        at_edge = [w for w in nyquist if abs(w - omega[-1]) <= 1e-9 * w]
        for ax in axes:
            for w in nyquist:
                if omega[0] < w < omega[-1] and w not in at_edge:
                    ax.axvline(w, color="0.35", linestyle="--", linewidth=1.2,
                               label=f"Nyquist frequency {w:.3g} rad/s")
            for low, high, label in bands:
                ax.axvspan(low, high, color="0.85", zorder=0, label=label)
        for value, label in lines:
            axes[0].axhline(20 * np.log10(value), color="k", linestyle=":", linewidth=1.4,
                            label=label)
        axes[0].set_ylabel(ylabel)
        if len(axes) > 1:
            axes[1].set_ylabel("phase [deg]")
        axes[-1].set_xlabel("frequency [rad/s]" + (
            f", up to the Nyquist frequency {at_edge[0]:.3g} rad/s" if at_edge else ""))
        axes[-1].set_xlim(omega[0], omega[-1])
        if title:
            axes[0].set_title(title)
        legend_outside(fig, ncols=2)
    return fig


def _default_omega(systems):
    poles = np.concatenate([np.abs(np.log(np.abs(G.poles()) + 1e-300)) / G.dt
                            if G.isdtime(strict=True) else np.abs(G.poles())
                            for G in systems] + [np.zeros(0)])
    poles = poles[poles > 0]
    low = 1e-3 * poles.min() if poles.size else 1e-3
    discrete = [G.dt for G in systems if G.isdtime(strict=True) and G.dt is not True]
    high = np.pi / min(discrete) if discrete else 1e3 * (poles.max() if poles.size else 1.0)
    return np.logspace(np.log10(low), np.log10(high), 400)
