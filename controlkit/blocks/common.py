"""Generic blocks that serve any diagram: filters and other signal conditioning."""

from __future__ import annotations

import control as ct
import numpy as np

from .. import _checks
from ..kernels import common
from .contract import KernelBlock


def lowpass_filter(tau, Ts, *, input="v", output="mu", size=2, y0=0.0,
                   name="lowpass") -> ct.NonlinearIOSystem:
    """First-order low-pass filter ``tau y' = u - y`` per channel, exact under ZOH at ``Ts``.

    ``y[k+1] = a y[k] + (1 - a) u[k]`` with ``a = exp(-Ts / tau)``: the
    discretisation is exact for an input held over each sample. The output is
    the state, so the block has no feedthrough: inserted in a loop it delays
    the signal by one sample and adds no algebraic loop.

    Parameters
    ----------
    tau : float
        Time constant (s), > 0.
    Ts : float
        Sampling period (s), > 0.
    input, output : str
        Base names of the input and output signals (``v[0], v[1]`` -> ``mu[0], mu[1]``).
    size : int
        Number of channels, >= 1.
    y0 : float or array_like
        Initial output (the filter's state), one value or one per channel.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Discrete at ``Ts``. Inputs ``<input>[i]``; states and outputs
        ``<output>[i]``; attributes ``x0`` (= ``y0``) and ``tau``.

    Examples
    --------
    >>> lp = lowpass_filter(tau=1.0, Ts=0.1)
    >>> lp.input_labels, lp.output_labels
    (['v[0]', 'v[1]'], ['mu[0]', 'mu[1]'])
    >>> lp.dynamics(0.0, [0.0, 1.0], [1.0, 1.0]).round(6).tolist()  # 1 - exp(-0.1)
    [0.095163, 1.0]
    """
    tau = _checks.positive_scalar("tau", tau)
    Ts = _checks.positive_scalar("Ts", Ts)
    if int(size) != size or size < 1:
        raise ValueError(f"size must be a positive integer (the number of channels), got {size!r}")
    size = int(size)
    y0 = np.broadcast_to(_checks.float_array("y0", y0), (size,)) if np.ndim(y0) == 0 else y0
    y0 = _checks.vector("y0", y0, size)
    signals = [f"{output}[{i}]" for i in range(size)]
    sys = KernelBlock(common.state_output, common.lowpass_update,
                       params=common.LOWPASS.pack(a=np.exp(-Ts / tau)), feedthrough=False,
                       inputs=[f"{input}[{i}]" for i in range(size)], outputs=signals,
                       states=signals, dt=Ts, name=name)
    sys.x0, sys.tau = y0.copy(), tau
    return sys
