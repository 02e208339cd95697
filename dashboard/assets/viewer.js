// crease viewer: the captured input and crease's output of one sequence, drawn with three.js from the
// server's per-frame buffers (frames.js). Both are seen through one camera: side by side, with a wipe between
// them, or one at a time. Overlays: the fold anchors (a dot per anchor triangle), the control lines the folds
// were traced along, and the output coloured by stretch or by displacement, both computed by the server with
// the definitions report.json uses.
import * as THREE from "/assets/three.min.js";
import { el } from "/assets/dom.js";
import { FrameStore, fetchJson } from "/assets/frames.js";

const LAYER_INPUT = 1, LAYER_OUTPUT = 2;
// Frames kept in the page; beyond this the farthest from the frame shown are dropped and fetched again.
const FRAME_BUDGET_BYTES = 512 << 20;
const PREFETCH_PARALLEL = 3;
const FPS_CHOICES = [6, 12, 24, 30, 60];

// Stretch colours of crease's own pictures (crease_core::render::stretch_color), so preview.png and the
// viewer read alike; displacement on a blue scale.
const STRETCH_STOPS = [[0, [232, 232, 232]], [0.3, [250, 222, 96]], [0.65, [238, 128, 40]], [1, [186, 22, 28]]];
const DISPLACEMENT_STOPS = [[0, [232, 232, 232]], [0.35, [140, 190, 230]], [0.7, [40, 110, 200]], [1, [30, 30, 120]]];
const BASE_INPUT = [170, 186, 205];
const BASE_OUTPUT = [214, 200, 180];

function srgbToLinear(c) {
  const x = c / 255;
  return x <= 0.04045 ? x / 12.92 : Math.pow((x + 0.055) / 1.055, 2.4);
}

// 256-entry colour table of a map, in linear RGB (what three.js expects of vertex colours).
function table(stops) {
  const out = new Float32Array(256 * 3);
  for (let i = 0; i < 256; i++) {
    const t = i / 255;
    let k = 0;
    while (k < stops.length - 2 && t > stops[k + 1][0]) k++;
    const [t0, c0] = stops[k], [t1, c1] = stops[k + 1];
    const f = Math.min(1, Math.max(0, (t - t0) / (t1 - t0)));
    for (let j = 0; j < 3; j++) out[3 * i + j] = srgbToLinear(c0[j] + (c1[j] - c0[j]) * f);
  }
  return out;
}

const STRETCH_TABLE = table(STRETCH_STOPS);
const DISPLACEMENT_TABLE = table(DISPLACEMENT_STOPS);

// A round number at or above x (1, 2 or 5 times a power of ten), for legend scales.
function niceCeil(x) {
  if (!(x > 0) || !isFinite(x)) return 1;
  const p = Math.pow(10, Math.floor(Math.log10(x)));
  for (const m of [1, 2, 5, 10]) if (m * p >= x) return m * p;
  return 10 * p;
}

// The 99th percentile of an array (a sample of at most 20000 values is enough for a legend's scale).
function p99(values) {
  const n = values.length;
  if (!n) return 0;
  const step = Math.max(1, Math.floor(n / 20000));
  const s = [];
  for (let i = 0; i < n; i += step) s.push(values[i]);
  s.sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.floor(0.99 * s.length))];
}

function gradientCss(stops) {
  return "linear-gradient(to right, " + stops.map(([t, c]) => `rgb(${c.join(",")}) ${(100 * t).toFixed(0)}%`).join(", ") + ")";
}

