// controlkit.widget.DiagramEditor's front end: an anywidget module drawing the diagram with
// React Flow. Python holds the diagram; every edit is sent to it as a message ({op: ...})
// and the redrawn diagram, the problems and the results come back as traits.
import React, { useCallback, useEffect, useMemo, useRef, useState } from "react";
import { createRoot } from "react-dom/client";
import {
  ReactFlow, ReactFlowProvider, Handle, Position, Controls, Background, applyNodeChanges,
  useReactFlow, useStore, BaseEdge, EdgeLabelRenderer,
} from "@xyflow/react";
import "@xyflow/react/dist/style.css";
import "./editor.css";
import { texToHtml } from "./tex.js";
import { JUNCTION_GAP, JUNCTION_R, freeSpot, pathOf, routeAll } from "./route.js";
import { Chart } from "./chart.jsx";

function useTrait(model, name) {
  const [value, setValue] = useState(() => model.get(name));
  useEffect(() => {
    const update = () => setValue(model.get(name));
    model.on(`change:${name}`, update);
    return () => model.off(`change:${name}`, update);
  }, [model, name]);
  return value;
}

const Tex = ({ text, className }) => (
  <span className={className} dangerouslySetInnerHTML={{ __html: texToHtml(text) }} />
);

const SIDE = { left: Position.Left, right: Position.Right, top: Position.Top,
  bottom: Position.Bottom };
const signChar = (s) => (s < 0 ? "\u2212" : "+");

// ------------------------------------------------------------------------------ nodes

function BlockNode({ data, selected }) {
  const b = data.block;
  const ins = b.inputs.filter((p) => !p.junction);
  const cls = ["ck-block", `ck-shape-${b.shape}`, selected ? "ck-selected" : "",
    data.bad ? "ck-bad" : "", data.warn ? "ck-warn" : "",
    data.mixed && b.discrete ? "ck-discrete" : ""].join(" ");
  const inSide = b.flip ? Position.Right : Position.Left;
  const outSide = b.flip ? Position.Left : Position.Right;
  const frac = (i, n) => `${(100 * (i + 1)) / (n + 1)}%`;
  return (
    <div className={cls} style={{ width: b.w, height: b.h }} data-block={b.name}
      title={`${b.name}: ${b.sub}`}>
      {b.shape === "gain" ? (
        <svg className="ck-triangle" width={b.w} height={b.h}>
          <polygon points={b.flip ? `${b.w},0 ${b.w},${b.h} 0,${b.h / 2}`
            : `0,0 0,${b.h} ${b.w},${b.h / 2}`} />
        </svg>
      ) : null}
      <div className={b.shape === "gain" ? "ck-gain-text" : "ck-block-text"}>
        {b.shape === "gain" && !b.math ? <b>{b.gain}</b> : <Tex text={b.label} className="ck-name" />}
        {b.shape !== "gain" && <div className="ck-sub">{b.sub}</div>}
      </div>
      {ins.map((p, i) => (
        <Handle key={`in${p.port}`} id={p.port} type="target" position={inSide}
          style={{ top: frac(i, ins.length) }}
          className={`ck-port ck-in ${data.loose && data.loose.has(p.port) ? "ck-loose" : ""}`}
          data-port={`${b.name}.${p.port}`}>
          <span className={`ck-port-label ${b.flip ? "ck-right" : ""}`}>
            {p.sign !== null && p.sign !== undefined ? signChar(p.sign) + " " : ""}{p.port}
          </span>
        </Handle>
      ))}
      {b.outputs.map((p, i) => (
        <Handle key={`out${p.port}`} id={p.port} type="source" position={outSide}
          style={{ top: frac(i, b.outputs.length) }} className="ck-port ck-out"
          data-port={`${b.name}.${p.port}`}>
          <span className={`ck-port-label ${b.flip ? "" : "ck-right"}`}>{p.port}</span>
        </Handle>
      ))}
    </div>
  );
}

function SumNode({ data, selected }) {
  const b = data.block;
  const r = b.w / 2;
  return (
    <div className={`ck-sum ${selected ? "ck-selected" : ""} ${data.bad ? "ck-bad" : ""}`}
      style={{ width: b.w, height: b.h }} data-block={b.name} title={`${b.name}: summing junction`}>
      {b.inputs.map((p) => (
        <Handle key={p.port} id={p.port} type="target" position={SIDE[p.side]}
          className="ck-port ck-in" data-port={`${b.name}.${p.port}`}>
          <span className={`ck-sign ck-sign-${p.side}`}>{signChar(p.sign)}</span>
        </Handle>
      ))}
      {b.outputs.map((p) => (
        <Handle key={p.port} id={p.port} type="source" position={Position.Right}
          className="ck-port ck-out" data-port={`${b.name}.${p.port}`} />
      ))}
      <div className="ck-sum-name" style={{ top: 2 * r + 2 }}>{b.name}</div>
    </div>
  );
}

function JunctionNode({ data }) {
  return (
    <div className="ck-junction" style={{ width: 2 * JUNCTION_R, height: 2 * JUNCTION_R }}>
      {data.ports.map((p, i) => {
        const side = ["left", "bottom", "top"][Math.min(i, 2)];
        return (
          <Handle key={p.port} id={p.port} type="target" position={SIDE[side]}
            className="ck-port ck-in" data-port={`${data.owner}.${p.port}`}>
            <span className={`ck-sign ck-sign-${side}`}>{signChar(p.sign)}</span>
          </Handle>
        );
      })}
    </div>
  );
}

