"""Debian's headless Chromium as the browser tests open it: a fresh profile (Playwright takes --user-data-dir as a
persistent context on a directory), WebGL through SwiftShader (no GPU), one page, a minute's default timeout, and
the page's console errors and uncaught exceptions collected."""

import contextlib
import tempfile

from playwright.sync_api import sync_playwright

CHROMIUM = "/usr/bin/chromium"
ARGS = [
    "--headless", "--no-sandbox", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    # WebGL (the viewer) without a GPU: ANGLE on SwiftShader, Chromium's CPU renderer.
    "--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist",
]


@contextlib.contextmanager
def page(width, height):
    """Yields (page, errors): the one page of a fresh browser, and the list its console errors go to."""
    with tempfile.TemporaryDirectory() as profile, sync_playwright() as pw:
        browser = pw.chromium.launch_persistent_context(
            profile, executable_path=CHROMIUM, args=ARGS, viewport={"width": width, "height": height})
        p = browser.pages[0] if browser.pages else browser.new_page()
        p.set_default_timeout(60_000)
        errors = []
        p.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        p.on("pageerror", lambda e: errors.append(str(e)))
        try:
            yield p, errors
        finally:
            browser.close()