class MeshView {
  // One drawn sequence (input or output): its mesh, anchor dots and colours, on its own layer.
  constructor(scene, index, vertices, layer, base, flat) {
    this.layer = layer;
    this.base = base.map(srgbToLinear);
    this.geometry = new THREE.BufferGeometry();
    this.geometry.setIndex(index);
    this.positions = new THREE.BufferAttribute(new Float32Array(3 * vertices), 3);
    this.positions.setUsage(THREE.DynamicDrawUsage);
    this.colors = new THREE.BufferAttribute(new Float32Array(3 * vertices), 3);
    this.colors.setUsage(THREE.DynamicDrawUsage);
    this.geometry.setAttribute("position", this.positions);
    this.geometry.setAttribute("color", this.colors);
    this.material = new THREE.MeshStandardMaterial({
      vertexColors: true, side: THREE.DoubleSide, flatShading: flat, roughness: 0.85, metalness: 0.0,
    });
    this.mesh = new THREE.Mesh(this.geometry, this.material);
    this.mesh.frustumCulled = false;
    this.mesh.layers.set(layer);
    scene.add(this.mesh);
    this.dots = new THREE.Points(new THREE.BufferGeometry(), new THREE.PointsMaterial({
      color: 0xd0163a, size: 5, sizeAttenuation: false, depthTest: true,
    }));
    this.dots.frustumCulled = false;
    this.dots.layers.set(layer);
    this.dotCapacity = 0;
    scene.add(this.dots);
    this.paint(null, null, 0);
  }

  setPositions(p, smooth) {
    this.positions.array.set(p);
    this.positions.needsUpdate = true;
    if (smooth) this.geometry.computeVertexNormals();
  }

  setShading(flat) {
    this.material.flatShading = flat;
    this.material.needsUpdate = true;
    if (!flat) this.geometry.computeVertexNormals();
  }

  // Colours each vertex from `values` (0..scale) through `lut`, or plain when values is null.
  paint(values, lut, scale) {
    const c = this.colors.array;
    const n = c.length / 3;
    // Plain colours do not change from frame to frame: paint (and upload) them once.
    if (!values && this.plain) return;
    this.plain = !values;
    if (!values) {
      for (let i = 0; i < n; i++) { c[3 * i] = this.base[0]; c[3 * i + 1] = this.base[1]; c[3 * i + 2] = this.base[2]; }
    } else {
      const k = scale > 0 ? 255 / scale : 0;
      for (let i = 0; i < n; i++) {
        const j = 3 * Math.min(255, Math.max(0, Math.round(values[i] * k)));
        c[3 * i] = lut[j]; c[3 * i + 1] = lut[j + 1]; c[3 * i + 2] = lut[j + 2];
      }
    }
    this.colors.needsUpdate = true;
  }

  // A dot at the centroid of every anchor triangle, on this mesh's current positions.
  setDots(anchors, index, visible) {
    this.dots.visible = visible && anchors.length > 0;
    if (!this.dots.visible) return;
    if (anchors.length > this.dotCapacity) {
      this.dots.geometry.dispose();
      this.dotCapacity = Math.max(anchors.length, 2 * this.dotCapacity);
      this.dots.geometry = new THREE.BufferGeometry();
      const attr = new THREE.BufferAttribute(new Float32Array(3 * this.dotCapacity), 3);
      attr.setUsage(THREE.DynamicDrawUsage);
      this.dots.geometry.setAttribute("position", attr);
    }
    const out = this.dots.geometry.getAttribute("position");
    const d = out.array, p = this.positions.array;
    for (let a = 0; a < anchors.length; a++) {
      const t = anchors[a];
      for (let j = 0; j < 3; j++) {
        d[3 * a + j] = (p[3 * index[3 * t] + j] + p[3 * index[3 * t + 1] + j] + p[3 * index[3 * t + 2] + j]) / 3;
      }
    }
    out.needsUpdate = true;
    this.dots.geometry.setDrawRange(0, anchors.length);
  }
}

