// crease report: report.json (written by the job's finalize task) and, when present, eval.json (`crease
// eval`) as tables a person reads — each figure with its unit and one line of what it means — and per-frame
// charts. The raw files are linked above the tables. Keys read here are the ones those writers set; a
// figure the report does not hold is left out, never shown as zero.
import { el } from "/assets/dom.js";
import { lineChart } from "/assets/plot.js";

const isNum = (v) => typeof v === "number" && isFinite(v);
// A cell that reads as a number is right-aligned; words and paths are not.
const NUMBER = /^[-+]?[\d,.]+(e[-+]?\d+)?$/;

function fmt(v, digits) {
  if (v == null) return "undefined";
  if (!isNum(v)) return String(v);
  if (v !== 0 && (Math.abs(v) >= 1e6 || Math.abs(v) < 1e-4)) return v.toExponential(digits - 1);
  return String(+v.toPrecision(digits));
}
const pct = (v) => (isNum(v) ? fmt(100 * v, 3) : fmt(v, 3));
const int = (v) => (isNum(v) ? Math.round(v).toLocaleString("en") : fmt(v, 3));
const secs = (v) => (isNum(v) ? fmt(v, 3) : fmt(v, 3));

// A table of [figure, value, unit, meaning] rows; rows whose value is undefined (not in the report) are
// dropped.
function figures(id, rows, head) {
  const kept = rows.filter((r) => r[1] !== undefined);
  if (!kept.length) return null;
  const th = head || ["Figure", "Value", "Unit", "What it means"];
  return el("table", { class: "figures", id },
    el("thead", {}, el("tr", {}, ...th.map((h) => el("th", { text: h })))),
    el("tbody", {}, ...kept.map((r) => el("tr", {},
      el("th", { text: r[0] }),
      ...r.slice(1, -2).map((v) => el("td", { class: NUMBER.test(v) ? "num" : "", text: v })),
      el("td", { class: "unit", text: r[r.length - 2] }),
      el("td", { class: "meaning", text: r[r.length - 1] })))));
}

// A row [name, ...values, unit, meaning] whose values come through `f`, or undefined values when the
// first is missing.
function row(name, values, f, unit, meaning) {
  if (values[0] === undefined) return [name, undefined, unit, meaning];
  return [name, ...values.map((v) => (v === undefined ? "" : f(v))), unit, meaning];
}

function section(title, ...body) {
  const kept = body.filter((b) => b != null);
  return kept.length ? el("section", { class: "report-part" }, el("h3", { text: title }), ...kept) : null;
}

function sum(a) { return a.reduce((s, x) => s + (isNum(x) ? x : 0), 0); }
function max(a) { return a.reduce((m, x) => (isNum(x) && x > m ? x : m), -Infinity); }

function sequenceTable(r) {
  const s = r.summary || {};
  const anchorsFrom = typeof r.anchors_file === "string" ? r.anchors_file
    : r.fold_detection && r.fold_detection.source ? `detected (${r.fold_detection.source})` : r.anchors_file === null ? "none" : undefined;
  return figures("report-sequence", [
    row("Frames", [s.frames], int, "frames", "length of the sequence"),
    row("Vertices", [s.vertices], int, "vertices", "points of the garment mesh, shared by every frame"),
    row("Triangles", [s.triangles], int, "triangles", "faces of the mesh (polygons fan-triangulated)"),
    row("Anchors", [s.anchors], int, "anchor triangles", "summed over frames: each rotates one triangle of one frame to put a fold back"),
    ["Anchors from", anchorsFrom, "", "the anchors file given, or the detector that found them"],
    ["Input", r.input, "", `the captured sequence (${r.input_layout || "layout unknown"})`],
    ["Output", r.output, "", "where the frames, pictures and this report were written"],
  ]);
}

function shapeTable(r) {
  const k = (r.summary || {}).shape_kept;
  if (!k) return null;
  const e = "mean edge lengths";
  return figures("report-shape", [
    row("Displacement, mean", [k.displacement_mean], (v) => fmt(v, 3), e, "how far an output vertex is from its captured position, on average"),
    row("Displacement, 99th percentile", [k.displacement_p99], (v) => fmt(v, 3), e, "99% of vertices moved less than this"),
    row("Displacement, max", [k.displacement_max], (v) => fmt(v, 3), e, "the vertex that moved most"),
    row("Drift, mean", [k.drift_mean], (v) => fmt(v, 3), e, "the smooth part of the displacement (folds filtered out): how much the garment's shape itself moved"),
    row("Drift, max", [k.drift_max], (v) => fmt(v, 3), e, "largest smooth displacement of a vertex"),
    row("Extent change", [k.extent_change], pct, "%", "largest change of the garment's size along an axis, relative to its largest extent"),
  ].concat(lostAreaRows((r.summary || {}).lost_area)));
}

