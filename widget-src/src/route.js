// Geometry of the diagram: where ports are, and orthogonal routes for the wires, drawn the
// way controlkit.drawing draws them: a signal leaves its block to the right, turns on a
// track beside it, and runs to the next block; feedback runs back in lanes under the
// blocks, and a signal that would cross a block runs in a lane above them.

export const JUNCTION_GAP = 56; // distance from a block's left edge to its junction's centre
export const JUNCTION_R = 14;

// where each handle of each node is, in flow coordinates
export function portPoints(nodes) {
  const points = {};
  for (const n of nodes) {
    const d = n.data || {};
    const x = n.position.x, y = n.position.y;
    if (n.type === "block" || n.type === "sum") {
      const b = d.block;
      const w = b.w, h = b.h;
      const flip = b.flip;
      const visibleIns = b.inputs.filter((p) => !p.junction);
      if (n.type === "sum") {
        const r = w / 2;
        for (const p of b.inputs) {
          const side = p.side;
          const pt = side === "left" ? [x, y + r] : side === "bottom" ? [x + r, y + 2 * r]
            : [x + r, y];
          points[`${n.id}|in|${p.port}`] = { x: pt[0], y: pt[1], side };
        }
        for (const p of b.outputs) points[`${n.id}|out|${p.port}`] = { x: x + w, y: y + r,
          side: "right" };
        continue;
      }
      visibleIns.forEach((p, i) => {
        points[`${n.id}|in|${p.port}`] = { x: flip ? x + w : x,
          y: y + (h * (i + 1)) / (visibleIns.length + 1), side: flip ? "right" : "left",
          index: i };
      });
      b.outputs.forEach((p, i) => {
        points[`${n.id}|out|${p.port}`] = { x: flip ? x : x + w,
          y: y + (h * (i + 1)) / (b.outputs.length + 1), side: flip ? "left" : "right",
          index: i };
      });
    } else if (n.type === "junction") {
      const cx = x + JUNCTION_R, cy = y + JUNCTION_R;
      d.ports.forEach((p, i) => {
        const side = ["left", "bottom", "top"][Math.min(i, 2)];
        const pt = side === "left" ? [cx - JUNCTION_R, cy] : side === "bottom"
          ? [cx, cy + JUNCTION_R] : [cx, cy - JUNCTION_R];
        points[`${d.owner}|in|${p.port}`] = { x: pt[0], y: pt[1], side, junction: n.id };
      });
    } else if (n.type === "terminal") {
      points[`${n.id}|out|out`] = { x: x + d.w, y: y + 10, side: "right" };
    }
  }
  return points;
}

// blocks as obstacles, widened by their port stubs so that no wire grazes a port
function rects(nodes) {
  return nodes.filter((n) => n.type === "block" || n.type === "sum").map((n) => ({
    id: n.id, x0: n.position.x - 12, y0: n.position.y - 4,
    x1: n.position.x + n.data.block.w + 12, y1: n.position.y + n.data.block.h + 4,
  }));
}

function crosses(points, boxes, skip) {
  for (let i = 0; i + 1 < points.length; i++) {
    const [a, b] = [points[i], points[i + 1]];
    const x0 = Math.min(a[0], b[0]), x1 = Math.max(a[0], b[0]);
    const y0 = Math.min(a[1], b[1]), y1 = Math.max(a[1], b[1]);
    for (const r of boxes) {
      if (skip.includes(r.id)) continue;
      if (x1 > r.x0 + 2 && x0 < r.x1 - 2 && y1 > r.y0 + 2 && y0 < r.y1 - 2) return true;
    }
  }
  return false;
}

function entryPoint(t, stub) {
  if (t.side === "left") return [t.x - stub, t.y];
  if (t.side === "right") return [t.x + stub, t.y];
  if (t.side === "bottom") return [t.x, t.y + stub];
  return [t.x, t.y - stub];
}