// Polylines as line segments, drawn in both views (they are positions in space, not on one mesh).
class Lines {
  constructor(scene) {
    this.lines = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0x1536c8 }));
    this.lines.frustumCulled = false;
    this.lines.layers.set(LAYER_INPUT);
    this.lines.layers.enable(LAYER_OUTPUT);
    this.capacity = 0;
    scene.add(this.lines);
  }

  set(lengths, points, visible) {
    let segments = 0;
    for (const n of lengths) segments += Math.max(0, n - 1);
    this.lines.visible = visible && segments > 0;
    if (!this.lines.visible) return;
    if (segments > this.capacity) {
      this.lines.geometry.dispose();
      this.capacity = Math.max(segments, 2 * this.capacity);
      this.lines.geometry = new THREE.BufferGeometry();
      const attr = new THREE.BufferAttribute(new Float32Array(6 * this.capacity), 3);
      attr.setUsage(THREE.DynamicDrawUsage);
      this.lines.geometry.setAttribute("position", attr);
    }
    const out = this.lines.geometry.getAttribute("position");
    const o = out.array;
    let at = 0, p = 0;
    for (const n of lengths) {
      for (let i = 0; i + 1 < n; i++) {
        for (let j = 0; j < 6; j++) o[at + j] = points[3 * (p + i) + j];
        at += 6;
      }
      p += n;
    }
    out.needsUpdate = true;
    this.lines.geometry.setDrawRange(0, 2 * segments);
  }
}

export class Viewer {
  constructor(container, base) {
    this.container = container;
    this.base = base;
    this.stats = { opened_ms: null, first_frame_ms: null, all_frames_ms: null, frames_loaded: 0, stalls: 0, shown: 0 };
    this.t0 = performance.now();
    this.frame = 0;
    this.playing = false;
    this.dirty = true;
    this.raf = null;
    this.destroyed = false;
    // Whether playback may lower the resolution to keep up (see keepUp).
    this.adaptive = true;
  }

  async open() {
    const [meta, index] = await Promise.all([
      fetchJson(this.base + "meta.json"),
      fetch(this.base + "index.bin", { credentials: "same-origin" }).then((r) => {
        if (!r.ok) throw new Error(`index.bin: HTTP ${r.status}`);
        return r.arrayBuffer();
      }),
    ]);
    this.meta = meta;
    this.index = new Uint32Array(index);
    if (this.index.length !== 3 * meta.triangles) throw new Error(`index.bin holds ${this.index.length / 3} triangles, meta.json says ${meta.triangles}`);
    this.stats.opened_ms = performance.now() - this.t0;
    this.build();
    this.store = new FrameStore(this.base, meta.frames, FRAME_BUDGET_BYTES);
    this.store.onload = () => { this.stats.frames_loaded = this.store.frames.size; this.updateLoaded(); };
    const first = await this.store.load(0);
    this.initScales(first);
    this.show(0);
    this.renderNow();
    this.stats.first_frame_ms = performance.now() - this.t0;
    this.container.dataset.ready = "true";
    this.store.prefetch(PREFETCH_PARALLEL).then(() => {
      if (this.store.frames.size === meta.frames) this.stats.all_frames_ms = performance.now() - this.t0;
      this.updateLoaded();
    });
    return this;
  }

  // ------------------------------------------------------------ DOM and three.js objects