// an external input: its source (what drives it) and its name; drag from its dot to a port
function TerminalNode({ data, selected }) {
  return (
    <div className={`ck-terminal ${selected ? "ck-terminal-selected" : ""}
      ${data.target ? "" : "ck-terminal-free"}`} style={{ width: data.w }}
      data-input={data.label} title={`external input ${data.label}: ${data.source}${
        data.target ? "" : " (drag from its dot to an input port)"}`}>
      <span className="ck-source">{data.source}</span> <Tex text={data.label} />
      <Handle id="out" type="source" position={Position.Right}
        className={`ck-port ck-out ${data.target ? "ck-hidden" : ""}`}
        data-port={`input.${data.label}`} />
    </div>
  );
}

function FrameNode({ data }) {
  return (
    <div className="ck-frame" style={{ width: data.w, height: data.h }}>
      <Tex text={data.label} className="ck-frame-label" />
    </div>
  );
}

const nodeTypes = { block: BlockNode, sum: SumNode, junction: JunctionNode,
  terminal: TerminalNode, frame: FrameNode };

// ------------------------------------------------------------------------------ edges

function WireEdge({ id, data, selected, markerEnd }) {
  const points = data.points;
  if (!points || points.length < 2) return null;
  const [sx, sy] = points[0];
  return (
    <>
      <BaseEdge id={id} path={pathOf(points)} markerEnd={markerEnd}
        className={`ck-wire ${selected ? "ck-wire-selected" : ""}`} interactionWidth={12} />
      <EdgeLabelRenderer>
        {data.showLabel && (
          <div className="ck-wire-label nodrag nopan" data-edge={id} style={{
            transform: `translate(${data.flip ? "-100%" : "0"}, -100%) translate(${sx + (data.flip ? -5 : 5)}px, ${sy - 2}px)` }}>
            <Tex text={data.label} />
          </div>
        )}
        {data.sign < 0 && !data.junctionSign && (
          <div className="ck-wire-sign" style={{ transform:
            `translate(-50%, -100%) translate(${points[points.length - 1][0] - 10}px, ${points[points.length - 1][1] - 2}px)` }}>
            {"\u2212"}</div>
        )}
      </EdgeLabelRenderer>
    </>
  );
}

const edgeTypes = { wire: WireEdge };

// ------------------------------------------------------------------------------ model -> nodes

function buildNodes(diagram, previous, badBlocks, warnBlocks) {
  const old = Object.fromEntries((previous || []).map((n) => [n.id, n]));
  const nodes = [];
  for (const g of diagram.groups) {
    nodes.push({ id: `frame:${g.label}`, type: "frame", position: { x: 0, y: 0 },
      data: { label: g.label, members: g.members, w: 10, h: 10 }, draggable: false,
      selectable: false, connectable: false, zIndex: -1 });
  }
  for (const b of diagram.blocks) {
    const type = b.shape === "sum" ? "sum" : "block";
    const prev = old[b.name];
    nodes.push({ id: b.name, type, position: { x: b.x - b.w / 2, y: b.y - b.h / 2 },
      data: { block: b, bad: badBlocks.has(b.name), warn: warnBlocks.has(b.name),
        mixed: diagram.mixed, loose: new Set(b.inputs.filter((p) => p.loose).map((p) => p.port)) },
      width: b.w, height: b.h, selected: prev ? prev.selected : false,
      ...(prev && prev.measured ? { measured: prev.measured } : {}) });
    const junctionPorts = b.inputs.filter((p) => p.junction);
    if (junctionPorts.length) {
      nodes.push({ id: `${b.name}::sum`, type: "junction", position: { x: 0, y: 0 },
        data: { owner: b.name, ports: junctionPorts }, draggable: false, selectable: false,
        width: 2 * JUNCTION_R, height: 2 * JUNCTION_R });
    }
  }
  for (const t of diagram.inputs) {
    const w = Math.max(24, 7.5 * t.label.length + 6.2 * t.source.length + 22);
    const prev = old[t.id];
    nodes.push({ id: t.id, type: "terminal", position: { x: 0, y: 0 },
      data: { label: t.label, target: t.target, port: t.port, w, source: t.source,
        groups: t.groups, names: t.names }, draggable: false,
      selectable: true, selected: prev ? prev.selected : false, width: w, height: 20 });
  }
  return follow(nodes);
}

