"""Load time and frame rate of the 3D viewer (`crease view`) in headless Chromium.

Starts `crease view FOLDER` on a free loopback port, then, `--runs` times each in a fresh browser profile (no
HTTP cache):

  * reference: every frame buffer (`frame-N.bin`) fetched one after the other with Python's HTTP client, no
    browser: what the server alone costs per frame;
  * the page: from navigation to the first frame drawn, and to every frame held in the page;
  * playback, in the default view (side by side, smooth shading, anchors and control lines on): `--seconds` of
    playing as fast as frames can be shown (each animation frame shows the next sequence frame) at full
    resolution, the same with the viewer's half-resolution fallback allowed, the output view alone at full
    resolution, and `--seconds` at the viewer's default 24 fps (side by side, fallback allowed), counting frames shown and stalls (a frame due but not loaded yet).

Prints one JSON object with every run and the medians, plus the ratio of the page's all-frames time to the
reference fetch. Needs scripts/setup-tools (Playwright in .tools/venv) and /usr/bin/chromium; run it with
.tools/venv/bin/python. WebGL runs on SwiftShader (the CPU), so frame rates are a floor for a machine with a GPU.

    .tools/venv/bin/python bench/viewer_load.py --crease target/release/crease --folder OUT [--runs 3]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
import urllib.request

# The browser tests' Chromium: the same flags (SwiftShader WebGL), a fresh profile per run.
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "tests", "browser"))
import chromium  # noqa: E402


def start_view(crease, folder):
    p = subprocess.Popen([crease, "view", folder, "--listen", "127.0.0.1:0"], stdout=subprocess.PIPE,
                         stderr=subprocess.DEVNULL, text=True)
    deadline = time.time() + 60
    while time.time() < deadline:
        line = p.stdout.readline()
        if not line:
            break
        if line.startswith("viewer listening on "):
            return p, line.split("viewer listening on ", 1)[1].strip()
    p.kill()
    sys.exit("crease view printed no URL")


def reference_fetch(base, frames):
    """Seconds to fetch every frame buffer in order, and the bytes fetched."""
    t0 = time.perf_counter()
    total = 0
    for t in range(frames):
        with urllib.request.urlopen(f"{base}frame-{t}.bin") as r:
            total += len(r.read())
    return time.perf_counter() - t0, total


def page_run(url, seconds):
    with chromium.page(1280, 900) as (page, errors):
        page.set_default_timeout(600_000)
        page.goto(url)
        page.wait_for_selector("#viewer[data-ready=true]")
        n = page.evaluate("window.__creaseViewer.meta.frames")
        page.wait_for_function("(n) => window.__creaseViewer.store.frames.size === n", arg=n, polling=100)
        s = page.evaluate("""() => { const v = window.__creaseViewer;
            return { t0: v.t0, first: v.stats.first_frame_ms, all: v.stats.all_frames_ms, opened: v.stats.opened_ms,
                     renderer: (() => { const g = v.renderer.getContext(); const i = g.getExtension('WEBGL_debug_renderer_info');
                                        return i ? g.getParameter(i.UNMASKED_RENDERER_WEBGL) : ''; })() }; }""")
        full = page.evaluate("(ms) => { window.__creaseViewer.adaptive = false; return window.__creaseViewer.measure(ms); }",
                             int(1000 * seconds))
        fast = page.evaluate("(ms) => { window.__creaseViewer.adaptive = true; return window.__creaseViewer.measure(ms); }",
                             int(1000 * seconds))
        page.select_option("#view-mode", "output")
        single = page.evaluate("(ms) => { window.__creaseViewer.adaptive = false; return window.__creaseViewer.measure(ms); }",
                               int(1000 * seconds))
        page.select_option("#view-mode", "side")
        page.evaluate("() => { window.__creaseViewer.adaptive = true; }")
        paced = page.evaluate("""(ms) => new Promise((resolve) => { const v = window.__creaseViewer;
            const shown0 = v.stats.shown, stalls0 = v.stats.stalls, t0 = performance.now(); v.play();
            setTimeout(() => { v.pause(); const secs = (performance.now() - t0) / 1000;
              resolve({ seconds: secs, fps: (v.stats.shown - shown0) / secs, stalls: v.stats.stalls - stalls0 }); }, ms); })""",
                              int(1000 * seconds))
        if errors:
            sys.exit(f"console errors: {errors}")
    return {
        "frames": n,
        "page_to_viewer_ms": s["t0"],
        "meta_and_index_ms": s["opened"],
        "first_frame_ms": s["t0"] + s["first"],
        "all_frames_ms": s["t0"] + s["all"] if s["all"] is not None else None,
        "fps_full_resolution": full["fps"],
        "fps_output_only": single["fps"],
        "fps_max_speed": fast["fps"],
        "fps_at_24": paced["fps"],
        "stalls_at_24": paced["stalls"],
        "renderer": s["renderer"],
    }


def main():
    a = argparse.ArgumentParser()
    a.add_argument("--crease", required=True)
    a.add_argument("--folder", required=True)
    a.add_argument("--runs", type=int, default=3)
    a.add_argument("--seconds", type=float, default=5.0)
    a = a.parse_args()
    proc, url = start_view(a.crease, a.folder)
    try:
        base = url.split("#")[0] + "api/jobs/local/view/"
        meta = json.load(urllib.request.urlopen(base + "meta.json"))
        runs, refs = [], []
        for _ in range(a.runs):
            secs, size = reference_fetch(base, meta["frames"])
            refs.append({"seconds": secs, "bytes": size})
            runs.append(page_run(url, a.seconds))
        med = lambda k, rows: statistics.median(r[k] for r in rows if r[k] is not None)
        out = {
            "folder": a.folder, "frames": meta["frames"], "vertices": meta["vertices"],
            "triangles": meta["triangles"], "runs": runs, "reference_fetch": refs,
            "median": {k: med(k, runs) for k in ("first_frame_ms", "all_frames_ms", "fps_full_resolution",
                                                  "fps_output_only", "fps_max_speed", "fps_at_24", "stalls_at_24")},
            "median_reference_fetch_ms": 1000 * med("seconds", refs),
            "bytes_per_frame": refs[0]["bytes"] / meta["frames"],
        }
        out["all_frames_vs_reference"] = out["median"]["all_frames_ms"] / out["median_reference_fetch_ms"]
        print(json.dumps(out, indent=1))
    finally:
        proc.kill()


if __name__ == "__main__":
    main()