// routes for all wires: {edgeId: {points, lane}}
export function routeAll(nodes, wires) {
  const pts = portPoints(nodes);
  const boxes = rects(nodes);
  const bottom = Math.max(...boxes.map((r) => r.y1), 0);
  const top = Math.min(...boxes.map((r) => r.y0), 0);
  // sources whose exits share a gap get tracks of their own, the topmost nearest its block
  // (past the signal's label, which is written where the signal leaves its block)
  const exits = [];
  for (const w of wires) {
    const s = pts[`${w.source}|out|${w.sourcePort}`];
    const key = `${w.source}|${w.sourcePort}`;
    if (s && !exits.some((e) => e.key === key)) {
      exits.push({ key, x: s.x, y: s.y, label: w.external ? 0 : 6.5 * (w.label || "").length });
    }
  }
  exits.sort((a, b) => a.y - b.y);
  const track = {};
  for (const e of exits) {
    const near = exits.filter((o) => Math.abs(o.x - e.x) < 40 && o.key in track);
    let k = 0;
    while (near.some((o) => track[o.key] === k)) k++;
    track[e.key] = k;
  }
  const base = {};
  for (const e of exits) {
    base[e.key] = 12 + Math.max(...exits.filter((o) => Math.abs(o.x - e.x) < 40)
      .map((o) => o.label));
  }
  const plans = [];
  for (const w of wires) {
    const s = pts[`${w.source}|out|${w.sourcePort}`];
    const t = pts[`${w.target}|in|${w.targetPort}`];
    if (!s || !t) continue;
    const dir = s.side === "left" ? -1 : 1;
    const key = `${w.source}|${w.sourcePort}`;
    const exit = (base[key] || 12) + 9 * (track[key] || 0);
    const S = [s.x, s.y], S1 = [s.x + dir * exit, s.y];
    const T = [t.x, t.y];
    const T1 = entryPoint(t, 12 + 5 * (t.index || 0));
    const owners = [w.source, w.target, t.junction].filter(Boolean);
    let points = null;
    if (t.side === "left" || t.side === "right") {
      const forward = t.side === "left" ? S1[0] <= T1[0] + 0.5 : S1[0] >= T1[0] - 0.5;
      if (forward) {
        if (Math.abs(S[1] - T[1]) < 0.5) points = [S, T];
        for (const xm of points ? [] : [S1[0], T1[0], (S1[0] + T1[0]) / 2]) {
          const cand = [S, [xm, S[1]], [xm, T[1]], T];
          if (!crosses(cand, boxes, owners)) { points = cand; break; }
        }
        if (points && crosses(points, boxes, owners)) points = null;
        if (points) { plans.push({ w, points }); continue; }
        plans.push({ w, lane: "top", S, S1, T, T1 });
        continue;
      }
      plans.push({ w, lane: "bottom", S, S1, T, T1 });
      continue;
    }
    // into a junction from above or below
    const fromBelow = t.side === "bottom";
    const cand = [S, [t.x, S[1]], T];
    const rightWay = fromBelow ? S[1] > T[1] : S[1] < T[1];
    if (rightWay && (dir > 0 ? S[0] < t.x : S[0] > t.x) && !crosses(cand, boxes, owners)) {
      plans.push({ w, points: cand });
      continue;
    }
    plans.push({ w, lane: fromBelow ? "bottom" : "top", S, S1, T, T1, vertical: true });
  }
  // lanes: the shortest spans nearest the blocks
  const routes = {};
  for (const where of ["bottom", "top"]) {
    const lanes = plans.filter((p) => p.lane === where);
    lanes.sort((a, b) => Math.abs(a.S[0] - a.T[0]) - Math.abs(b.S[0] - b.T[0]));
    // one lane per source port: a signal that feeds back to several blocks is one line
    const index = {};
    let next = 0;
    for (const p of lanes) {
      const key = `${p.w.source}|${p.w.sourcePort}`;
      if (!(key in index)) index[key] = next++;
      const y = where === "bottom" ? bottom + 26 + 14 * index[key] : top - 26 - 14 * index[key];
      p.points = p.vertical ? [p.S, p.S1, [p.S1[0], y], [p.T[0], y], p.T]
        : [p.S, p.S1, [p.S1[0], y], [p.T1[0], y], [p.T1[0], p.T[1]], p.T];
    }
  }
  for (const p of plans) routes[p.w.id] = { points: simplify(p.points), lane: p.lane || null };
  return routes;
}

function simplify(points) {
  const out = [];
  for (const p of points) {
    const last = out[out.length - 1];
    if (last && Math.abs(last[0] - p[0]) < 0.01 && Math.abs(last[1] - p[1]) < 0.01) continue;
    if (out.length >= 2) {
      const a = out[out.length - 2], b = last;
      const collinear = (Math.abs(a[0] - b[0]) < 0.01 && Math.abs(b[0] - p[0]) < 0.01)
        || (Math.abs(a[1] - b[1]) < 0.01 && Math.abs(b[1] - p[1]) < 0.01);
      if (collinear) { out[out.length - 1] = p; continue; }
    }
    out.push(p);
  }
  return out;
}

export function pathOf(points) {
  return points.map((p, i) => `${i ? "L" : "M"}${p[0].toFixed(1)},${p[1].toFixed(1)}`).join(" ");
}

// the point nearest `point` where a w x h block overlaps no block, terminal, frame or wire
export function freeSpot(nodes, edges, point, w, h, margin = 24) {
  const boxes = nodes.filter((n) => !n.hidden).map((n) => {
    const nw = n.width || (n.data && n.data.block ? n.data.block.w : 20);
    const nh = n.height || (n.data && n.data.block ? n.data.block.h : 20);
    return { x0: n.position.x - margin, y0: n.position.y - margin,
      x1: n.position.x + nw + margin, y1: n.position.y + nh + margin };
  });
  for (const e of edges) {
    const pts = (e.data && e.data.points) || [];
    for (let i = 0; i + 1 < pts.length; i++) {
      const [a, b] = [pts[i], pts[i + 1]];
      boxes.push({ x0: Math.min(a[0], b[0]) - 10, y0: Math.min(a[1], b[1]) - 10,
        x1: Math.max(a[0], b[0]) + 10, y1: Math.max(a[1], b[1]) + 10 });
    }
  }
  const free = (cx, cy) => boxes.every((r) => cx + w / 2 <= r.x0 || cx - w / 2 >= r.x1
    || cy + h / 2 <= r.y0 || cy - h / 2 >= r.y1);
  for (let ring = 0; ring < 80; ring++) {
    const candidates = [];
    for (let dx = -ring; dx <= ring; dx++) {
      for (let dy = -ring; dy <= ring; dy++) {
        if (Math.max(Math.abs(dx), Math.abs(dy)) !== ring) continue;
        candidates.push([point.x + 20 * dx, point.y + 20 * dy]);
      }
    }
    candidates.sort((a, b) => Math.hypot(a[0] - point.x, a[1] - point.y)
      - Math.hypot(b[0] - point.x, b[1] - point.y));
    const found = candidates.find(([x, y]) => free(x, y));
    if (found) return { x: found[0], y: found[1] };
  }
  return point;
}