// The lost-area bound's verdict on the frames: a capture that kept its folds has most of them given back.
function lostAreaRows(j) {
  if (!j) return [];
  const n = (v) => String(v);
  return [
    row("Frames kept whole", [j.frames_kept], n, "frames", "the deformation added surface where the capture had lost it, and stands whole"),
    row("Frames scaled", [j.frames_scaled], n, "frames", "only part of what the deformation added was surface the capture lost: scaled down"),
    row("Frames given back", [j.frames_given_back], n, "frames", "what the deformation added was not lost surface: the frame comes back as captured"),
    row("Lost share, median", [j.median_share], (v) => fmt(v, 2), "share", "of the surface a frame's deformation adds, the part the capture had lost (below 0.1: given back)"),
  ];
}

function stretchTables(r) {
  const s = r.summary || {};
  const a = s.stretch_after_positioning, f = s.stretch_final;
  const passes = (r.parameters || {}).stretch_passes;
  const head = ["Figure", "After positioning", passes != null ? `Final (after ${passes} stretch pass${passes === 1 ? "" : "es"})` : "Final", "Unit", "What it means"];
  const both = (k) => (a && f ? [a[k], f[k]] : [undefined]);
  const perTri = a && f ? figures("report-stretch", [
    row("L2 stretch", both("l2"), (v) => fmt(v, 6), "ratio (1 = none)", "Sander et al.'s area-weighted stretch of the whole sequence"),
    row("Max", both("max"), pct, "%", "the most stretched triangle of any frame"),
    row("99th percentile", both("p99"), pct, "%", "99% of triangles are stretched less than this"),
    row("Mean", both("mean"), pct, "%", "area-weighted mean stretch of a triangle"),
  ], head) : null;
  const vr = s.stretch_vs_rest && s.stretch_vs_rest.final;
  const rest = vr ? figures("report-stretch-rest", [
    row("Edge tension, 99th percentile", [vr.p99], pct, "%", "99% of edge samples are stretched less than this beyond their rest length"),
    row("Edge tension, max", [vr.max], pct, "%", "the most stretched edge of any frame"),
    row("Edge tension, mean", [vr.mean], pct, "%", "mean tension over all edges and frames (compressed edges count as 0)"),
    row("Edges over 1%", [vr.above_1pct], pct, "% of edge samples", "edges stretched by more than 1% beyond their rest length"),
  ]) : null;
  return [
    s.stretch_reference ? el("p", { class: "muted", text: `Stretch per triangle: ${s.stretch_reference}.` }) : null,
    perTri,
    vr && s.stretch_vs_rest.reference ? el("p", { class: "muted", text: `Edge tension against rest lengths: ${s.stretch_vs_rest.reference}.` }) : null,
    rest,
  ];
}

function foldsTable(r) {
  const d = r.fold_detection;
  if (!d) return null;
  const pf = Array.isArray(d.per_frame) ? d.per_frame : [];
  const col = (k) => pf.map((x) => x[k]);
  const tv = d.tracked_vertices || {};
  return figures("report-folds", [
    ["Detector", d.source, "", "where the folds were found: the capture video or the geometry alone"],
    row("Anchors", [d.anchors], int, "anchor triangles", "detected over the whole sequence"),
    row("Folds", [pf.length && pf.some((x) => isNum(x.folds)) ? sum(col("folds")) : undefined], int, "folds", "summed over frames: folds traced (geometry) or edge pairs projected onto the mesh (video)"),
    row("Control lines", [pf.length ? sum(col("control_lines")) : undefined], int, "polylines", "summed over frames: the lines the folds were traced along"),
    row("Seeds tried", [pf.some((x) => isNum(x.seeds_tried)) ? sum(col("seeds_tried")) : undefined], int, "seeds", "summed over frames: places a fold was looked for"),
    row("Frames traced again", [d.retraced_frames], int, "frames", "frames whose tracing was redone to agree with their neighbours' chunks"),
    row("Detection time", [pf.length ? sum(col("detection_seconds")) : undefined], secs, "s (work)", "seconds spent detecting, summed over the detection tasks"),
    row("Cameras", [d.cameras], int, "cameras", "calibrated views the video detector read"),
    row("Tracked vertices, front", [tv.front], int, "vertices", "vertices the video detector followed on the front"),
    row("Tracked vertices, back", [tv.back], int, "vertices", "vertices the video detector followed on the back"),
  ]);
}

