// crease report: per-frame line charts as SVG (no library: a few polylines, axes and a legend). Values that
// are missing (null, NaN) break the line rather than being drawn as zero.
import { el, svg } from "/assets/dom.js";

const W = 560, H = 220;
const M = { left: 58, right: 12, top: 12, bottom: 34 };
export const COLORS = ["#2f6fd6", "#d0413a", "#2e9d4f", "#b26ad8", "#d98a1c", "#444b5a"];

function ticks(lo, hi, n) {
  if (!(hi > lo)) return [lo];
  const raw = (hi - lo) / n;
  const p = Math.pow(10, Math.floor(Math.log10(raw)));
  const step = [1, 2, 5, 10].map((m) => m * p).find((s) => s >= raw);
  const out = [];
  for (let v = Math.ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) out.push(+v.toPrecision(12));
  return out;
}

// A chart of `series` ([{label, values, color?, dash?}], values indexed by 0-based frame) against the frame
// number (shown 1-based). `format` writes a y value for the axis; `unit` labels the axis.
export function lineChart({ id, title, meaning, unit, series, format }) {
  const fmt = format || ((v) => String(+v.toPrecision(3)));
  const n = Math.max(0, ...series.map((s) => s.values.length));
  const finite = series.flatMap((s) => s.values).filter((v) => v != null && isFinite(v));
  let lo = Math.min(0, ...finite), hi = Math.max(...finite, lo + 1e-12);
  if (!finite.length) { lo = 0; hi = 1; }
  const pad = 0.05 * (hi - lo);
  hi += pad;
  if (lo < 0) lo -= pad;
  const x = (i) => M.left + (n > 1 ? (i / (n - 1)) : 0.5) * (W - M.left - M.right);
  const y = (v) => H - M.bottom - ((v - lo) / (hi - lo)) * (H - M.top - M.bottom);
  const root = svg("svg", { viewBox: `0 0 ${W} ${H}`, width: W, height: H, class: "chart", role: "img", "aria-label": title });
  for (const v of ticks(lo, hi, 4)) {
    root.append(svg("line", { x1: M.left, x2: W - M.right, y1: y(v), y2: y(v), stroke: "#e6e8ec" }),
      svg("text", { x: M.left - 6, y: y(v) + 4, "text-anchor": "end", "font-size": 11, fill: "#6b7385", text: fmt(v) }));
  }
  const xt = ticks(1, Math.max(1, n), 6).filter((v) => Number.isInteger(v));
  for (const f of xt) {
    root.append(svg("text", { x: x(f - 1), y: H - M.bottom + 15, "text-anchor": "middle", "font-size": 11, fill: "#6b7385", text: String(f) }));
  }
  root.append(
    svg("line", { x1: M.left, x2: W - M.right, y1: H - M.bottom, y2: H - M.bottom, stroke: "#9aa1ae" }),
    svg("line", { x1: M.left, x2: M.left, y1: M.top, y2: H - M.bottom, stroke: "#9aa1ae" }),
    svg("text", { x: (M.left + W - M.right) / 2, y: H - 4, "text-anchor": "middle", "font-size": 11, fill: "#6b7385", text: "frame" }),
    svg("text", { x: 12, y: (M.top + H - M.bottom) / 2, "text-anchor": "middle", "font-size": 11, fill: "#6b7385",
      transform: `rotate(-90 12 ${(M.top + H - M.bottom) / 2})`, text: unit }));
  series.forEach((s, k) => {
    const color = s.color || COLORS[k % COLORS.length];
    let d = "", pen = false;
    s.values.forEach((v, i) => {
      if (v == null || !isFinite(v)) { pen = false; return; }
      d += `${pen ? "L" : "M"}${x(i).toFixed(1)},${y(v).toFixed(1)}`;
      pen = true;
    });
    if (n === 1 && d) d += `h0.01`;
    const attrs = { d, fill: "none", stroke: color, "stroke-width": 1.8, "stroke-linejoin": "round", "data-series": s.label };
    if (s.dash) attrs["stroke-dasharray"] = "5 3";
    if (d) root.append(svg("path", attrs));
  });
  const legend = el("div", { class: "chart-legend" }, ...series.map((s, k) => {
    const sw = el("span", { class: "swatch" });
    sw.style.backgroundColor = s.color || COLORS[k % COLORS.length];
    return el("span", {}, sw, document.createTextNode(s.label));
  }));
  return el("figure", { class: "chart-box", id: id || "" },
    el("figcaption", { class: "chart-title", text: title }),
    root, legend,
    meaning ? el("figcaption", { class: "muted", text: meaning }) : null);
}
