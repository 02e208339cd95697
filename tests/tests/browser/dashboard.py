"""Drives the crease dashboard in headless Chromium (Debian's /usr/bin/chromium through Playwright) against a
real coordinator and worker that tests/tests/dashboard_browser.rs started on 127.0.0.1.

Steps, each an assertion: sign in through the login form; submit a job (with `crease submit`) and watch its
row's stacked progress bar move to done without the page polling; open the job and see preview.png load
(naturalWidth > 0), its stages, log tails and report figures; submit a second job, cancel it with its Cancel
button and see its state become `cancelled`; the workers page lists the worker. Screenshots go to --out.
Exits non-zero with a message on the first failed step.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import chromium


def fail(msg):
    print(f"dashboard browser test: FAILED: {msg}", file=sys.stderr)
    sys.exit(1)


def submit(a, job):
    o = subprocess.run([a.crease, "submit", job, "--coordinator", a.coordinator, "--token-file", a.token_file],
                       capture_output=True, text=True, timeout=60)
    if o.returncode != 0:
        fail(f"crease submit {job}: {o.stderr}")
    return o.stdout.strip()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--url", required=True)
    p.add_argument("--coordinator", required=True)
    p.add_argument("--crease", required=True)
    p.add_argument("--token-file", required=True)
    p.add_argument("--worker-token", required=True)
    p.add_argument("--job", required=True)
    p.add_argument("--job2", required=True)
    p.add_argument("--out", required=True)
    a = p.parse_args()
    os.makedirs(a.out, exist_ok=True)
    shot = lambda page, name: page.screenshot(path=os.path.join(a.out, name), full_page=True)
    token = open(a.token_file).read().strip()

    with chromium.page(1280, 800) as (page, console_errors):

        # Signed out: the page sends the browser to the login form; a worker token is refused there.
        page.goto(a.url + "/")
        if not page.url.endswith("/login"):
            fail(f"unauthenticated visit went to {page.url}, not /login")
        page.fill("#token", a.worker_token)
        page.click("button[type=submit]")
        err = page.text_content("#login-error") or ""
        if "worker token" not in err:
            fail(f"a worker token at the login form: expected a refusal naming it, got {err!r}")
        shot(page, "01-login-refused-worker-token.png")
        page.fill("#token", token)
        page.click("button[type=submit]")
        page.wait_for_selector("table#jobs")
        # The refused login above logged its 403; from here on the console must stay clean.
        console_errors.clear()
        page.wait_for_selector("#live.on")

        # Count API requests from here on: the page must not poll.
        api_requests = []
        page.on("request", lambda r: api_requests.append(r.url) if "/api/" in r.url else None)
        time.sleep(3)
        if api_requests:
            fail(f"the idle jobs page made API requests (polling?): {api_requests}")

        job = submit(a, a.job)
        row = f'tr[data-job="{job}"]'
        page.wait_for_selector(row)
        # Record every done count the bar shows as events arrive.
        page.evaluate("""(row) => {
            window.__seen = [];
            const note = () => {
              const bar = document.querySelector(row + ' .bar');
              if (bar) window.__seen.push([+bar.dataset.done, +bar.dataset.total]);
            };
            note();
            new MutationObserver(note).observe(document.getElementById('view'), {subtree: true, childList: true, attributes: true});
        }""", row)
        shot(page, "02-jobs-running.png")
        page.wait_for_selector(f'{row}[data-state="done"]', timeout=120_000)
        seen = page.evaluate("window.__seen")
        dones = [d for d, _ in seen]
        total = seen[-1][1]
        if total <= 0 or dones[-1] != total:
            fail(f"the bar ended at {seen[-1]}, not done/total")
        if not any(0 < d < total for d in dones):
            fail(f"the bar never showed partial progress: {seen}")
        if dones != sorted(dones):
            fail(f"the bar went backwards: {dones}")
        width = page.evaluate(f"""getComputedStyle(document.querySelector('{row} .seg.done')).width""")
        shot(page, "03-jobs-done.png")
        polled = [u for u in api_requests if "/api/jobs" in u or "/api/workers" in u]
        if polled:
            fail(f"the jobs list fetched instead of following events: {polled}")

        # The job page: stages, pictures, logs, report.
        page.click(f'{row} a')
        page.wait_for_selector(f'#job[data-job="{job}"]')
        page.wait_for_selector('figure[data-file="preview.png"] img')
        page.wait_for_function("""() => {
            const img = document.querySelector('figure[data-file="preview.png"] img');
            return img && img.complete && img.naturalWidth > 0;
        }""")
        nw = page.evaluate("""document.querySelector('figure[data-file="preview.png"] img').naturalWidth""")
        stages = page.eval_on_selector_all("section.stage", "s => s.map(x => x.dataset.stage)")
        for want in ("position", "finalize"):
            if want not in stages:
                fail(f"stage {want} missing from the job page: {stages}")
        if stages.index("position") > stages.index("finalize"):
            fail(f"stages out of graph order: {stages}")
        page.click('tr[data-task="finalize"] details summary')
        log = page.text_content('tr[data-task="finalize"] pre.log') or ""
        if "dispatched to worker" not in log:
            fail(f"finalize's log tail does not show its dispatch: {log[:300]!r}")
        page.wait_for_selector("#report-sequence")
        frames = page.text_content("#report-sequence") or ""
        if "Frames" not in frames or "Triangles" not in frames:
            fail(f"report figures missing: {frames[:300]!r}")
        shot(page, "04-job-done.png")

        # A second job, cancelled from its row while it runs.
        page.click('a[href="#/"]')
        page.wait_for_selector("table#jobs")
        job2 = submit(a, a.job2)
        row2 = f'tr[data-job="{job2}"]'
        page.wait_for_selector(f'{row2}[data-state="running"]', timeout=60_000)
        page.once("dialog", lambda d: d.accept())
        page.click(f'{row2} button[data-action="cancel"]')
        page.wait_for_selector(f'{row2}[data-state="cancelled"]', timeout=30_000)
        shot(page, "05-jobs-cancelled.png")
        page.click("#filter-cancelled")
        rows = page.eval_on_selector_all("table#jobs tr[data-job]", "r => r.map(x => x.dataset.job)")
        if rows != [job2]:
            fail(f"the cancelled filter shows {rows}, expected only {job2}")
        page.click("#filter-all")

        # Workers page.
        page.click("#nav-workers")
        page.wait_for_selector("table#workers tr[data-worker]")
        cells = page.text_content("table#workers") or ""
        if "s ago" not in cells:
            fail(f"workers page shows no heartbeat age: {cells[:300]!r}")
        shot(page, "06-workers.png")

        if console_errors:
            fail(f"console errors: {console_errors}")
    print(json.dumps({"job": job, "cancelled": job2, "progress_seen": dones, "preview_natural_width": nw,
                      "done_segment_width": width, "stages": stages}))


if __name__ == "__main__":
    main()