function solverTable(r) {
  const w = ((r.report || {}).windows) || [];
  const p = r.parameters || {};
  if (!w.length && !Object.keys(p).length) return null;
  const col = (k) => w.map((x) => x[k]);
  return figures("report-solver", [
    ["Weight mode", p.mode, "", "fused: one 3-column solve per window; per-anchor: one column per anchor"],
    row("Windows", [w.length || undefined], int, "windows", `overlapping spans of frames solved together (${p.window ?? "?"} frames, shifted by ${p.shift ?? "?"})`),
    row("CG iterations", w.length ? [sum(col("cg_iterations"))] : [undefined], int, "iterations", "conjugate-gradient iterations of the weight solves, summed over windows"),
    row("CG iterations, largest window", w.length ? [max(col("cg_iterations"))] : [undefined], int, "iterations", `the window that needed most (limit ${p.cg_max_iterations ?? "?"})`),
    row("Largest relative residual", w.length ? [max(col("max_relative_residual"))] : [undefined], (v) => fmt(v, 3), "ratio", `how far the worst solve is from exact (tolerance ${p.cg_tolerance ?? "?"})`),
    row("Anchor blocks", w.length ? [sum(col("blocks"))] : [undefined], int, "blocks", "anchor blocks solved, summed over windows"),
    row("Node updates", w.some((x) => x.node_updates > 0) ? [sum(col("node_updates"))] : [undefined], int, "updates", "per-anchor mode's work: vertex updates over all columns"),
    row("Stretch passes", [p.stretch_passes], int, "passes", "stretch-reduction passes after positioning"),
  ]);
}

function timingTable(r) {
  const s = r.summary || {};
  const t = s.seconds_per_frame;
  if (!t) return null;
  const unit = "s / frame";
  const rows = [
    row("Weights", [t.weights], secs, unit, "solving the anchors' rotations over each window (space-time weights)"),
    row("Blend", [t.blend], secs, unit, "blending the weights into each triangle's target rotation"),
    row("Factor", [t.factor], secs, unit, "factorising each frame's positioning matrix"),
    row("Position", [t.position], secs, unit, "the first positioning solve of each frame"),
  ];
  (t.stretch_passes || []).forEach((v, k) => rows.push(row(`Stretch pass ${k + 1}`, [v], secs, unit, "one stretch-reduction pass (rotations + solve with the reused factor)")));
  rows.push(row("Pictures", [s.preview_seconds], secs, "s", "drawing preview.png and stretch.png"));
  return [
    figures("report-timings", rows),
    s.timings_note ? el("p", { class: "muted", text: `Timings are ${s.timings_note}.` }) : null,
  ];
}

function evalTables(e) {
  const o = e.output || {}, b = e.captured_baseline || {};
  const head = ["Figure", "Output", "Captured input", "Unit", "What it means"];
  const two = (k) => [o[k], b[k] === undefined ? "" : b[k]];
  const main = figures("report-eval", [
    row("Fold-signal correlation", two("correlation"), (v) => fmt(v, 3), "−1 … 1", "how well the fold signal (bending) matches the ground truth's, vertex by vertex"),
    row("Fold-region kappa", two("kappa"), (v) => fmt(v, 3), "−1 … 1", "agreement on where the folds are (Cohen's kappa of the fold regions)"),
    row("Fold-region IoU, dilated", two("iou_dilated"), (v) => fmt(v, 3), "0 … 1", "overlap of the fold regions, allowing one ring of tolerance"),
    row("Normal error", two("normal_error_deg"), (v) => fmt(v, 3), "degrees", "mean angle between the surface normals and the ground truth's"),
    row("Temporal popping", two("popping"), (v) => fmt(v, 3), "ratio (ground truth = 1)", "how much the fold signal flickers from frame to frame, relative to the ground truth"),
    row("Fold-region fraction", two("fold_fraction"), pct, "% of vertices", `vertices in a fold region (signal above ${e.threshold_deg}°); ground truth: ${pct(e.gt_fold_fraction)}%`),
  ], head);
  const so = (e.shape || {}).output, sg = (e.shape || {}).ground_truth;
  const shape = so && sg ? figures("report-eval-shape", [
    row("Displacement, mean", [so.displacement_mean, sg.displacement_mean], (v) => fmt(v, 3), "mean edge lengths", "distance from the captured input, on average"),
    row("Displacement, max", [so.displacement_max, sg.displacement_max], (v) => fmt(v, 3), "mean edge lengths", "largest distance from the captured input"),
    row("Drift, mean", [so.drift_mean, sg.drift_mean], (v) => fmt(v, 3), "mean edge lengths", "the smooth part of that distance: the shape itself moving"),
    row("Extent change", [so.extent_change, sg.extent_change], pct, "%", "largest change of size along an axis"),
  ], ["Figure", "Output", "Ground truth", "Unit", "What it means"]) : null;
  return [main, shape];
}

