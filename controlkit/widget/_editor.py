"""``DiagramEditor``: the notebook widget (an ``anywidget``) around a :class:`DiagramModel`."""

from __future__ import annotations

import io
import traceback
from pathlib import Path

import anywidget
import traitlets

from . import _run, _schema, _view
from ._model import DiagramModel

STATIC = Path(__file__).parent / "static"


class DiagramEditor(anywidget.AnyWidget):
    """Edit any python-control interconnect as a block diagram, in the notebook.

    The editor opens on ``sys`` drawn as
    :func:`~controlkit.drawing.draw_block_diagram` draws it (display names,
    junction signs, frames, rates). Blocks are moved, deleted and added (from a
    palette of python-control and controlkit blocks, or any system the notebook
    holds, by variable name); signals are connected and disconnected by
    dragging between ports. Wrong wiring (an unconnected input, two drivers on
    one signal, an algebraic loop, mismatched timebases) is listed at once,
    naming the blocks. *Run* simulates the diagram and draws the chosen
    signals and measures; a selected block's parameters are on sliders.

    Parameters
    ----------
    sys : control.InterconnectedSystem or DiagramModel
        The diagram to open.
    horizon : float, optional
        Simulated time of a run (s); default the saved diagram's, else 10 s.
    initial : dict, optional
        Initial states by block name (default each block's ``x0``, else zero).
    inputs : dict, optional
        What drives each external input, by name: a number (a constant) or a source
        ``{"kind": "step", "value": 1.0, "time": 1.0}`` (kinds ``constant``, ``step``,
        ``ramp``, ``sine``, ``pulse``; see :meth:`DiagramModel.set_source`). Default 0.
    scopes : list of str, optional
        Signals drawn after a run, as ``"block.signal"``.
    namespace : dict, optional
        The notebook's variables, offered in the palette and used by
        :meth:`code`; default the IPython user namespace when there is one.
    height : int
        Height of the widget in pixels.

    Attributes
    ----------
    model : DiagramModel
        The diagram being edited.

    Examples
    --------
    >>> from controlkit.studies.spacecraft.diagrams import mec_loop
    >>> editor = DiagramEditor(mec_loop(K=0.1), horizon=100.0)
    >>> editor.delete_block("mec")
    >>> editor.connect("controller", "mu_n", "linearizer", "mu")
    >>> [p.kind for p in editor.model.problems() if p.severity != "note"]
    []
    """

    _esm = STATIC / "editor.js"
    _css = STATIC / "editor.css"

    diagram = traitlets.Dict().tag(sync=True)
    problems = traitlets.List().tag(sync=True)
    variables = traitlets.List().tag(sync=True)
    results = traitlets.Dict().tag(sync=True)
    status = traitlets.Unicode("").tag(sync=True)
    horizon = traitlets.Float(100.0).tag(sync=True)
    scopes = traitlets.List().tag(sync=True)
    height = traitlets.Int(620).tag(sync=True)
    code_text = traitlets.Unicode("").tag(sync=True)

    def __init__(self, sys, *, horizon=None, initial=None, inputs=None, scopes=None,
                 namespace=None, height=620, source_name=None, **kwargs):
        super().__init__(**kwargs)
        self._namespace = namespace
        if isinstance(sys, DiagramModel):
            self.model = sys
        else:
            if source_name is None:
                source_name = next((k for k, v in self.namespace().items()
                                    if v is sys and not k.startswith("_")), None)
            self.model = DiagramModel.from_interconnect(sys, source_name=source_name)
        for name, values in (initial or {}).items():
            self.model.set_initial(name, values)
        for name, value in (inputs or {}).items():
            if isinstance(value, dict):
                self.model.set_source(name, **value)
            else:
                self.model.set_source(name, "constant", value=float(value))
        if horizon is not None:
            self.model.set_horizon(horizon)
        self.measures = []
        self.last_response = None
        self.horizon = self.model.horizon
        self.height = int(height)
        self.scopes = list(scopes) if scopes is not None else self._default_scopes()
        self.on_msg(self._on_message)
        self._refresh(layout=True)

    # ------------------------------------------------------------------ python API

    @property
    def system(self):
        """The edited diagram as a ``control.interconnect`` object."""
        return self.model.system()

    def code(self, variable=None):
        """The Python that builds :attr:`system` (see :meth:`DiagramModel.code`)."""
        return self.model.code(variable)

    def save(self, path):
        """Write the diagram (with block positions) as JSON to ``path``."""
        self.model.to_json(path)

    @classmethod
    def load(cls, path, *, systems=None, namespace=None, **kwargs):
        """An editor on a diagram saved by :meth:`save`.

        ``systems`` gives the blocks that were taken from an opened diagram (that
        diagram, or ``{name: system}``); ``namespace`` the notebook's variables.
        """
        path = Path(path)
        if path.stat().st_size > _schema.LIMITS["bytes"]:
            raise ValueError(f"{path} is not a saved diagram: larger than "
                             f"{_schema.LIMITS['bytes']:,} bytes")
        model = DiagramModel.from_json(path.read_text(encoding="utf-8"), systems=systems,
                                       namespace=namespace)
        return cls(model, namespace=namespace, **kwargs)

    def connect(self, src_block, src_port, dst_block, dst_port):
        """Wire an output port to an input port (as dragging between them does)."""
        self.model.connect(src_block, src_port, dst_block, dst_port)
        self._refresh()

    def disconnect(self, src_block, src_port, dst_block, dst_port):
        """Remove the wires between two ports."""
        self.model.disconnect(src_block, src_port, dst_block, dst_port)
        self._refresh()

    def delete_block(self, name):
        """Remove a block and its wires."""
        self.model.delete_block(name)
        self._refresh()

    def add_block(self, key_or_variable, *, position=None, **kwargs):
        """Add a palette block (a key of ``controlkit.widget.PALETTE``) or a notebook variable.

        Returns the new block's name.
        """
        if key_or_variable in _view._palette.PALETTE:
            name = self.model.add_from_palette(key_or_variable, position=position, **kwargs)
        else:
            namespace = self.namespace()
            if key_or_variable not in namespace:
                raise ValueError(f"{key_or_variable!r} is neither a palette entry nor a "
                                 f"variable of the notebook")
            name = self.model.add_variable(key_or_variable, namespace[key_or_variable],
                                           position=position)
        if position is None:
            xs = [b.position for b in self.model.blocks.values() if b.position]
            low = max((p[1] for p in xs), default=0.0)
            self.model.blocks[name].position = (min((p[0] for p in xs), default=0.0),
                                                low + 140.0)
        self._refresh()
        return name

    def set_parameter(self, block, parameter, value):
        """Change a block's parameter (rebuilds the block; its wires stay)."""
        self.model.set_parameter(block, parameter, value)
        self._refresh()

    def add_measure(self, name, signals, function, *, unit="", limit=None, over="last half",
                    log=False):
        """Show ``function(signals)`` after each run, with its worst value against ``limit``.

        Parameters
        ----------
        name : str
            What the scope and the summary call it.
        signals : list of str
            Inputs of ``function``, as ``"block.signal"``.
        function : callable
            ``function(values)`` with ``values`` of shape ``(len(signals), N)``, returning
            ``N`` values.
        unit : str
            Unit printed after the numbers.
        limit : float, optional
            The requirement: the largest absolute value over ``over`` must not exceed it.
        over : {"last half", "all"}
            Which part of the run the summary judges.
        log : bool
            Draw on a logarithmic axis.
        """
        if over not in ("last half", "all"):
            raise ValueError(f'over must be "last half" or "all", got {over!r}')
        self.measures.append(_run.Measure(name, list(signals), function, unit,
                                          None if limit is None else float(limit), over, log))

    def run(self):
        """Simulate the diagram as the *Run* button does; returns the scopes' data.

        The run itself (every sample, all block outputs as ``"block.signal"``) is kept as
        :attr:`last_response`.
        """
        self.model.set_horizon(self.horizon)
        results, self.last_response = _run.run_diagram(self.model, measures=self.measures,
                                                       scopes=self.scopes)
        self.status = (f"ran {results['steps']:,} steps in {results['seconds']:.2f} s"
                       + ("" if not results["warnings"] else
                          " - " + "; ".join(results["warnings"])))
        self.results = results  # after the status: the page shows both once this arrives
        return results

    def namespace(self):
        """The notebook's variables (the IPython user namespace, or the one given)."""
        if self._namespace is not None:
            return self._namespace
        try:
            from IPython import get_ipython
        except ImportError:
            return {}
        shell = get_ipython()
        return shell.user_ns if shell is not None else {}

    # ------------------------------------------------------------------ display

    def _repr_mimebundle_(self, **kwargs):
        """The live widget, and the drawing as SVG for pages shown without a kernel."""
        bundle = super()._repr_mimebundle_(**kwargs)
        data = bundle[0] if isinstance(bundle, tuple) else bundle
        try:
            data["image/svg+xml"] = self.static_svg()
        except Exception:  # noqa: BLE001 - the live widget still shows
            pass
        return bundle

    def static_svg(self):
        """The diagram drawn by :func:`~controlkit.drawing.draw_block_diagram`, as SVG text."""
        import matplotlib as mpl
        import matplotlib.pyplot as plt

        from controlkit.drawing import draw_block_diagram

        fig = draw_block_diagram(self.system)
        buffer = io.StringIO()
        with mpl.rc_context({"svg.fonttype": "none"}):
            fig.savefig(buffer, format="svg")
        plt.close(fig)
        return buffer.getvalue()

    # ------------------------------------------------------------------ front end

    def _default_scopes(self):
        for _, sources in self.model.outputs:
            side, block, signal, _ = sources[0]
            if side == "out":
                port = next(p for p in self.model.ports(block, "out") if signal in p[1])
                return [f"{block}.{s}" for s in port[1]]
        return []

    def _refresh(self, layout=False):
        _view.place(self.model)
        self.diagram = _view.view(self.model)
        self.problems = [p.as_dict() for p in self.model.problems()]
        self.variables = sorted(k for k, v in self.namespace().items()
                                if not k.startswith("_") and _view._palette.is_system(v))
        try:
            self.code_text = self.model.code()
        except Exception as error:  # noqa: BLE001 - shown in the widget
            self.code_text = f"# the code cannot be written yet: {error}"

    def _on_message(self, _widget, content, _buffers):
        """Apply one message of the front end (``{"op": ..., ...}``) and redraw."""
        op = content.get("op")
        handler = getattr(self, f"_op_{op}", None) if isinstance(op, str) else None
        try:
            if handler is None:
                raise ValueError(f"unknown operation {op!r}")
            if handler(content) is _QUIET:
                return
            self.status = ""
        except Exception as error:  # noqa: BLE001 - every mistake is shown in the widget
            self.status = f"{type(error).__name__}: {error}"
            if not isinstance(error, ValueError):
                self.status += "\n" + traceback.format_exc(limit=3)
        self._refresh()

    # one method per operation of the front end; _QUIET: nothing to redraw

    def _op_move(self, content):
        for name, (x, y) in content["positions"].items():
            if name in self.model.blocks:
                self.model.blocks[name].position = (float(x), float(y))
        return _QUIET

    def _op_connect(self, content):
        self.model.connect(*content["source"], *content["target"])

    def _op_disconnect(self, content):
        for edge in content["edges"]:
            self.model.disconnect(*edge)

    def _op_delete(self, content):
        for name in content["blocks"]:
            self.model.delete_block(name)

    def _op_add(self, content):  # a palette key, or "var:<name>" for a notebook variable
        key, position = content["key"], tuple(content["position"])
        if key.startswith("var:") and key[4:] in _view._palette.PALETTE:
            key = key[4:]  # a variable named like a palette entry
            self.model.add_variable(key, self.namespace()[key], position=position)
        else:
            self.add_block(key.removeprefix("var:"), position=position)

    def _op_set_parameter(self, content):
        self.model.set_parameter(content["block"], content["name"], content["value"])

    def _op_add_input(self, content):
        target = content.get("target") or (None, None)
        self.model.add_input(content["name"], *target)

    def _op_connect_input(self, content):
        self.model.connect_input(content["input"], *content["target"])

    def _op_disconnect_input(self, content):
        self.model.disconnect_input(content["input"], *content["target"])

    def _op_remove_input(self, content):
        self.model.remove_input(content["input"])

    def _op_set_source(self, content):
        fields = {k: float(v) for k, v in (content.get("fields") or {}).items()}
        for name in self.model.input_names(content["input"]):
            self.model.set_source(name, content["kind"], **fields)

    def _op_set_initial(self, content):
        self.model.set_initial(content["block"], content.get("values"))

    def _op_horizon(self, content):
        self.model.set_horizon(float(content["value"]))
        self.horizon = self.model.horizon

    def _op_scopes(self, content):
        self.scopes = list(content["signals"])
        return _QUIET

    def _op_run(self, content):
        if "horizon" in content:
            self._op_horizon({"value": content["horizon"]})
        self.status = "running..."
        self.run()
        return _QUIET

    def _op_refresh(self, content):
        return None


_QUIET = object()
