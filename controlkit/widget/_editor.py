"""``DiagramEditor``: the notebook widget (an ``anywidget``) around a :class:`DiagramModel`."""

from __future__ import annotations

import io
import traceback
from pathlib import Path

import anywidget
import traitlets

from . import _run, _schema, _view
from ._history import History
from ._model import DiagramModel

STATIC = Path(__file__).parent / "static"


class DiagramEditor(anywidget.AnyWidget):
    """Edit any python-control interconnect as a block diagram, in the notebook.

    The editor opens on ``sys`` drawn as
    :func:`~controlkit.drawing.draw_block_diagram` draws it (display names,
    junction signs, frames, rates). Blocks are moved, deleted and added (from a
    palette of python-control and controlkit blocks, or any system the notebook
    holds, by variable name); signals are connected and disconnected by
    dragging between ports; external inputs are driven by sources (step, ramp,
    sine, pulse, constant) set in the page, as are initial states and the horizon.
    Every edit can be undone (Ctrl+Z) and redone (Ctrl+Shift+Z); blocks are copied
    and pasted (Ctrl+C, Ctrl+V); the diagram is saved and loaded as a file (the
    schema of :mod:`controlkit.widget._schema`). Wrong wiring (an unconnected input,
    two drivers on one signal, an algebraic loop, timebases the engine refuses) is
    listed at once, naming the blocks. *Run* simulates the diagram and draws the
    chosen signals and measures; a selected block's parameters are on sliders.

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
    download = traitlets.Dict().tag(sync=True)  # a saved file for the page to hand over
    can_undo = traitlets.Bool(False).tag(sync=True)
    can_redo = traitlets.Bool(False).tag(sync=True)

    def __init__(self, sys, *, horizon=None, initial=None, inputs=None, scopes=None,
                 namespace=None, height=620, source_name=None, **kwargs):
        super().__init__(**kwargs)
        self._namespace = namespace
        self.history = History()
        self._opened = {}  # blocks of the opened diagram: what a loaded file may refer to
        if isinstance(sys, DiagramModel):
            self.model = sys
        else:
            self._opened = {s.name: s for s in sys.syslist}
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
        """Write the diagram (with block positions and the run's setup) as JSON to ``path``.

        The file is written whole or not at all (a temporary file, then renamed).
        """
        path = Path(path)
        partial = path.with_name(f".{path.name}.partial")
        try:
            partial.write_text(self.model.to_json(), encoding="utf-8")
            partial.replace(path)
        finally:
            partial.unlink(missing_ok=True)

    def open_text(self, text):
        """Replace the diagram by the saved one in ``text`` (what *load* in the page does).

        The file is read by the schema; a block it cannot rebuild is taken from the
        diagram the editor was opened on, or the notebook's variables. Undoable.
        """
        model = DiagramModel.from_json(text, systems=self._opened, namespace=self.namespace())
        self._edit(lambda: self._replace_model(model))

    def _replace_model(self, model):
        for name in ("name", "blocks", "wires", "inputs", "outputs", "summed", "hints",
                     "horizon", "sources", "initial", "source_name"):
            setattr(self.model, name, getattr(model, name))
        self.horizon = self.model.horizon

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

    def _edit(self, change):
        """``change()`` as one edit that can be undone; the page is redrawn after it."""
        self.history.record(self.model)
        try:
            result = change()
        except Exception:
            self.history.forget(self.model)
            raise
        self._refresh()
        return result

    def undo(self):
        """Undo the last edit (Ctrl+Z in the page); False when there is none."""
        done = self.history.undo(self.model)
        self.horizon = self.model.horizon
        self._refresh()
        return done

    def redo(self):
        """Redo the edit undone last (Ctrl+Shift+Z in the page); False when there is none."""
        done = self.history.redo(self.model)
        self.horizon = self.model.horizon
        self._refresh()
        return done

    def connect(self, src_block, src_port, dst_block, dst_port):
        """Wire an output port to an input port (as dragging between them does)."""
        self._edit(lambda: self.model.connect(src_block, src_port, dst_block, dst_port))

    def disconnect(self, src_block, src_port, dst_block, dst_port):
        """Remove the wires between two ports."""
        self._edit(lambda: self.model.disconnect(src_block, src_port, dst_block, dst_port))

    def delete_block(self, name):
        """Remove a block and its wires (its external inputs stay, unattached)."""
        self._edit(lambda: self.model.delete_block(name))

    def paste(self, names):
        """Copies of blocks ``names`` (Ctrl+C, Ctrl+V in the page), beside the originals
        where they overlap nothing; returns the new names."""
        return self._edit(lambda: self._paste(names))

    def _paste(self, names):
        new = self.model.paste(names)
        _view.place(self.model)
        for name in new:
            block = self.model.blocks[name]
            block.position = _view.free_spot(self.model, name, block.position)
        return new

    def relayout(self):
        """Place every block again as the static drawing places it."""
        self._edit(lambda: _view.relayout(self.model))

    def set_source(self, name, kind="constant", **fields):
        """Drive external input ``name`` by a source (see :meth:`DiagramModel.set_source`)."""
        self._edit(lambda: self.model.set_source(name, kind, **fields))

    def set_initial(self, block, values):
        """The initial state of ``block`` (None: its own)."""
        self._edit(lambda: self.model.set_initial(block, values))

    def add_block(self, key_or_variable, *, position=None, **kwargs):
        """Add a palette block (a key of ``controlkit.widget.PALETTE``) or a notebook variable.

        It goes at ``position`` (pixels), or where the drawing would put it, moved to
        the nearest spot that overlaps no other block. Returns the new block's name.
        """
        return self._edit(lambda: self._add(key_or_variable, position, kwargs))

    def _add(self, key_or_variable, position, kwargs):
        if key_or_variable in _view._palette.PALETTE:
            name = self.model.add_from_palette(key_or_variable, position=position, **kwargs)
        else:
            namespace = self.namespace()
            if key_or_variable not in namespace:
                raise ValueError(f"{key_or_variable!r} is neither a palette entry nor a "
                                 f"variable of the notebook")
            name = self.model.add_variable(key_or_variable, namespace[key_or_variable],
                                           position=position)
        _view.place(self.model)
        if position is not None:
            block = self.model.blocks[name]
            block.position = _view.free_spot(self.model, name, block.position)
        return name

    def set_parameter(self, block, parameter, value):
        """Change a block's parameter (rebuilds the block; its wires stay)."""
        self._edit(lambda: self.model.set_parameter(block, parameter, value))

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
        self.can_undo, self.can_redo = bool(self.history.done), bool(self.history.undone)
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
        undoable = op not in _NOT_EDITS and handler is not None
        try:
            if handler is None:
                raise ValueError(f"unknown operation {op!r}")
            if undoable:
                self.history.record(self.model)
            try:
                quiet = handler(content) is _QUIET
            except Exception:
                if undoable:
                    self.history.forget(self.model)
                raise
            if quiet:
                self.can_undo = bool(self.history.done)
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
            self._add(key.removeprefix("var:"), position, {})

    def _op_paste(self, content):
        self._paste([n for n in content["blocks"] if n in self.model.blocks])

    def _op_relayout(self, content):
        _view.relayout(self.model)

    def _op_undo(self, content):
        if not self.history.undo(self.model):
            self.status = "nothing to undo"
            return _QUIET
        self.horizon = self.model.horizon

    def _op_redo(self, content):
        if not self.history.redo(self.model):
            self.status = "nothing to redo"
            return _QUIET
        self.horizon = self.model.horizon

    def _op_save(self, content):
        name = "".join(c if c.isalnum() or c in "-_" else "_" for c in self.model.name)
        self.download = {"name": f"{name or 'diagram'}.json", "text": self.model.to_json(),
                         "serial": self.download.get("serial", 0) + 1}
        self.status = f"saved {name or 'diagram'}.json"
        return _QUIET

    def _op_load(self, content):
        model = DiagramModel.from_json(content["text"], systems=self._opened,
                                       namespace=self.namespace())
        self._replace_model(model)

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
#: Operations that change no diagram (no entry in the undo history).
_NOT_EDITS = {"scopes", "run", "refresh", "undo", "redo", "save"}