function charts(r, e, meta) {
  const out = [];
  const fs = ((r.report || {}).frame_stretch) || [];
  if (fs.length) {
    const first = fs.map((f) => f[0] && f[0].p99), last = fs.map((f) => f[f.length - 1] && f[f.length - 1].p99);
    const lastMax = fs.map((f) => f[f.length - 1] && f[f.length - 1].max);
    out.push(lineChart({
      id: "chart-stretch", title: "Stretch per frame", unit: "%",
      meaning: "per-triangle stretch against the captured frame: 99th percentile after positioning and at the end, and the largest",
      format: (v) => fmt(100 * v, 3),
      series: [{ label: "p99 after positioning", values: first, dash: true }, { label: "p99 final", values: last }, { label: "max final", values: lastMax }],
    }));
  }
  const pf = r.fold_detection && Array.isArray(r.fold_detection.per_frame) ? r.fold_detection.per_frame : null;
  const anchors = pf ? pf.map((x) => x.anchors) : meta && meta.anchors ? meta.anchors.per_frame : null;
  if (anchors && anchors.length) {
    const series = [{ label: "anchors", values: anchors }];
    if (pf && pf.some((x) => isNum(x.folds))) series.push({ label: "folds", values: pf.map((x) => x.folds) });
    out.push(lineChart({ id: "chart-anchors", title: "Anchors per frame", unit: "count",
      meaning: pf ? "anchor triangles the detector placed in each frame (after settling), and the folds it found" : "anchor triangles of each frame in the anchors file",
      series }));
  }
  if (pf && pf.some((x) => isNum(x.detection_seconds))) {
    out.push(lineChart({ id: "chart-detection", title: "Detection time per frame", unit: "s",
      meaning: "work seconds of fold detection; a task's time is spread evenly over the frames it detected",
      series: [{ label: "detection seconds", values: pf.map((x) => x.detection_seconds) }] }));
  }
  const ef = e && Array.isArray(e.per_frame) ? e.per_frame : null;
  if (ef && ef.length) {
    out.push(lineChart({ id: "chart-eval-correlation", title: "Fold-signal correlation per frame", unit: "correlation",
      meaning: "crease eval: the output's fold signal against the ground truth's (1 = identical)",
      series: [{ label: "correlation", values: ef.map((x) => x.correlation) }, { label: "kappa", values: ef.map((x) => x.kappa) }] }));
    out.push(lineChart({ id: "chart-eval-normals", title: "Normal error per frame", unit: "degrees",
      meaning: "crease eval: mean angle to the ground truth's normals, output against the captured input",
      series: [{ label: "output", values: ef.map((x) => x.normal_error_deg) }, { label: "captured input", values: ef.map((x) => x.captured_normal_error_deg), dash: true }] }));
  }
  return out;
}

// The report section: `r` is report.json (or null), `e` eval.json (or null), `meta` the viewer's meta.json
// (or null), `base` the URL prefix of the raw files.
export function renderReport(r, e, meta, base) {
  const links = el("p", { class: "raw" }, document.createTextNode("Raw JSON: "));
  if (r) links.append(el("a", { href: base + "report.json", target: "_blank", rel: "noopener", id: "raw-report", text: "report.json" }));
  if (e) links.append(document.createTextNode(" · "), el("a", { href: base + "eval.json", target: "_blank", rel: "noopener", id: "raw-eval", text: "eval.json" }));
  const parts = [];
  if (r) {
    if (r.complete !== true) parts.push(el("p", { class: "error", text: "report.json does not say the output is complete" }));
    parts.push(
      section("Sequence", sequenceTable(r)),
      section("Shape kept", shapeTable(r)),
      section("Stretch", ...stretchTables(r)),
      section("Folds", foldsTable(r)),
      section("Solver", solverTable(r)),
      section("Timings", ...(timingTable(r) || [])));
  }
  if (e) parts.push(section("Against ground truth (crease eval)", ...evalTables(e)));
  const plots = charts(r || {}, e, meta);
  if (plots.length) parts.push(el("section", { class: "report-part" }, el("h3", { text: "Per frame" }), el("div", { class: "charts" }, ...plots)));
  return el("div", { id: "report" }, links, ...parts.filter((p) => p != null));
}