  build() {
    const m = this.meta;
    const hasIn = !!m.input, hasOut = !!m.output;
    const modes = [];
    if (hasIn && hasOut) modes.push(["side", "Side by side"], ["wipe", "Wipe"]);
    if (hasIn) modes.push(["input", hasOut ? "Input (captured)" : "Sequence"]);
    if (hasOut) modes.push(["output", "Output (crease)"]);
    this.mode = modes[0][0];
    const option = ([v, label]) => el("option", { value: v, text: label });
    const check = (id, label, on, enabled) => el("label", { class: enabled ? "" : "muted" },
      el("input", { type: "checkbox", id, checked: on && enabled, disabled: !enabled, onchange: () => this.refresh() }),
      document.createTextNode(" " + label));
    const ov = m.overlays;
    const colours = [["none", "plain"]];
    if (ov.stretch) colours.push(["stretch", "stretch"]);
    if (ov.displacement) colours.push(["displacement", "displacement"]);

    this.ui = {
      play: el("button", { id: "view-play", type: "button", text: "Play", onclick: () => this.toggle() }),
      scrub: el("input", { id: "view-frame", type: "range", min: 0, max: m.frames - 1, step: 1, value: 0,
        oninput: (e) => { this.pause(); this.show(+e.target.value); } }),
      label: el("span", { id: "view-frame-label", class: "num" }),
      loaded: el("span", { id: "view-loaded", class: "muted" }),
      mode: el("select", { id: "view-mode", onchange: (e) => { this.mode = e.target.value; this.layout(); this.place(); this.refresh(); } }, ...modes.map(option)),
      shading: el("select", { id: "view-shading", onchange: (e) => this.setShading(e.target.value === "flat") },
        option(["smooth", "smooth shading"]), option(["flat", "flat shading"])),
      colour: el("select", { id: "view-colour", onchange: () => this.refresh() }, ...colours.map(option)),
      fps: el("select", { id: "view-fps", onchange: (e) => { this.fps = +e.target.value; } },
        ...FPS_CHOICES.map((f) => el("option", { value: f, text: `${f} fps`, selected: f === 24 }))),
      anchors: check("ov-anchors", "anchors", true, ov.anchors),
      lines: check("ov-lines", "control lines", true, ov.control_lines),
      wipe: el("input", { id: "view-wipe", type: "range", min: 0, max: 1000, value: 500, class: "wipe",
        oninput: () => this.requestRender() }),
      legend: el("div", { id: "view-legend", class: "legend" }),
      labels: el("div", { class: "view-labels" }),
      canvasBox: el("div", { class: "canvas-box" }),
      status: el("div", { id: "view-status", class: "muted" }),
    };
    this.fps = 24;
    this.ui.shading.value = "smooth";
    const u = this.ui;
    const notes = (m.notes || []).map((n) => el("li", { text: n }));
    this.container.replaceChildren(...[
      el("div", { class: "viewer-bar" }, u.play, u.scrub, u.label, u.fps, u.loaded),
      el("div", { class: "viewer-bar" }, u.mode, u.shading, el("span", { text: "colour:" }), u.colour, u.anchors, u.lines),
      u.canvasBox,
      u.wipe,
      u.legend,
      u.status,
      notes.length ? el("ul", { class: "notes" }, ...notes) : null].filter((x) => x != null));

    this.renderer = new THREE.WebGLRenderer({ antialias: false, preserveDrawingBuffer: true });
    this.fullRatio = Math.min(2, window.devicePixelRatio || 1);
    this.renderer.setPixelRatio(this.fullRatio);
    this.renderer.setClearColor(0xf6f7f9, 1);
    this.canvas = this.renderer.domElement;
    this.canvas.id = "view-canvas";
    u.canvasBox.append(this.canvas, u.labels);

    const scene = this.scene = new THREE.Scene();
    const index = new THREE.BufferAttribute(this.index, 1);
    this.input = hasIn ? new MeshView(scene, index, m.vertices, LAYER_INPUT, BASE_INPUT, false) : null;
    this.output = hasOut ? new MeshView(scene, index, m.vertices, LAYER_OUTPUT, BASE_OUTPUT, false) : null;
    this.lines = new Lines(scene);
    const camera = this.camera = new THREE.PerspectiveCamera(30, 1, m.radius / 100, m.radius * 100);
    const [dx, dy, dz] = m.camera.direction;
    camera.up.set(...m.camera.up);
    const dist = 1.15 * m.radius / Math.sin(THREE.MathUtils.degToRad(15));
    camera.position.set(-dx * dist, -dy * dist, -dz * dist);
    camera.lookAt(0, 0, 0);
    scene.add(camera);
    const hemi = new THREE.HemisphereLight(0xffffff, 0x667080, 1.4);
    hemi.up = camera.up.clone();
    hemi.position.copy(camera.up);
    const key = new THREE.DirectionalLight(0xffffff, 1.6);
    key.position.set(0.4, 0.6, 1);
    camera.add(key);
    for (const l of [hemi, key]) l.layers.enableAll();
    scene.add(hemi);
    this.controls = new THREE.OrbitControls(camera, this.canvas);
    this.controls.target.set(0, 0, 0);
    this.controls.addEventListener("change", () => this.requestRender());
    this.controls.update();
    this.resizer = new ResizeObserver(() => this.layout());
    this.resizer.observe(u.canvasBox);
    this.layout();
  }