// place the nodes that follow blocks: junctions, external inputs, frames
function follow(nodes) {
  const byId = Object.fromEntries(nodes.map((n) => [n.id, n]));
  const out = nodes.map((n) => {
    if (n.type === "junction") {
      const o = byId[n.data.owner];
      const b = o.data.block;
      const x = b.flip ? o.position.x + b.w + JUNCTION_GAP - JUNCTION_R
        : o.position.x - JUNCTION_GAP - JUNCTION_R;
      return { ...n, position: { x, y: o.position.y + b.h / 2 - JUNCTION_R } };
    }
    return n;
  });
  const byId2 = Object.fromEntries(out.map((n) => [n.id, n]));
  // inputs that drive nothing wait in a column left of the diagram
  const blocks = out.filter((n) => n.type === "block" || n.type === "sum");
  const left = blocks.length ? Math.min(...blocks.map((n) => n.position.x)) : 0;
  const top = blocks.length ? Math.min(...blocks.map((n) => n.position.y)) : 0;
  let free = 0;
  return out.map((n) => {
    if (n.type === "terminal" && !n.data.target) {
      const position = { x: left - 150 - n.data.w, y: top + 34 * free++ };
      return { ...n, position };
    }
    if (n.type === "terminal") {
      const o = byId2[n.data.target];
      if (!o) return n;
      const b = o.data.block;
      const jp = b.inputs.find((p) => p.port === n.data.port);
      let x, y;
      if (jp && jp.junction) {
        const j = byId2[`${b.name}::sum`];
        x = j.position.x - 50 - n.data.w;
        y = j.position.y + JUNCTION_R - 10;
      } else {
        const ins = b.inputs.filter((p) => !p.junction);
        const i = ins.findIndex((p) => p.port === n.data.port);
        x = o.position.x - 60 - n.data.w;
        y = o.position.y + (b.h * (i + 1)) / (ins.length + 1) - 10;
      }
      return { ...n, position: { x, y } };
    }
    if (n.type === "frame") {
      const members = n.data.members.map((m) => byId2[m]).filter(Boolean);
      if (!members.length) return { ...n, hidden: true };
      const x0 = Math.min(...members.map((m) => m.position.x)) - 16;
      const y0 = Math.min(...members.map((m) => m.position.y)) - 30;
      const x1 = Math.max(...members.map((m) => m.position.x + m.data.block.w)) + 16;
      const y1 = Math.max(...members.map((m) => m.position.y + m.data.block.h)) + 14;
      return { ...n, position: { x: x0, y: y0 }, width: x1 - x0, height: y1 - y0,
        data: { ...n.data, w: x1 - x0, h: y1 - y0 }, hidden: false };
    }
    return n;
  });
}

function buildEdges(diagram, nodes, selectedEdges) {
  const wires = diagram.edges.map((e) => ({ ...e }));
  const blockById = Object.fromEntries(diagram.blocks.map((b) => [b.name, b]));
  const junctionPort = (block, port) => {
    const b = blockById[block];
    const p = b && b.inputs.find((q) => q.port === port);
    return p && p.junction;
  };
  for (const t of diagram.inputs) {
    if (!t.target) continue;
    wires.push({ id: `${t.id}|wire`, source: t.id, sourcePort: "out", target: t.target,
      targetPort: t.port, label: "", sign: t.sign, external: true, groups: t.groups });
  }
  const routes = routeAll(nodes, wires);
  const labelled = new Set();
  return wires.map((w) => {
    const key = `${w.source}|${w.sourcePort}`;
    const showLabel = !w.external && !labelled.has(key);
    labelled.add(key);
    const inJunction = junctionPort(w.target, w.targetPort);
    const src = blockById[w.source];
    return {
      id: w.id, source: w.source, sourceHandle: w.sourcePort,
      target: inJunction ? `${w.target}::sum` : w.target, targetHandle: w.targetPort,
      type: "wire", selected: selectedEdges.has(w.id), selectable: true,
      reconnectable: !w.external, deletable: true,
      markerEnd: { type: "arrowclosed", width: 14, height: 14, color: "#1f3b6e" },
      data: { points: (routes[w.id] || {}).points, label: w.label, sign: w.sign, showLabel,
        flip: src && src.flip, junctionSign: inJunction, wire: w },
    };
  }).concat(junctionEdges(diagram, nodes));
}

// the line from a junction into its block (drawn, not editable)
function junctionEdges(diagram, nodes) {
  const byId = Object.fromEntries(nodes.map((n) => [n.id, n]));
  const out = [];
  for (const b of diagram.blocks) {
    const j = byId[`${b.name}::sum`];
    const o = byId[b.name];
    if (!j || !o) continue;
    const y = o.position.y + b.h / 2;
    const x0 = b.flip ? j.position.x : j.position.x + 2 * JUNCTION_R;
    const x1 = b.flip ? o.position.x + b.w : o.position.x;
    out.push({ id: `${b.name}::sum|edge`, source: `${b.name}::sum`, target: b.name,
      type: "wire", selectable: false, deletable: false, reconnectable: false,
      markerEnd: { type: "arrowclosed", width: 14, height: 14, color: "#1f3b6e" },
      data: { points: [[x0, y], [x1, y]], showLabel: false, sign: 1 } });
  }
  return out;
}

// ------------------------------------------------------------------------------ panels

// "+ input": a new external input, wired afterwards by dragging from its dot
function NewInput({ send }) {
  const [open, setOpen] = useState(false);
  const [name, setName] = useState("");
  if (!open) {
    return <button type="button" data-testid="add-input" title="a new external input"
      onClick={() => setOpen(true)}>+ input</button>;
  }
  const add = () => { if (name) send({ op: "add_input", name }); setOpen(false); setName(""); };
  return (
    <span className="ck-row">
      <input autoFocus className="ck-number" placeholder="name" value={name}
        data-testid="new-input" onChange={(ev) => setName(ev.target.value)}
        onKeyDown={(ev) => { if (ev.key === "Enter") add(); if (ev.key === "Escape")
          setOpen(false); }} />
      <button type="button" onClick={add}>add</button>
    </span>
  );
}

