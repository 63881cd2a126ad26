"""The blocks the editor can add, each with the Python that builds it.

Every entry builds its block from keyword arguments (``kwargs``) and writes
the same call as source code, so that :meth:`DiagramModel.code` shows what a
student would type and a saved diagram can be rebuilt. Numbers among the
keyword arguments are the block's parameters (sliders in the editor); the
sampling period ``Ts`` is the diagram's and is not offered as a slider.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import control as ct
import numpy as np

#: Import lines that the written code needs, by the alias it uses.
IMPORTS = {
    "ct": "import control as ct",
    "np": "import numpy as np",
    "sc": "from controlkit.blocks import spacecraft as sc",
    "mec": "from controlkit.blocks import mec",
    "frit": "from controlkit.blocks import frit",
    "cmg": "from controlkit.blocks import cmg",
    "common": "from controlkit.blocks import common",
    "sample_nlsys": "from controlkit.blocks.sampling import sample_nlsys",
}


def _literal(value):
    """Python source for a keyword value (numbers as they print, lists as lists).

    Examples
    --------
    >>> _literal(0.1), _literal([1.0, 2.0]), _literal("mu_n"), _literal(np.float64(2.0))
    ('0.1', '[1.0, 2.0]', "'mu_n'", '2.0')
    """
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_literal(v) for v in value) + "]"
    return repr(value)


def _args(kwargs):
    return ", ".join(f"{k}={_literal(v)}" for k, v in kwargs.items())


@dataclass(frozen=True)
class PaletteEntry:
    """One block the editor can add.

    Attributes
    ----------
    key : str
        Identifier (stored in saved diagrams).
    title : str
        What the palette shows.
    group : str
        ``"python-control"`` or ``"controlkit"``.
    name : str
        Default block name (made unique with a number when taken).
    defaults : dict
        Keyword arguments of a new block; ``Ts`` is filled with the diagram's period.
    expression : str
        The call, as a format string over ``{args}`` (the keyword arguments written out)
        and the keywords themselves.
    needs : tuple of str
        Aliases of :data:`IMPORTS` that the expression uses.
    sampled : bool
        A continuous block that joins a discrete diagram under zero-order hold.
    """

    key: str
    title: str
    group: str
    name: str
    defaults: dict = field(default_factory=dict)
    expression: str = ""
    needs: tuple = ("ct",)
    sampled: bool = False
    lti: bool = False

    def parameters(self, kwargs):
        """The numeric keyword arguments, which the editor shows as sliders."""
        return {k: v for k, v in kwargs.items() if k != "Ts" and _is_number(v)}

    def source(self, name, kwargs, Ts):
        """Python source of the call that builds this block named ``name``."""
        if self.key == "summing_junction":
            signs = kwargs.get("signs", "+-")
            inputs = [f"{'-' if s == '-' else ''}u{i + 1}" for i, s in enumerate(signs)]
            return f"ct.summing_junction(inputs={inputs!r}, output='y', name={name!r})"
        if self.key == "saturation":
            limit = _literal(kwargs["limit"])
            return (f"ct.nlsys(None, lambda t, x, u, params: np.clip(u, -{limit}, {limit}), "
                    f"inputs='u', outputs='y', dt=None, name={name!r})")
        literal = {k: _literal(v) for k, v in kwargs.items()}
        if self.lti:
            core = self.expression.format(**literal)
            if Ts:  # a discrete diagram: the continuous design under zero-order hold
                return (f"ct.sample_system({core}, {_literal(Ts)}, inputs='u', outputs='y', "
                        f"name={name!r})")
            return f"ct.tf({core}, inputs='u', outputs='y', name={name!r})"
        call = self.expression.format(args=_args({**kwargs, "name": name}), name=repr(name),
                                      **literal)
        if self.sampled and Ts:  # a continuous plant joins a discrete diagram under ZOH
            return f"sample_nlsys({call}, {_literal(Ts)})"
        return call

    def imports(self, Ts):
        needs = set(self.needs)
        if self.sampled and Ts:
            needs.add("sample_nlsys")
        return needs


def _is_number(value):
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value,
                                                                                      bool)


_S = "ct.tf('s')"
ENTRIES = [
    PaletteEntry("gain", "gain", "python-control", "gain", {"k": 2.0},
                 "ct.tf({k}, 1, dt=None, inputs='u', outputs='y', name={name})"),
    PaletteEntry("transfer_function", "transfer function", "python-control", "tf",
                 {"num": [1.0], "den": [1.0, 1.0]}, "ct.tf({num}, {den})", lti=True),
    PaletteEntry("pi", "PI controller", "python-control", "pi",
                 {"kp": 1.0, "ki": 0.1}, "ct.tf([{kp}, {ki}], [1, 0])", lti=True),
    PaletteEntry("pid", "PID controller", "python-control", "pid",
                 {"kp": 1.0, "ki": 0.1, "kd": 0.1, "tf": 0.01},
                 "{kp} + {ki} / " + _S + " + {kd} * " + _S + " / ({tf} * " + _S + " + 1)",
                 lti=True),
    PaletteEntry("summing_junction", "summing junction", "python-control", "sum",
                 {"signs": "+-"}),
    PaletteEntry("saturation", "saturation", "python-control", "saturation",
                 {"limit": 1.0}, needs=("ct", "np")),
    PaletteEntry("spacecraft_plant", "spacecraft plant", "controlkit", "plant", {},
                 "sc.spacecraft_plant({args})", ("sc",), sampled=True),
    PaletteEntry("io_linearizer", "IO linearizer", "controlkit",
                 "linearizer", {}, "sc.io_linearizer({args})", ("sc",)),
    PaletteEntry("attitude_output", "attitude output h(q)", "controlkit", "output", {},
                 "sc.attitude_output({args})", ("sc",)),
    PaletteEntry("outer_controller", "outer controller F", "controlkit",
                 "controller", {"F": 0.0009, "output": "mu"},
                 "sc.outer_controller({args})", ("sc",)),
    PaletteEntry("nominal_model", "nominal model L_n", "controlkit", "nominal", {"Ts": 0.1},
                 "mec.nominal_model({args})", ("mec",)),
    PaletteEntry("mec_compensator", "MEC compensator", "controlkit", "mec",
                 {}, "mec.mec_compensator({args})", ("mec",)),
    PaletteEntry("constant_gain", "constant gain K", "controlkit", "gain", {"K": 0.1},
                 "mec.constant_gain({args})", ("mec",)),
    PaletteEntry("frit_tuner", "FRIT tuner", "controlkit", "tuner",
                 {"F": 0.0009, "Ts": 0.1}, "frit.frit_tuner({args})", ("frit",)),
    PaletteEntry("lowpass_filter", "low-pass filter", "controlkit", "lowpass",
                 {"tau": 10.0, "Ts": 0.1}, "common.lowpass_filter({args})", ("common",)),
    PaletteEntry("cmg_plant", "CMG plant", "controlkit", "cmg", {}, "cmg.cmg_plant({args})",
                 ("cmg",), sampled=True),
    PaletteEntry("adaptive_smc", "adaptive SMC", "controlkit", "smc", {"Ts": 0.001},
                 "cmg.adaptive_smc({args})", ("cmg",)),
    PaletteEntry("reference_generator", "CMG references", "controlkit", "reference", {},
                 "cmg.reference_generator({args})", ("cmg",)),
    PaletteEntry("torque_saturation", "CMG torque limits", "controlkit", "saturation",
                 {"T1_max": 0.6, "T2_max": 2.4}, "cmg.torque_saturation({args})", ("cmg",)),
]
PALETTE = {entry.key: entry for entry in ENTRIES}


def build(key, name, kwargs, Ts):
    """The block of palette entry ``key``, named ``name``, as its source code builds it.

    Parameters
    ----------
    key : str
        A key of :data:`PALETTE`.
    name : str
        Block name.
    kwargs : dict
        Keyword arguments (see the entry's ``defaults``).
    Ts : float or None
        The diagram's sampling period (None or 0: continuous).

    Returns
    -------
    control.InputOutputSystem

    Examples
    --------
    >>> build("pi", "pi", {"kp": 2.0, "ki": 1.0}, None).num[0][0].tolist()
    [2.0, 1.0]
    """
    if key not in PALETTE:
        raise ValueError(f"palette entry must be one of {sorted(PALETTE)}, got {key!r}")
    entry = PALETTE[key]
    source = entry.source(name, kwargs, Ts)
    namespace = {}
    for alias in entry.imports(Ts):
        exec(IMPORTS[alias], namespace)  # noqa: S102 - our own import lines
    return eval(source, namespace)  # noqa: S307 - source written by PaletteEntry.source


def defaults(key, Ts):
    """A new block's keyword arguments: the entry's defaults with the diagram's ``Ts``."""
    kwargs = dict(PALETTE[key].defaults)
    if "Ts" in kwargs and Ts:
        kwargs["Ts"] = float(Ts)
    return kwargs


def recognise(block):
    """A recipe for a block of an opened diagram whose factory arguments can be read back.

    ``outer_controller`` keeps ``F`` and ``constant_gain`` keeps ``K`` as attributes; a
    block recognised here gets sliders and is written in :meth:`DiagramModel.code` as
    the factory call. Others return None.

    Examples
    --------
    >>> from controlkit.blocks import spacecraft as sc
    >>> recognise(sc.outer_controller(0.002, output="mu_n"))["kwargs"]
    {'F': 0.002, 'output': 'mu_n'}
    """
    labels = list(block.input_labels)
    F = getattr(block, "F", None)
    if (F is not None and getattr(block, "kernels", None) is not None
            and labels == ["r[0]", "r[1]", "h[0]", "h[1]"]):
        F = np.asarray(F, dtype=float).reshape(-1)
        outputs = block.output_labels
        base = outputs[0][:-3] if outputs[0].endswith("[0]") else None
        if F.size == 2 and F[0] == F[1] and base and outputs == [f"{base}[0]", f"{base}[1]"]:
            return {"kind": "outer_controller", "kwargs": {"F": float(F[0]), "output": base}}
    K = getattr(block, "K", None)
    if K is not None and getattr(block, "kernels", None) is not None and not labels:
        K = np.asarray(K, dtype=float)
        if K.shape == (2, 2) and np.array_equal(K, K[0, 0] * np.eye(2)):
            return {"kind": "constant_gain", "kwargs": {"K": float(K[0, 0])}}
    return None


def is_system(value):
    """Whether ``value`` is a block the editor can hold (any python-control I/O system)."""
    return isinstance(value, ct.InputOutputSystem)
