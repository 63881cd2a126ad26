// A light SVG chart for the scopes: lines over time, linear or logarithmic y, a limit line.
import React from "react";

const COLORS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2",
  "#17becf"];

function niceTicks(lo, hi, count = 5) {
  if (!(hi > lo)) return [lo];
  const step0 = (hi - lo) / count;
  const mag = 10 ** Math.floor(Math.log10(step0));
  const step = [1, 2, 5, 10].map((m) => m * mag).find((s) => s >= step0) || mag * 10;
  const ticks = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + step * 1e-9; v += step) {
    ticks.push(Math.abs(v) < step * 1e-9 ? 0 : v);
  }
  return ticks;
}

function fmt(v) {
  if (v === 0) return "0";
  const a = Math.abs(v);
  if (a >= 1e6 || a < 1e-3) return v.toExponential(1).replace("e+", "e");
  return String(Number(v.toPrecision(3)));
}

// the legend's entries in rows above the plot, each in its curve's colour (never on a curve)
function legendRows(traces, width) {
  const rows = [];
  let x = 0, row = 0;
  traces.forEach((tr, k) => {
    const w = 26 + 6.4 * tr.name.length;
    if (x > 0 && x + w > width) { row++; x = 0; }
    rows.push({ name: tr.name, x, row, color: COLORS[k % COLORS.length] });
    x += w + 10;
  });
  return rows;
}

export function Chart({ title, time, traces, log = false, limit = null, unit = "", testid }) {
  const W = 560, H0 = 190, L = 58, R = 24, B = 30;
  const legend = traces.length > 1 ? legendRows(traces, W - L - R) : [];
  const rows = legend.length ? legend[legend.length - 1].row + 1 : 0;
  const T = 22 + 14 * rows, H = H0 + 14 * rows;
  const values = [];
  for (const tr of traces) for (const v of tr.y) if (v !== null && (!log || v > 0)) values.push(v);
  if (limit !== null && (!log || limit > 0)) values.push(limit);
  if (!values.length || !time.length) {
    return <div className="ck-chart-empty">{title}: nothing to draw</div>;
  }
  let lo = Math.min(...values), hi = Math.max(...values);
  const t0 = time[0], t1 = time[time.length - 1] || 1;
  let ticks;
  const f = (v) => (log ? Math.log10(v) : v);
  if (log) {
    lo = Math.floor(Math.log10(lo));
    hi = Math.ceil(Math.log10(hi));
    if (hi === lo) hi = lo + 1;
    ticks = [];
    for (let e = lo; e <= hi; e++) ticks.push(e);
  } else {
    if (hi === lo) { hi += 1; lo -= 1; }
    const pad = (hi - lo) * 0.05;
    lo -= pad; hi += pad;
    ticks = niceTicks(lo, hi);
  }
  const X = (t) => L + ((t - t0) / (t1 - t0 || 1)) * (W - L - R);
  const Y = (v) => T + (1 - (f(v) - lo) / (hi - lo)) * (H - T - B);
  const Yt = (e) => T + (1 - (e - lo) / (hi - lo)) * (H - T - B);
  const lines = traces.map((tr, k) => {
    let d = "";
    let pen = false;
    tr.y.forEach((v, i) => {
      if (v === null || (log && v <= 0)) { pen = false; return; }
      d += `${pen ? "L" : "M"}${X(time[i]).toFixed(1)},${Y(v).toFixed(1)}`;
      pen = true;
    });
    return <path key={tr.name} d={d} fill="none" stroke={COLORS[k % COLORS.length]}
      strokeWidth="1.4" />;
  });
  const tticks = niceTicks(t0, t1, 6);
  return (
    <svg className="ck-chart" viewBox={`0 0 ${W} ${H}`} width={W} height={H} data-testid={testid}>
      <text x={L} y={14} className="ck-chart-title">{title}</text>
      <rect x={L} y={T} width={W - L - R} height={H - T - B} fill="white" stroke="#999" />
      {ticks.map((v) => (
        <g key={`y${v}`}>
          <line x1={L} x2={W - R} y1={Yt(v)} y2={Yt(v)} stroke="#eee" />
          <text x={L - 4} y={Yt(v) + 4} textAnchor="end" className="ck-tick">
            {log ? `1e${v}` : fmt(v)}</text>
        </g>
      ))}
      {tticks.map((t) => (
        <text key={`t${t}`} x={X(t)} y={H - B + 14} className="ck-tick"
          textAnchor={X(t) > W - R - 12 ? "end" : "middle"}>
          {fmt(t)}</text>
      ))}
      <text x={W - R} y={H - 2} textAnchor="end" className="ck-tick">time [s]</text>
      {limit !== null && (!log || limit > 0) && (
        <g>
          <line x1={L} x2={W - R} y1={Y(limit)} y2={Y(limit)} stroke="black"
            strokeDasharray="5 3" />
          <text x={W - R - 4} y={Y(limit) - 4} textAnchor="end" className="ck-tick">
            requirement {limit} {unit}</text>
        </g>
      )}
      {lines}
      {legend.map((e) => (
        <g key={`l${e.name}`} className="ck-legend-entry" data-legend={e.name}>
          <line x1={L + e.x} x2={L + e.x + 18} y1={30 + 14 * e.row - 4}
            y2={30 + 14 * e.row - 4} stroke={e.color} strokeWidth="2" />
          <text x={L + e.x + 22} y={30 + 14 * e.row} className="ck-legend"
            style={{ fill: e.color }}>{e.name}</text>
        </g>
      ))}
    </svg>
  );
}