  // Sets the canvas size (the box's, from the style sheet) and the view labels for the mode.
  layout() {
    const w = Math.max(1, this.ui.canvasBox.clientWidth), h = Math.max(1, this.ui.canvasBox.clientHeight);
    this.renderer.setSize(w, h);
    this.ui.wipe.hidden = this.mode !== "wipe";
    const label = (text, cls) => el("span", { class: "view-label " + cls, text });
    const labels = {
      side: [label("Input (captured)", "left"), label("Output (crease)", "right")],
      wipe: [label("◀ Output (crease)", "left"), label("Input (captured) ▶", "right")],
      input: [label(this.output ? "Input (captured)" : "Sequence", "left")],
      output: [label("Output (crease)", "left")],
    }[this.mode];
    this.ui.labels.replaceChildren(...labels);
    this.requestRender();
  }

  initScales(f) {
    this.stretchScale = f.stretch ? niceCeil(Math.max(1e-4, p99(f.stretch))) : 0;
    this.displacementScale = f.displacement ? niceCeil(Math.max(1e-9, p99(f.displacement))) : 0;
    this.vertexValues = new Float32Array(this.meta.vertices);
  }

  // ------------------------------------------------------------ frames

  show(t) {
    this.want = t;
    const f = this.store.get(t);
    if (!f) {
      this.ui.status.textContent = `loading frame ${t + 1}…`;
      this.store.load(t).then(() => { if (this.want === t && !this.destroyed) this.show(t); },
        (e) => { this.ui.status.textContent = `frame ${t + 1}: ${e.message}`; });
      return false;
    }
    this.frame = t;
    this.store.focus = t;
    this.current = f;
    this.place();
    this.refresh();
    this.ui.scrub.value = String(t);
    this.ui.label.textContent = `frame ${t + 1} / ${this.meta.frames}`;
    this.ui.status.textContent = "";
    this.stats.shown++;
    return true;
  }

  // Puts the current frame's positions on the meshes in view (a hidden one is updated when it is shown).
  place() {
    const f = this.current;
    const smooth = this.ui.shading.value === "smooth";
    const shows = (which) => this.mode === "side" || this.mode === "wipe" || this.mode === which;
    for (const [mv, which, p] of [[this.input, "input", f.input], [this.output, "output", f.output]]) {
      if (!mv || !shows(which) || mv.frame === f.frame) continue;
      mv.setPositions(p, smooth);
      mv.frame = f.frame;
    }
  }

  // Re-applies the overlays to the current frame.
  refresh() {
    const f = this.current;
    if (!f) return;
    const colour = this.ui.colour.value;
    if (this.output) {
      if (colour === "stretch" && f.stretch) {
        // Per triangle on the wire; each vertex shows the largest stretch of the triangles around it, so a
        // single stretched triangle stays visible.
        const v = this.vertexValues.fill(0), idx = this.index, s = f.stretch;
        for (let k = 0; k < s.length; k++) {
          const x = s[k];
          for (let j = 0; j < 3; j++) { const i = idx[3 * k + j]; if (x > v[i]) v[i] = x; }
        }
        this.output.paint(v, STRETCH_TABLE, this.stretchScale);
      } else if (colour === "displacement" && f.displacement) {
        this.output.paint(f.displacement, DISPLACEMENT_TABLE, this.displacementScale);
      } else {
        this.output.paint(null, null, 0);
      }
    }
    const showDots = document.getElementById("ov-anchors")?.checked ?? false;
    const showLines = document.getElementById("ov-lines")?.checked ?? false;
    for (const mv of [this.input, this.output]) if (mv) mv.setDots(f.anchors, this.index, showDots);
    this.lines.set(f.lineLengths, f.linePoints, showLines);
    this.legend(colour);
    this.requestRender();
  }

