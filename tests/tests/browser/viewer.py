"""Drives the crease 3D viewer in headless Chromium (Debian's /usr/bin/chromium through Playwright, WebGL
through SwiftShader) against servers that tests/tests/viewer_browser.rs started on 127.0.0.1: a coordinator's
dashboard with a finished job, and `crease view` on a local output folder and on an input folder alone.

Each step is an assertion on what the canvas shows, read back as pixels: the viewer of the finished job
renders (most of the canvas is not background), the first and the last frame differ, the input and output
views differ, each overlay (stretch colours, displacement colours, anchors, control lines) changes the
picture when switched on and back when switched off, flat and smooth shading differ; the report shows its
tables and charts and links the raw report.json. Screenshots go to --out. Prints a JSON summary; exits
non-zero with a message on the first failed step.
"""

import argparse
import json
import os
import sys

import chromium

BACKGROUND = (246, 247, 249)

# Reads the viewer's canvas back as a small RGBA image (the renderer keeps its drawing buffer).
SNAP = """() => {
  const c = document.getElementById('view-canvas');
  const t = document.createElement('canvas');
  t.width = 240; t.height = Math.max(1, Math.round(240 * c.height / c.width));
  const g = t.getContext('2d');
  g.drawImage(c, 0, 0, t.width, t.height);
  return { w: t.width, h: t.height, data: Array.from(g.getImageData(0, 0, t.width, t.height).data) };
}"""


def fail(msg):
    print(f"viewer browser test: FAILED: {msg}", file=sys.stderr)
    sys.exit(1)


def covered(img):
    """Fraction of pixels that are not the viewer's background."""
    d, n = img["data"], img["w"] * img["h"]
    hit = sum(1 for i in range(0, len(d), 4) if max(abs(d[i + k] - BACKGROUND[k]) for k in range(3)) > 12)
    return hit / n


def differ(a, b, level=16):
    """Fraction of pixels that differ by more than `level` in some channel."""
    if (a["w"], a["h"]) != (b["w"], b["h"]):
        return 1.0
    d1, d2 = a["data"], b["data"]
    hit = sum(1 for i in range(0, len(d1), 4) if max(abs(d1[i + k] - d2[i + k]) for k in range(3)) > level)
    return hit / (a["w"] * a["h"])


class Page:
    def __init__(self, page, out):
        self.page, self.out = page, out

    def shot(self, name, selector=None):
        path = os.path.join(self.out, name)
        if selector:
            self.page.locator(selector).screenshot(path=path)
        else:
            self.page.screenshot(path=path, full_page=True)

    def snap(self):
        # Two animation frames after a change, so the viewer has drawn it.
        self.page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        return self.page.evaluate(SNAP)

    def select(self, sel, value):
        self.page.select_option(sel, value)
        return self.snap()

    def check(self, sel, on):
        self.page.set_checked(sel, on)
        return self.snap()

    def frame(self, t):
        self.page.evaluate("""(t) => { const s = document.getElementById('view-frame'); s.value = String(t);
                              s.dispatchEvent(new Event('input')); }""", t)
        self.page.wait_for_function("(t) => window.__creaseViewer && window.__creaseViewer.frame === t", arg=t)
        return self.snap()

    def open_viewer(self, url):
        self.page.goto(url)
        self.page.wait_for_selector('#viewer[data-ready]', timeout=120_000)
        state = self.page.get_attribute("#viewer", "data-ready")
        if state != "true":
            fail(f"{url}: the viewer did not open: {self.page.text_content('#viewer')!r}")
        n = self.page.evaluate("window.__creaseViewer.meta.frames")
        self.page.wait_for_function("(n) => window.__creaseViewer.store.frames.size === n", arg=n, timeout=120_000)
        return n