function Palette({ palette, variables, onAdd }) {
  const groups = {};
  for (const e of palette) (groups[e.group] = groups[e.group] || []).push(e);
  const item = (key, title, tip) => (
    <div key={key} className="ck-palette-item" draggable data-palette={key}
      onDragStart={(ev) => { ev.dataTransfer.setData("application/x-controlkit", key); }}
      onClick={() => onAdd(key)} title={`${tip || title}: click to add, or drag onto the diagram`}>
      {title}</div>
  );
  return (
    <div className="ck-palette">
      {Object.entries(groups).map(([g, entries]) => (
        <div key={g}><div className="ck-heading">{g}</div>
          {entries.map((e) => item(e.key, e.title, e.tip))}</div>
      ))}
      <div className="ck-heading">notebook variables</div>
      {variables.length ? variables.map((v) => item(`var:${v}`, v))
        : <div className="ck-muted">no python-control systems in the notebook</div>}
    </div>
  );
}

function sliderRange(v) {
  if (v > 0) return { log: true, lo: Math.log10(v) - 1, hi: Math.log10(v) + 1 };
  if (v < 0) return { log: true, lo: Math.log10(-v) - 1, hi: Math.log10(-v) + 1, neg: true };
  return { log: false, lo: -1, hi: 1 };
}

function ParamSlider({ block, name, value, send }) {
  const [range] = useState(() => sliderRange(value));
  const [shown, setShown] = useState(value);
  useEffect(() => setShown(value), [value]);
  const pos = range.log ? Math.log10(Math.abs(shown) || 1e-300) : shown;
  const toValue = (p) => (range.log ? (range.neg ? -1 : 1) * 10 ** p : p);
  const commit = (v) => send({ op: "set_parameter", block, name, value: v });
  return (
    <div className="ck-param">
      <label>{name}</label>
      <input type="range" min={range.lo} max={range.hi} step={(range.hi - range.lo) / 200}
        value={pos} data-param={`${block}.${name}`}
        onChange={(ev) => setShown(toValue(Number(ev.target.value)))}
        onPointerUp={(ev) => commit(toValue(Number(ev.target.value)))}
        onKeyUp={(ev) => commit(toValue(Number(ev.target.value)))} />
      <input type="number" className="ck-number" value={Number(shown.toPrecision(4))}
        onChange={(ev) => setShown(Number(ev.target.value))}
        onKeyDown={(ev) => { if (ev.key === "Enter") commit(Number(ev.target.value)); }}
        onBlur={(ev) => { if (Number(ev.target.value) !== value) commit(Number(ev.target.value)); }} />
    </div>
  );
}

function Inspector({ diagram, selectedBlock, selectedEdge, send, scopes }) {
  if (selectedBlock) {
    const b = diagram.blocks.find((x) => x.name === selectedBlock);
    if (!b) return null;
    const params = Object.entries(b.params);
    return (
      <div className="ck-inspector" data-testid="inspector">
        <div className="ck-heading"><Tex text={b.label} /></div>
        <div>block <b>{b.name}</b>, {b.sub.replace(`${b.name}, `, "")}
          {b.recipe ? `, from ${b.recipe}` : ""}</div>
        <div>{b.nstates} state{b.nstates === 1 ? "" : "s"}, {b.feedthrough
          ? "input reaches the output at once" : "no direct feedthrough"}</div>
        <div className="ck-ports">in: {b.inputs.map((p) => p.port).join(", ") || "none"}
          <br />out: {b.outputs.map((p) => p.port).join(", ") || "none"}</div>
        {diagram.setup && diagram.setup.initial[b.name] ? (
          <InitialState block={b.name} state={diagram.setup.initial[b.name]} send={send} />
        ) : null}
        {params.length ? <div className="ck-heading">parameters</div> : null}
        {params.map(([k, v]) => (
          <ParamSlider key={`${b.name}.${k}`} block={b.name} name={k} value={v} send={send} />
        ))}
        <div className="ck-row">
          {b.outputs.map((p) => (
            <button key={p.port} type="button" onClick={() => send({ op: "scopes",
              signals: [...new Set([...scopes, ...p.signals.map((s) => `${b.name}.${s}`)])] })}>
              scope {p.port}</button>
          ))}
        </div>
        <button type="button" className="ck-danger" data-testid="delete-block"
          onClick={() => send({ op: "delete", blocks: [b.name] })}>delete block {b.name}</button>
      </div>
    );
  }
  if (selectedEdge) {
    const e = diagram.edges.find((x) => x.id === selectedEdge);
    if (!e) return null;
    return (
      <div className="ck-inspector" data-testid="inspector">
        <div className="ck-heading">wire {e.source}.{e.sourcePort} → {e.target}.{e.targetPort}</div>
        <div className="ck-ports">{e.signals.map(([a, b]) => `${a} → ${b}`).join(", ")}</div>
        <button type="button" onClick={() => send({ op: "scopes", signals: [...new Set([
          ...scopes, ...e.signals.map(([a]) => `${e.source}.${a}`)])] })}>scope these signals</button>
        <button type="button" className="ck-danger" data-testid="disconnect"
          onClick={() => send({ op: "disconnect", edges: [[e.source, e.sourcePort, e.target,
            e.targetPort]] })}>disconnect</button>
      </div>
    );
  }
  return (
    <div className="ck-inspector ck-muted">
      Select a block to see its parameters, a wire to scope or disconnect it. Drag from an
      output port (right) to an input port (left) to connect; press Delete to remove what is
      selected.
    </div>
  );
}

