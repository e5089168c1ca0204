"""Open a page in the system's headless Chromium (driven by Python playwright, no browser download):
for tests and screenshots of animations."""

from __future__ import annotations

import shutil
import tempfile
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

# Chromium as root in a container: no sandbox, no GPU, no network chatter of its own
CHROMIUM_ARGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync"]
READY_TIMEOUT_MS = 120_000


def chromium_path() -> str | None:
    return shutil.which("chromium") or shutil.which("chromium-browser")


@dataclass
class Tab:
    """A loaded page; `errors` holds JavaScript errors, `requests` every URL the page asked for."""

    page: object
    errors: list = field(default_factory=list)
    requests: list = field(default_factory=list)

    def seek(self, t: float) -> None:
        """Pause the animation at t seconds, as the time slider does."""
        self.page.evaluate(f"viewer.animator.pause(); viewer.animator.time = {float(t)}; viewer.animator.seek({float(t)})")

    def screenshot(self, path, settle_ms: int = 700) -> Path:
        self.page.wait_for_timeout(settle_ms)
        self.page.screenshot(path=str(path))
        return Path(path)


@contextmanager
def open_page(html_path, width: int = 900, height: int = 700, animated: bool = True):
    """A fresh headless Chromium (own temporary profile) showing `html_path`, once the scene is
    loaded (for an animation: once every muscle line is found and the recording is loaded)."""
    from playwright.sync_api import sync_playwright

    chromium = chromium_path()
    if chromium is None:
        raise FileNotFoundError("no chromium on PATH (Debian: apt-get install chromium)")
    with tempfile.TemporaryDirectory(prefix="trunk-drake-chromium-") as profile, sync_playwright() as p:
        browser = p.chromium.launch_persistent_context(profile, executable_path=chromium, headless=True,
                                                       args=CHROMIUM_ARGS, viewport={"width": width, "height": height})
        try:
            tab = Tab(browser.new_page())
            tab.page.on("pageerror", lambda e: tab.errors.append(str(e)))
            tab.page.on("console", lambda m: m.type == "error" and tab.errors.append(m.text))
            tab.page.on("request", lambda r: tab.requests.append(r.url))
            tab.page.goto(Path(html_path).resolve().as_uri())
            if animated:
                tab.page.wait_for_function("window.trunkDrakeReady === true", timeout=READY_TIMEOUT_MS)
            yield tab
        finally:
            browser.close()