  legend(colour) {
    const m = this.meta;
    const box = this.ui.legend;
    const pct = (x) => `${+(100 * x).toPrecision(3)}%`;
    const bar = (stops) => { const b = el("span", { class: "ramp" }); b.style.backgroundImage = gradientCss(stops); return b; };
    const parts = [];
    if (colour === "stretch") {
      parts.push(el("span", { text: "stretch 0" }), bar(STRETCH_STOPS), el("span", { text: `≥ ${pct(this.stretchScale)}` }),
        el("span", { class: "muted", text: ` — ${m.stretch_definition}; each vertex shows the largest of its triangles` }));
    } else if (colour === "displacement") {
      const edges = m.mean_edge > 0 ? ` (${+(this.displacementScale / m.mean_edge).toPrecision(3)} mean edge lengths)` : "";
      parts.push(el("span", { text: "displacement 0" }), bar(DISPLACEMENT_STOPS), el("span", { text: `≥ ${+this.displacementScale.toPrecision(3)}${edges}` }),
        el("span", { class: "muted", text: ` — ${m.displacement_definition}` }));
    }
    const f = this.current;
    if (f && (document.getElementById("ov-anchors")?.checked)) parts.push(el("span", { class: "dot", text: ` ● ${f.anchors.length} anchors` }));
    if (f && (document.getElementById("ov-lines")?.checked)) parts.push(el("span", { class: "line", text: ` ━ ${f.lineLengths.length} control lines` }));
    box.replaceChildren(...parts);
  }

  updateLoaded() {
    if (!this.store) return;
    const n = this.store.frames.size, total = this.meta.frames;
    const errs = this.store.errors.length ? ` · ${this.store.errors.length} failed (${this.store.errors[0]})` : "";
    this.ui.loaded.textContent = n === total ? `all ${total} frames loaded` : `${n}/${total} frames loaded${errs}`;
  }

  setShading(flat) {
    for (const mv of [this.input, this.output]) if (mv) mv.setShading(flat);
    this.requestRender();
  }

  // ------------------------------------------------------------ playback and drawing

  toggle() { if (this.playing) this.pause(); else this.play(); }

  play() {
    this.playing = true;
    this.ui.play.textContent = "Pause";
    this.lastAdvance = performance.now();
    this.ticks = [];
    this.loop();
  }

  pause() {
    this.playing = false;
    this.ui.play.textContent = "Play";
    if (this.renderer && this.renderer.getPixelRatio() !== this.fullRatio) {
      this.renderer.setPixelRatio(this.fullRatio);
      this.ui.status.textContent = "";
      this.requestRender();
    }
  }

  // Without a GPU (or with a slow one) a large mesh cannot be drawn at the frame rate asked for: after a few
  // frames that came late, playback draws at half the resolution, and the full picture comes back on pause.
  keepUp(now) {
    this.ticks.push(now);
    if (!this.adaptive || this.ticks.length < 9 || this.renderer.getPixelRatio() !== this.fullRatio) return;
    const recent = this.ticks.slice(-9);
    const interval = (recent[8] - recent[0]) / 8;
    const target = 1000 / (this.maxSpeed ? 60 : this.fps);
    if (interval > 1.25 * target) {
      this.renderer.setPixelRatio(this.fullRatio / 2);
      this.ui.status.textContent = `playing at half resolution to keep up (${(1000 / interval).toFixed(1)} frames/s at full)`;
      this.stats.reduced = true;
    }
  }