// what drives an external input: a kind and its numbers, applied with Enter or "apply"
function SourceEditor({ name, source, kinds, send }) {
  const [kind, setKind] = useState(source.kind);
  const [fields, setFields] = useState(() => ({ ...source }));
  useEffect(() => { setKind(source.kind); setFields({ ...source }); }, [source]);
  const shown = kinds[kind];
  const value = (k) => (k in fields ? fields[k] : shown[k]);
  const apply = () => send({ op: "set_source", input: name, kind, fields: Object.fromEntries(
    Object.keys(shown).map((k) => [k, Number(value(k))])) });
  return (
    <div className="ck-source-editor" data-source={name}>
      <div className="ck-row"><b><Tex text={name} /></b>
        <select value={kind} data-testid="source-kind" onChange={(ev) => {
          setKind(ev.target.value); setFields({ ...kinds[ev.target.value] }); }}>
          {Object.keys(kinds).map((k) => <option key={k}>{k}</option>)}
        </select></div>
      <div className="ck-fields">
        {Object.keys(shown).map((k) => (
          <label key={k}>{k}{k === "time" || k === "width" || k === "period" ? " [s]"
            : k === "frequency" ? " [Hz]" : k === "phase" ? " [rad]" : ""}
            <input className="ck-number" data-field={k} value={value(k)}
              onChange={(ev) => setFields({ ...fields, [k]: ev.target.value })}
              onKeyDown={(ev) => { if (ev.key === "Enter") apply(); }} /></label>
        ))}
      </div>
      <div className="ck-row"><button type="button" data-testid="apply-source"
        onClick={apply}>apply</button>
        <span className="ck-muted">{kind === source.kind ? source.text : ""}</span></div>
    </div>
  );
}

function InputInspector({ diagram, terminal, send }) {
  const { sources, kinds } = diagram.setup;
  return (
    <div className="ck-inspector" data-testid="input-inspector">
      <div className="ck-heading">external input <Tex text={terminal.label} /></div>
      <div className="ck-muted">{terminal.target ? `drives ${terminal.target}.${terminal.port}`
        : "drives nothing yet: drag from its dot to an input port"}</div>
      {terminal.names.map((n) => sources[n] ? (
        <SourceEditor key={n} name={n} source={sources[n]} kinds={kinds} send={send} />
      ) : null)}
      <div className="ck-row">
        {terminal.target ? terminal.groups.map((g) => (
          <button key={g} type="button" onClick={() => send({ op: "disconnect_input", input: g,
            target: [terminal.target, terminal.port] })}>disconnect {g}</button>)) : null}
        {terminal.groups.map((g) => (
          <button key={`rm${g}`} type="button" className="ck-danger" data-testid="remove-input"
            onClick={() => send({ op: "remove_input", input: g })}>remove input {g}</button>))}
      </div>
    </div>
  );
}

function InitialState({ block, state, send }) {
  const text = state.values.map((v) => Number(v.toPrecision(6))).join(", ");
  const [shown, setShown] = useState(text);
  useEffect(() => setShown(text), [text]);
  const apply = () => send({ op: "set_initial", block,
    values: shown.split(/[,\s]+/).filter(Boolean).map(Number) });
  return (
    <div className="ck-initial">
      <div className="ck-heading">initial state</div>
      <div className="ck-muted">{state.states.join(", ")}{state.set ? "" : " (the block's own)"}</div>
      <div className="ck-row">
        <input value={shown} data-testid="initial-state" onChange={(ev) => setShown(ev.target.value)}
          onKeyDown={(ev) => { if (ev.key === "Enter") apply(); }} />
        <button type="button" onClick={apply}>set</button>
        {state.set ? <button type="button" onClick={() => send({ op: "set_initial", block,
          values: null })}>reset</button> : null}
      </div>
    </div>
  );
}

function Problems({ problems }) {
  const shown = problems.filter((p) => p.severity !== "note");
  const notes = problems.filter((p) => p.severity === "note");
  return (
    <div className="ck-problems" data-testid="problems">
      {shown.length === 0 ? <div className="ck-ok">wiring: no problems</div> : null}
      {shown.map((p) => (
        <div key={p.message} className={`ck-problem ck-${p.severity}`} data-kind={p.kind}>
          {p.message}</div>
      ))}
      {notes.length ? <details><summary>{notes.length} note{notes.length > 1 ? "s" : ""}
        </summary>{notes.map((p) => <div key={p.message} className="ck-problem ck-note">
          {p.message}</div>)}</details> : null}
    </div>
  );
}

const fmtValue = (v) => (v === null || v === undefined ? "–" : String(Number(v.toPrecision(6))));