def exercise(p, name):
    """The assertions every viewer with input and output must pass; returns the figures measured."""
    r = {}
    page = p.page
    has = page.evaluate("window.__creaseViewer.meta.overlays")
    n = page.evaluate("window.__creaseViewer.meta.frames")
    base = p.select("#view-mode", "side")
    r["covered"] = covered(base)
    if r["covered"] < 0.05:
        fail(f"{name}: the canvas is blank ({r['covered']:.3f} of it drawn)")
    p.shot(f"{name}-01-side-by-side.png", "#viewer")

    last = p.frame(n - 1)
    r["frames_1_vs_n"] = differ(base, last)
    if r["frames_1_vs_n"] < 0.002:
        fail(f"{name}: frame 1 and frame {n} look the same ({r['frames_1_vs_n']:.4f} of pixels differ)")
    p.frame(0)

    inp = p.select("#view-mode", "input")
    out = p.select("#view-mode", "output")
    r["input_vs_output"] = differ(inp, out)
    if r["input_vs_output"] < 0.002:
        fail(f"{name}: the input and output views look the same ({r['input_vs_output']:.4f})")

    for colour in ("stretch", "displacement"):
        if not has[colour]:
            fail(f"{name}: no {colour} overlay offered")
        on = p.select("#view-colour", colour)
        r[f"{colour}_on"] = differ(out, on)
        if r[f"{colour}_on"] < 0.01:
            fail(f"{name}: the {colour} colours change nothing ({r[f'{colour}_on']:.4f})")
        if colour == "stretch":
            p.shot(f"{name}-02-stretch.png", "#viewer")
        off = p.select("#view-colour", "none")
        if differ(out, off) > 0.001:
            fail(f"{name}: switching the {colour} colours off does not restore the picture")

    for box, what in (("#ov-anchors", "anchors"), ("#ov-lines", "control_lines")):
        if not has[what]:
            continue
        on = p.check(box, True)
        off = p.check(box, False)
        r[f"{what}_toggle"] = differ(on, off)
        if r[f"{what}_toggle"] < 0.0005:
            fail(f"{name}: the {what} overlay changes nothing ({r[f'{what}_toggle']:.5f})")
    for box, what in (("#ov-anchors", "anchors"), ("#ov-lines", "control_lines")):
        if has[what]:
            page.set_checked(box, True)

    flat = p.select("#view-shading", "flat")
    smooth = p.select("#view-shading", "smooth")
    # Shading moves brightness a little on a fine mesh: compare at a finer level (SwiftShader draws the same
    # picture twice to the bit, so any difference is the shading's).
    r["flat_vs_smooth"] = differ(flat, smooth, level=2)
    if r["flat_vs_smooth"] < 0.002:
        fail(f"{name}: flat and smooth shading look the same ({r['flat_vs_smooth']:.5f})")

    p.select("#view-mode", "wipe")
    p.select("#view-colour", "stretch" if has["stretch"] else "none")
    p.shot(f"{name}-03-wipe.png", "#viewer")
    p.select("#view-mode", "side")
    p.select("#view-colour", "none")
    return r


def check_report(p, name, want_eval):
    page = p.page
    page.wait_for_selector("#report", timeout=60_000)
    text = page.text_content("#report") or ""
    for want in ("Frames", "Shape kept", "Stretch", "Solver", "Timings", "mean edge lengths", "s / frame"):
        if want not in text:
            fail(f"{name}: the report lacks {want!r}: {text[:400]!r}")
    if page.locator("#chart-stretch path").count() < 2:
        fail(f"{name}: the per-frame stretch chart has no lines")
    if want_eval and page.locator("#report-eval").count() != 1:
        fail(f"{name}: eval.json is present but the report has no eval table")
    href = page.get_attribute("#raw-report", "href")
    raw = page.evaluate("(u) => fetch(u).then(r => r.json())", href)
    if raw.get("complete") is not True or "summary" not in raw:
        fail(f"{name}: the raw report link does not give report.json: {str(raw)[:200]}")
    p.shot(f"{name}-04-report.png", ".report-box")
    p.shot(f"{name}-05-charts.png", "#report .charts")
    return page.locator("#report svg.chart").count()


def main():
    a = argparse.ArgumentParser()
    a.add_argument("--dashboard", required=True, help="the coordinator dashboard's URL")
    a.add_argument("--token-file", required=True)
    a.add_argument("--job", required=True, help="a finished job's id")
    a.add_argument("--view", required=True, help="`crease view` on an output folder: its URL")
    a.add_argument("--view-input", required=True, help="`crease view` on an input folder alone: its URL")
    a.add_argument("--out", required=True)
    a = a.parse_args()
    os.makedirs(a.out, exist_ok=True)
    token = open(a.token_file).read().strip()
    result = {}

    with chromium.page(1280, 900) as (page, errors):
        p = Page(page, a.out)

        # The dashboard, signed in, on the finished job's page.
        page.goto(a.dashboard + "/login")
        page.fill("#token", token)
        page.click("button[type=submit]")
        page.wait_for_selector("table#jobs")
        renderer = page.evaluate("""() => { const g = document.createElement('canvas').getContext('webgl2');
            if (!g) return null; const i = g.getExtension('WEBGL_debug_renderer_info');
            return i ? g.getParameter(i.UNMASKED_RENDERER_WEBGL) : g.getParameter(g.RENDERER); }""")
        if not renderer:
            fail("this Chromium has no WebGL 2 (the SwiftShader flags did not take)")
        result["webgl_renderer"] = renderer
        n = p.open_viewer(f"{a.dashboard}/#/jobs/{a.job}")
        result["job_frames"] = n
        result["job"] = exercise(p, "job")
        result["job_charts"] = check_report(p, "job", want_eval=False)
        p.shot("job-00-page.png")

        # crease view on the output folder of a run (with eval.json beside it).
        n = p.open_viewer(a.view)
        result["view"] = exercise(p, "view")
        result["view_charts"] = check_report(p, "view", want_eval=True)
        result["view_title"] = page.text_content("#local-title")

        # crease view on an input folder alone: one sequence, no overlays of output against input.
        n = p.open_viewer(a.view_input)
        img = p.snap()
        if covered(img) < 0.05:
            fail("input alone: the canvas is blank")
        modes = page.eval_on_selector_all("#view-mode option", "o => o.map(x => x.value)")
        if modes != ["input"]:
            fail(f"input alone: modes offered {modes}, expected only the sequence")
        first, last = img, p.frame(n - 1)
        if differ(first, last) < 0.002:
            fail("input alone: the first and last frames look the same")
        p.shot("input-alone.png", "#viewer")
        result["input_alone_frames"] = n

        if errors:
            fail(f"console errors: {errors}")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