  requestRender() {
    this.dirty = true;
    this.loop();
  }

  loop() {
    if (this.raf !== null || this.destroyed) return;
    this.raf = requestAnimationFrame((now) => {
      this.raf = null;
      if (this.playing) {
        const step = this.maxSpeed ? 0 : 1000 / this.fps;
        if (now - this.lastAdvance >= step) {
          const next = (this.frame + 1) % this.meta.frames;
          if (this.store.get(next)) {
            this.show(next);
            this.keepUp(now);
            this.lastAdvance = this.maxSpeed ? now : Math.max(this.lastAdvance + step, now - step);
          } else {
            this.stats.stalls++;
            this.store.load(next).catch(() => {});
          }
        }
      }
      if (this.dirty) this.renderNow();
      if (this.playing) this.loop();
    });
  }

  renderNow() {
    this.dirty = false;
    const r = this.renderer, cam = this.camera;
    const size = r.getSize(new THREE.Vector2());
    const w = size.x, h = size.y;
    const draw = (layer, vx, vw, sx, sw) => {
      r.setViewport(vx, 0, vw, h);
      r.setScissor(sx, 0, sw, h);
      cam.layers.set(layer);
      r.render(this.scene, cam);
    };
    r.setScissorTest(true);
    if (this.mode === "side") {
      const half = Math.floor(w / 2);
      cam.aspect = half / h;
      cam.updateProjectionMatrix();
      draw(LAYER_INPUT, 0, half, 0, half);
      draw(LAYER_OUTPUT, half, w - half, half, w - half);
    } else {
      cam.aspect = w / h;
      cam.updateProjectionMatrix();
      if (this.mode === "wipe") {
        const split = Math.round(w * (+this.ui.wipe.value) / 1000);
        draw(LAYER_INPUT, 0, w, 0, w);
        if (split > 0) draw(LAYER_OUTPUT, 0, w, 0, split);
      } else {
        draw(this.mode === "input" ? LAYER_INPUT : LAYER_OUTPUT, 0, w, 0, w);
      }
    }
    r.setScissorTest(false);
    this.stats.renders = (this.stats.renders || 0) + 1;
  }

  // Plays as fast as frames can be shown for `ms` milliseconds (every animation frame shows the next
  // sequence frame) and says how many were shown per second: the viewer's playback rate on this machine.
  measure(ms) {
    return new Promise((resolve) => {
      const shown0 = this.stats.shown, stalls0 = this.stats.stalls, t0 = performance.now();
      this.maxSpeed = true;
      this.play();
      setTimeout(() => {
        this.pause();
        this.maxSpeed = false;
        const secs = (performance.now() - t0) / 1000;
        const shown = this.stats.shown - shown0;
        resolve({ seconds: secs, frames_shown: shown, fps: shown / secs, stalls: this.stats.stalls - stalls0 });
      }, ms);
    });
  }

  destroy() {
    this.destroyed = true;
    this.pause();
    if (this.raf !== null) cancelAnimationFrame(this.raf);
    if (this.store) this.store.stop();
    if (this.resizer) this.resizer.disconnect();
    if (this.controls) this.controls.dispose();
    if (this.renderer) this.renderer.dispose();
  }
}

// Opens a viewer in `container` on the view files under `base` (".../view/"). Errors are shown in the
// container and rethrown.
export async function openViewer(container, base) {
  container.replaceChildren(el("p", { class: "muted", text: "opening the viewer…" }));
  const v = new Viewer(container, base);
  window.__creaseViewer = v;
  try {
    return await v.open();
  } catch (e) {
    container.replaceChildren(el("p", { class: "error", id: "view-error", text: `viewer: ${e.message}` }));
    container.dataset.ready = "error";
    throw e;
  }
}
