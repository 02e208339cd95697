// crease viewer: reads the server's per-frame buffers (layout in dashboard/src/viewer/frame_buffer.rs) and
// keeps them. The first frame asked for is fetched at once; the rest are fetched in the background, a few at a
// time, nearest to the frame shown first, so scrubbing and playing find them ready. Frames beyond a memory
// budget are dropped again, farthest from the frame shown first.
"use strict";

const MAGIC = 0x46565243; // "CRVF" read as a little-endian u32
const HEADER_WORDS = 10;
const HAS_INPUT = 1, HAS_OUTPUT = 2, HAS_DISPLACEMENT = 4, HAS_STRETCH = 8;

// Decodes one frame buffer into typed arrays over the same memory (no copies).
export function decodeFrame(buf) {
  if (buf.byteLength < HEADER_WORDS * 4) throw new Error(`frame buffer of ${buf.byteLength} bytes is truncated`);
  const h = new Uint32Array(buf, 0, HEADER_WORDS);
  if (h[0] !== MAGIC) throw new Error("not a viewer frame buffer (no CRVF magic)");
  if (h[1] !== 1) throw new Error(`frame buffer version ${h[1]}, this page reads 1`);
  const [frame, flags, v, t, a, l, p] = [h[2], h[3], h[4], h[5], h[6], h[7], h[8]];
  let at = HEADER_WORDS * 4;
  const take = (Type, n, what) => {
    if (at + 4 * n > buf.byteLength) throw new Error(`frame ${frame}: truncated in ${what}`);
    const arr = new Type(buf, at, n);
    at += 4 * n;
    return arr;
  };
  const f = { frame, vertices: v, triangles: t, bytes: buf.byteLength };
  f.input = flags & HAS_INPUT ? take(Float32Array, 3 * v, "input positions") : null;
  f.output = flags & HAS_OUTPUT ? take(Float32Array, 3 * v, "output positions") : null;
  f.displacement = flags & HAS_DISPLACEMENT ? take(Float32Array, v, "displacement") : null;
  f.stretch = flags & HAS_STRETCH ? take(Float32Array, t, "stretch") : null;
  f.anchors = take(Uint32Array, a, "anchors");
  f.lineLengths = take(Uint32Array, l, "control-line lengths");
  f.linePoints = take(Float32Array, 3 * p, "control-line points");
  if (at !== buf.byteLength) throw new Error(`frame ${frame}: ${buf.byteLength - at} bytes after the last section`);
  return f;
}

async function fetchBuffer(url) {
  const r = await fetch(url, { credentials: "same-origin" });
  if (r.status === 401) {
    location.href = "/login";
    throw new Error("not signed in");
  }
  if (!r.ok) {
    const body = await r.json().catch(() => ({}));
    throw new Error(body.error || `HTTP ${r.status}`);
  }
  return r.arrayBuffer();
}

export async function fetchJson(url) {
  const r = await fetch(url, { credentials: "same-origin", headers: { "Accept": "application/json" } });
  if (r.status === 401) {
    location.href = "/login";
    throw new Error("not signed in");
  }
  const body = await r.json().catch(() => ({ error: `HTTP ${r.status}` }));
  if (!r.ok) {
    const e = new Error(body.error || `HTTP ${r.status}`);
    e.status = r.status;
    throw e;
  }
  return body;
}

export class FrameStore {
  // base: ".../view/" URL prefix; n: frame count; budget: bytes of frames kept.
  constructor(base, n, budget) {
    this.base = base;
    this.n = n;
    this.budget = budget;
    this.frames = new Map(); // frame -> decoded
    this.pending = new Map(); // frame -> promise
    this.bytes = 0;
    this.focus = 0;
    this.stopped = false;
    this.onload = null; // called with each frame as it arrives
    this.errors = [];
  }

  get(t) {
    return this.frames.get(t) || null;
  }

  load(t) {
    if (this.frames.has(t)) return Promise.resolve(this.frames.get(t));
    if (this.pending.has(t)) return this.pending.get(t);
    const p = fetchBuffer(`${this.base}frame-${t}.bin`).then((buf) => {
      const f = decodeFrame(buf);
      this.pending.delete(t);
      if (this.stopped) return f;
      this.frames.set(t, f);
      this.bytes += f.bytes;
      this.evict();
      if (this.onload) this.onload(f);
      return f;
    }, (e) => {
      this.pending.delete(t);
      this.errors.push(`frame ${t}: ${e.message}`);
      throw e;
    });
    this.pending.set(t, p);
    return p;
  }

  // Distance in frames from the focus, going round the end (playback loops).
  distance(t) {
    const d = Math.abs(t - this.focus);
    return Math.min(d, this.n - d);
  }

  evict() {
    if (this.bytes <= this.budget) return;
    const order = [...this.frames.keys()].sort((a, b) => this.distance(b) - this.distance(a));
    for (const t of order) {
      if (this.bytes <= this.budget || t === this.focus) break;
      this.bytes -= this.frames.get(t).bytes;
      this.frames.delete(t);
    }
  }

  // Fetches the frames not held yet, nearest the focus first, `parallel` at a time, while they fit the budget.
  async prefetch(parallel) {
    const order = [...Array(this.n).keys()].sort((a, b) => this.distance(a) - this.distance(b));
    const avg = () => (this.frames.size ? this.bytes / this.frames.size : 0);
    let next = 0;
    const worker = async () => {
      while (!this.stopped && next < order.length) {
        const t = order[next++];
        if (this.frames.has(t)) continue;
        if (this.bytes + avg() > this.budget) return;
        try { await this.load(t); } catch (_) { /* kept in errors; the viewer shows it */ }
      }
    };
    await Promise.all([...Array(parallel)].map(worker));
  }

  stop() {
    this.stopped = true;
  }
}