function Scopes({ results, scopes, signals, send }) {
  const [pick, setPick] = useState("");
  const time = results.time || [];
  return (
    <div className="ck-scopes">
      <div className="ck-row">
        <span className="ck-heading">scopes</span>
        {scopes.map((s) => (
          <span key={s} className="ck-chip">{s}
            <button type="button" onClick={() => send({ op: "scopes",
              signals: scopes.filter((x) => x !== s) })}>×</button></span>
        ))}
        <select value={pick} onChange={(ev) => {
          setPick("");
          if (ev.target.value) send({ op: "scopes", signals: [...scopes, ev.target.value] });
        }}>
          <option value="">+ signal…</option>
          {signals.filter((s) => !scopes.includes(s)).map((s) => <option key={s}>{s}</option>)}
        </select>
      </div>
      {(results.measures || []).map((m) => (
        <div key={m.name} className={`ck-measure ${m.met === false ? "ck-missed" : m.met
          ? "ck-met" : ""}`} data-testid="measure">{m.text}</div>
      ))}
      <div className="ck-charts">
      {(results.measures || []).map((m) => (
        <div key={m.name}>
          {m.y ? <Chart title={`${m.name}${m.unit ? ` [${m.unit}]` : ""}`} time={time}
            traces={[{ name: m.name, y: m.y }]} log={m.log} limit={m.limit} unit={m.unit}
            testid="measure-chart" /> : null}
        </div>
      ))}
      {(results.traces || []).length ? (
        <div>
          <Chart title="signals" time={time} traces={results.traces} testid="scope-chart" />
          <div className="ck-readout" data-testid="readout">
            {results.traces.map((tr) => (
              <div key={tr.name} data-trace={tr.name}>{tr.name}: final {fmtValue(tr.final)},
                largest {fmtValue(tr.peak)} at t = {fmtValue(tr.peak_time)} s</div>
            ))}
          </div>
        </div>) : null}
      </div>
    </div>
  );
}

// ------------------------------------------------------------------------------ app

