"""Model error compensator (MEC): ideal model, compensator and gain (spacecraft paper, eq. 13-16).

The MEC (Fig. 3) compares the actual output ``h`` with the output ``hn`` of
an ideal model driven by the outer controller, and adds ``K (hn - h)`` at
the virtual input. The gain source is a block of its own, so the same
compensator takes a constant gain (:func:`constant_gain`, Fig. 3) or the
on-line FRIT tuner (:func:`controlkit.blocks.frit.frit_tuner`, Fig. 4): swapping one block swaps
the method. Errata E1-E3 of the project spec apply (see each docstring).
"""

from __future__ import annotations

import control as ct

from .. import _checks
from ..kernels import common
from ..kernels import mec as kernels
from ..kernels.mec import MEC_INPUTS
from .contract import KernelBlock, drawn_as
from .spacecraft import TS_PAPER

K_SIGNALS = [f"K[{i}]" for i in range(4)]  # the gain signal, row-major


def nominal_model(Ts=TS_PAPER, *, h0=(0.0, 0.0), name="nominal") -> ct.NonlinearIOSystem:
    """Ideal linearized model ``L_n`` of Fig. 3-4: ``hn' = mu_n``, exact under ZOH at ``Ts``.

    ``L_n`` is what eq. (10)-(11) make of the plant when the model is exact; the
    MEC (eq. 13-14) compares its output ``hn`` with the actual ``h``.

    ``hn[k+1] = hn[k] + Ts mu_n[k]`` (the ZOH discretisation of an integrator
    is exact). Driven by the outer controller's ``mu_n``, not by the
    compensated ``mu`` (erratum E3, after Okajima et al. 2013).

    Parameters
    ----------
    Ts : float
        Sampling period (s), > 0.
    h0 : array_like
        Initial nominal output; the paper's loop starts with ``hn(0) = h(0)``.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Discrete. Inputs ``mu_n[0], mu_n[1]``; states and outputs ``hn[0], hn[1]``;
        attribute ``x0`` (= ``h0``).

    Examples
    --------
    >>> nominal_model(0.1).dynamics(0.0, [1.0, 2.0], [0.5, -1.0]).tolist()
    [1.05, 1.9]
    """
    Ts = _checks.positive_scalar("Ts", Ts)
    h0 = _checks.vector("h0", h0, 2)
    sys = KernelBlock(common.state_output, common.integrator_update,
                       params=common.INTEGRATOR.pack(Ts=Ts),
                       feedthrough=False, inputs=["mu_n[0]", "mu_n[1]"],
                       outputs=["hn[0]", "hn[1]"], states=["hn[0]", "hn[1]"], dt=Ts, name=name)
    sys.x0 = h0
    return drawn_as(sys, "$L_n$", default_name="nominal")


def mec_compensator(*, name="mec") -> ct.NonlinearIOSystem:
    """Model error compensator, ``mu = mu_n + K (hn - h)`` (eq. 13-15).

    ``K`` (2x2) arrives as the signal ``K[0..3]`` (row-major: K11, K12, K21, K22)
    from a gain source: :func:`constant_gain` (Fig. 3) or :func:`frit_tuner` (Fig. 4).

    Returns
    -------
    control.NonlinearIOSystem
        Static. Inputs ``mu_n[0], mu_n[1], hn[0], hn[1], h[0], h[1], K[0]..K[3]``;
        outputs ``mu[0], mu[1]``.

    Examples
    --------
    >>> mec = mec_compensator()
    >>> mec.output(0.0, [], [1, 1, 0.5, 0, 0, 0, 2, 0, 0, 2]).tolist()
    [2.0, 1.0]
    """
    sys = KernelBlock(kernels.mec_output, inputs=MEC_INPUTS.labels(),
                      outputs=["mu[0]", "mu[1]"], dt=None, name=name)
    return drawn_as(sys, r"$\mu_n + K\,(h_n - h)$", default_name="mec")


def constant_gain(K=0.1, *, name="gain") -> ct.NonlinearIOSystem:
    """Constant compensation gain ``K`` of eq. (13) as a source block (Fig. 3).

    Parameters
    ----------
    K : float or array_like
        Scalar (times the identity) or 2x2 matrix. Default ``0.1 I``.
    name : str
        System name.

    Returns
    -------
    control.NonlinearIOSystem
        Static, no inputs; outputs ``K[0]..K[3]`` (row-major); attribute ``K``.

    Examples
    --------
    >>> constant_gain([[1, 2], [3, 4]]).output(0.0, [], []).tolist()
    [1.0, 2.0, 3.0, 4.0]
    """
    K = _checks.gain_matrix("K", K)
    sys = KernelBlock(common.constant_output, params=K.ravel(), feedthrough=False, inputs=0,
                       outputs=K_SIGNALS, dt=None, name=name)
    sys.K = K
    return drawn_as(sys, "$K$", default_name="gain")