function Editor({ model }) {
  const diagram = useTrait(model, "diagram");
  const problems = useTrait(model, "problems");
  const variables = useTrait(model, "variables");
  const results = useTrait(model, "results");
  const status = useTrait(model, "status");
  const horizon = useTrait(model, "horizon");
  const scopes = useTrait(model, "scopes");
  const height = useTrait(model, "height");
  const code = useTrait(model, "code_text");
  const download = useTrait(model, "download");
  const canUndo = useTrait(model, "can_undo");
  const canRedo = useTrait(model, "can_redo");
  const send = useCallback((msg) => model.send(msg), [model]);
  const zoom = useStore((st) => st.transform[2]);
  const clipboard = useRef([]);
  const refit = useRef(null);  // the diagram a re-layout or a load replaces
  const upload = useRef(null);
  const root = useRef(null);
  const flow = useReactFlow();
  const wrapper = useRef(null);
  const [nodes, setNodes] = useState([]);
  const [selectedEdges, setSelectedEdges] = useState(new Set());
  const [showCode, setShowCode] = useState(false);
  const [running, setRunning] = useState(false);
  const [horizonText, setHorizonText] = useState(String(horizon));
  useEffect(() => setHorizonText(String(horizon)), [horizon]);
  useEffect(() => setRunning(false), [results, status]);

  const bad = useMemo(() => new Set(problems.filter((p) => p.severity === "error")
    .flatMap((p) => p.blocks)), [problems]);
  const warn = useMemo(() => new Set(problems.filter((p) => p.severity === "warning")
    .flatMap((p) => p.blocks)), [problems]);
  useEffect(() => {
    setNodes((prev) => buildNodes(diagram, prev, bad, warn));
  }, [diagram, bad, warn]);
  const edges = useMemo(() => buildEdges(diagram, nodes, selectedEdges),
    [diagram, nodes, selectedEdges]);
  // fit the blocks and the lanes of their wires (React Flow's own fit sees the blocks only)
  const fit = useCallback(() => {
    const xs = [], ys = [];
    for (const n of nodes) {
      if (n.hidden) continue;
      const w = n.width || (n.data.block ? n.data.block.w : 20);
      const h = n.height || (n.data.block ? n.data.block.h : 20);
      xs.push(n.position.x, n.position.x + w);
      ys.push(n.position.y, n.position.y + h);
    }
    for (const e of edges) for (const [x, y] of (e.data && e.data.points) || []) {
      xs.push(x); ys.push(y);
    }
    if (!xs.length) return;
    const x0 = Math.min(...xs) - 30, y0 = Math.min(...ys) - 20;
    flow.fitBounds({ x: x0, y: y0, width: Math.max(...xs) - x0 + 40,
      height: Math.max(...ys) - y0 + 30 }, { padding: 0.02 });
  }, [nodes, edges, flow]);
  const fitted = useRef(false);
  useEffect(() => {  // on opening, and once a re-layout or a loaded file has arrived
    const again = refit.current && refit.current !== diagram;
    if ((!fitted.current || again) && nodes.length
        && nodes.every((n) => n.measured || n.width)) {
      fitted.current = true;
      refit.current = null;
      const fitAll = () => { fit(); if (flow.getZoom() > 1.25) flow.zoomTo(1.25); };
      requestAnimationFrame(fitAll);
    }
  }, [nodes, fit, flow, diagram]);
  // a saved file handed to the browser as a download
  const lastDownload = useRef(download && download.serial);
  useEffect(() => {
    if (!download || !download.text || download.serial === lastDownload.current) return;
    lastDownload.current = download.serial;
    const url = URL.createObjectURL(new Blob([download.text], { type: "application/json" }));
    const link = document.createElement("a");
    link.href = url;
    link.download = download.name;
    document.body.appendChild(link);
    link.click();
    link.remove();
    setTimeout(() => URL.revokeObjectURL(url), 1000);
  }, [download]);
  const load = useCallback((ev) => {
    const file = ev.target.files && ev.target.files[0];
    if (!file) return;
    file.text().then((text) => { refit.current = diagram; send({ op: "load", text }); });
    ev.target.value = "";
  }, [send]);

  const onNodesChange = useCallback((changes) => {
    setNodes((nds) => follow(applyNodeChanges(changes, nds)));
  }, []);
  const onEdgesChange = useCallback((changes) => {
    setSelectedEdges((prev) => {
      const next = new Set(prev);
      for (const c of changes) {
        if (c.type === "select") { if (c.selected) next.add(c.id); else next.delete(c.id); }
        if (c.type === "remove") next.delete(c.id);
      }
      return next;
    });
  }, []);
  const onNodeDragStop = useCallback((_ev, _node, dragged) => {
    const positions = {};
    for (const n of dragged || []) {
      if (n.type === "block" || n.type === "sum") {
        const b = n.data.block;
        positions[n.id] = [n.position.x + b.w / 2, n.position.y + b.h / 2];
      }
    }
    send({ op: "move", positions });
  }, [send]);
  const owner = (id) => id.replace(/::sum$/, "");
  const onConnect = useCallback((c) => {
    if (c.source.startsWith("in:")) {  // an external input dragged onto a port
      const t = diagram.inputs.find((x) => x.id === c.source);
      if (t) send({ op: "connect_input", input: t.groups[0],
        target: [owner(c.target), c.targetHandle] });
      return;
    }
    send({ op: "connect", source: [c.source, c.sourceHandle],
      target: [owner(c.target), c.targetHandle] });
  }, [send, diagram]);
  const wireOf = (edge) => (edge.data && edge.data.wire) || null;
  const onDelete = useCallback(({ nodes: gone, edges: cut }) => {
    const blocks = gone.filter((n) => n.type === "block" || n.type === "sum").map((n) => n.id);
    const kept = cut.map(wireOf).filter((w) => w && !blocks.includes(w.target)
      && !blocks.includes(w.source));
    const wires = kept.filter((w) => !w.external)
      .map((w) => [w.source, w.sourcePort, w.target, w.targetPort]);
    if (wires.length) send({ op: "disconnect", edges: wires });
    for (const w of kept.filter((x) => x.external)) {
      for (const g of w.groups) send({ op: "disconnect_input", input: g,
        target: [w.target, w.targetPort] });
    }
    if (blocks.length) send({ op: "delete", blocks });
  }, [send]);
  const reconnected = useRef(false);
  const onReconnectStart = useCallback(() => { reconnected.current = false; }, []);
  const onReconnect = useCallback((old, c) => {
    reconnected.current = true;
    const w = wireOf(old);
    if (!w) return;
    send({ op: "disconnect", edges: [[w.source, w.sourcePort, w.target, w.targetPort]] });
    send({ op: "connect", source: [c.source, c.sourceHandle],
      target: [owner(c.target), c.targetHandle] });
  }, [send]);
  const onReconnectEnd = useCallback((_ev, old) => {
    if (reconnected.current) return;
    const w = wireOf(old);  // dropped on nothing: the wire is removed
    if (w) send({ op: "disconnect", edges: [[w.source, w.sourcePort, w.target, w.targetPort]] });
  }, [send, diagram]);
  // a new block goes where it overlaps no block and no wire, nearest the point asked for
  const addAt = useCallback((key, point) => {
    const wanted = flow.screenToFlowPosition(point);
    const entry = (diagram.palette || []).find((e) => e.key === key);
    const [w, h] = entry && entry.key === "summing_junction" ? [40, 40]
      : entry && entry.key === "gain" ? [60, 50] : [130, 60];
    const position = freeSpot(nodes, edges, wanted, w, h);
    send({ op: "add", key, position: [position.x, position.y] });
  }, [flow, send, nodes, edges, diagram]);
  const addCentre = useCallback((key) => {
    const r = wrapper.current.getBoundingClientRect();
    addAt(key, { x: r.left + r.width / 2, y: r.top + r.height / 2 });
  }, [addAt]);
  // Ctrl+Z undo, Ctrl+Shift+Z (or Ctrl+Y) redo, Ctrl+C / Ctrl+V copy and paste blocks
  const onKeyDown = useCallback((ev) => {
    const tag = (ev.target && ev.target.tagName) || "";
    if (["INPUT", "TEXTAREA", "SELECT"].includes(tag) || !(ev.ctrlKey || ev.metaKey)) return;
    const key = ev.key.toLowerCase();
    let msg = null;
    if (key === "z") msg = { op: ev.shiftKey ? "redo" : "undo" };
    else if (key === "y") msg = { op: "redo" };
    else if (key === "c") {
      clipboard.current = nodes.filter((n) => n.selected && (n.type === "block"
        || n.type === "sum")).map((n) => n.id);
    } else if (key === "v" && clipboard.current.length) {
      msg = { op: "paste", blocks: clipboard.current };
    } else return;
    ev.preventDefault();
    ev.stopPropagation();
    if (msg) send(msg);
  }, [nodes, send]);
  // the keys reach the editor the user last clicked in (a deleted node takes the focus
  // with it, so the document listens, not the node)
  const active = useRef(false);
  useEffect(() => {
    const down = (ev) => { active.current = !!(root.current && root.current.contains(ev.target)); };
    const key = (ev) => { if (active.current) onKeyDown(ev); };
    document.addEventListener("mousedown", down, true);
    document.addEventListener("keydown", key, true);
    return () => {
      document.removeEventListener("mousedown", down, true);
      document.removeEventListener("keydown", key, true);
    };
  }, [onKeyDown]);
  const onDrop = useCallback((ev) => {
    ev.preventDefault();
    const key = ev.dataTransfer.getData("application/x-controlkit");
    if (key) addAt(key, { x: ev.clientX, y: ev.clientY });
  }, [addAt]);
  const selectedNode = nodes.find((n) => n.selected && (n.type === "block" || n.type === "sum"));
  const selectedInput = nodes.find((n) => n.selected && n.type === "terminal");
  const selectedEdge = [...selectedEdges][0];
  const errors = problems.filter((p) => p.severity === "error").length;
  const run = () => {
    const value = Number(horizonText);
    setRunning(true);
    send({ op: "run", horizon: value });
  };

  return (
    <div className="ck-editor" data-lm-suppress-shortcuts="true" ref={root}>
      <div className="ck-toolbar">
        <Tex text={diagram.title} className="ck-title" />
        <span className="ck-spacer" />
        <button type="button" data-testid="undo" disabled={!canUndo} title="undo (Ctrl+Z)"
          onClick={() => send({ op: "undo" })}>↶ undo</button>
        <button type="button" data-testid="redo" disabled={!canRedo}
          title="redo (Ctrl+Shift+Z)" onClick={() => send({ op: "redo" })}>↷ redo</button>
        <button type="button" data-testid="save" title="download the diagram as a file"
          onClick={() => send({ op: "save" })}>save</button>
        <button type="button" data-testid="load" title="open a saved diagram file"
          onClick={() => upload.current.click()}>load</button>
        <input type="file" accept=".json,application/json" ref={upload} onChange={load}
          style={{ display: "none" }} data-testid="load-file" />
        <button type="button" data-testid="relayout" title="place the blocks as the static drawing does"
          onClick={() => { refit.current = diagram; send({ op: "relayout" }); }}>re-layout</button>
        <NewInput send={send} />
        <label>horizon [s] <input className="ck-number" value={horizonText}
          onChange={(ev) => setHorizonText(ev.target.value)} data-testid="horizon"
          onKeyDown={(ev) => { if (ev.key === "Enter") send({ op: "horizon",
            value: Number(horizonText) }); }}
          onBlur={() => { if (Number(horizonText) !== horizon) send({ op: "horizon",
            value: Number(horizonText) }); }} /></label>
        <button type="button" className="ck-run" onClick={run} disabled={errors > 0 || running}
          data-testid="run" title={errors ? "fix the wiring errors first" : "simulate"}>
          {running ? "running…" : "▶ Run"}</button>
        <button type="button" onClick={fit} title="show the whole diagram">fit</button>
        <button type="button" onClick={() => setShowCode(!showCode)}>
          {showCode ? "diagram" : "Python code"}</button>
      </div>
      <div className="ck-main" style={{ height }}>
        <Palette palette={diagram.palette || []} variables={variables}
          onAdd={(key) => addCentre(key)} />
        <div className={`ck-canvas ${zoom >= 1.3 ? "ck-zoomed" : ""}`} ref={wrapper}
          onDragOver={(ev) => ev.preventDefault()} onDrop={onDrop}>
          {diagram.mixed && !showCode ? (
            <div className="ck-rate-legend" data-testid="rate-legend">
              <span className="ck-swatch ck-discrete" /> discrete: updates at its instants,
              holds its output between them
              <span className="ck-swatch" /> continuous or static</div>) : null}
          {showCode ? <pre className="ck-code" data-testid="code">{code}</pre> : null}
          {(
            <ReactFlow nodes={nodes} edges={edges} nodeTypes={nodeTypes} edgeTypes={edgeTypes}
              onNodesChange={onNodesChange} onEdgesChange={onEdgesChange}
              onNodeDragStop={onNodeDragStop} onConnect={onConnect} onDelete={onDelete}
              onReconnect={onReconnect} onReconnectStart={onReconnectStart}
              onReconnectEnd={onReconnectEnd} deleteKeyCode={["Delete", "Backspace"]}
              minZoom={0.2} maxZoom={3}
              connectionRadius={24} proOptions={{ hideAttribution: true }}
              connectionLineStyle={{ stroke: "#b03a2e", strokeWidth: 2 }}>
              <Background gap={20} size={1} color="#e8e8e8" />
              <Controls showInteractive={false} showFitView={false} />
            </ReactFlow>
          )}
        </div>
        <div className="ck-side">
          {selectedInput && !selectedNode && diagram.setup ? (
            <InputInspector diagram={diagram} terminal={selectedInput.data} send={send} />
          ) : (
            <Inspector diagram={diagram} selectedBlock={selectedNode && selectedNode.id}
              selectedEdge={selectedNode ? null : selectedEdge} send={send} scopes={scopes} />
          )}
          <Problems problems={problems} />
        </div>
      </div>
      <div className={`ck-status ${/^[A-Za-z]*Error/.test(status || "") ? "ck-error" : ""}`}
        data-testid="status">{status}</div>
      <Scopes results={results} scopes={scopes} signals={diagram.signals || []} send={send} />
    </div>
  );
}

function render({ model, el }) {
  const root = createRoot(el);
  root.render(<ReactFlowProvider><Editor model={model} /></ReactFlowProvider>);
  return () => root.unmount();
}

export default { render };
