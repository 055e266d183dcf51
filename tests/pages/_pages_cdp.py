"""A small Chrome DevTools Protocol driver for the page tests: Debian's headless Chromium,
driven over its websocket (``websockets``' synchronous client), no browser download.

``Browser.open(url)`` loads a page in a fresh tab and returns a :class:`Tab` holding what the
page logged: console errors, uncaught exceptions, failed loads (``Log.entryAdded`` errors and
``Network.loadingFailed``) and HTTP answers >= 400 of its sub-resources.
"""

from __future__ import annotations

import base64
import itertools
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from websockets.sync.client import connect

CHROMIUM_NAMES = ("chromium", "chromium-browser")

FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
    "--mute-audio",
    "--remote-debugging-port=0",
)


def find_chromium() -> str | None:
    """The Chromium executable (``SNAPWARN_CHROMIUM`` or on PATH), None if absent."""
    env = os.environ.get("SNAPWARN_CHROMIUM")
    if env:
        return env if Path(env).exists() else None
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


@dataclass
class Tab:
    """One page: its session and what it reported."""

    browser: Browser
    session: str
    url: str
    console_errors: list[str] = field(default_factory=list)
    http_errors: list[str] = field(default_factory=list)

    def call(self, method: str, params: dict[str, Any] | None = None, timeout: float = 60) -> Any:
        return self.browser.call(method, params, session=self.session, timeout=timeout)

    def evaluate(self, expression: str, timeout: float = 30) -> Any:
        """Evaluate JavaScript in the page; the value (JSON-able) or an AssertionError."""
        r = self.call(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": True},
            timeout=timeout,
        )
        if "exceptionDetails" in r:
            raise AssertionError(f"JavaScript failed: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait_for(self, expression: str, timeout: float = 30.0) -> Any:
        """Poll ``expression`` until it is truthy; its value."""
        end = time.monotonic() + timeout
        while True:
            try:
                v = self.evaluate(expression)
            except (AssertionError, RuntimeError):  # the page is reloading: ask again
                v = None
            if v:
                return v
            if time.monotonic() > end:
                raise AssertionError(f"timed out waiting for {expression!r}")
            self.browser.pump(0.2)

    def screenshot(self, path: Path, width: int = 1400) -> Path:
        """A full-page PNG of the tab at ``width`` CSS pixels."""
        height = int(self.evaluate("document.documentElement.scrollHeight") or 900)
        self.call(
            "Emulation.setDeviceMetricsOverride",
            {"width": width, "height": min(max(height, 600), 12000), "deviceScaleFactor": 1,
             "mobile": False},
        )  # fmt: skip
        self.wait_for("Array.from(document.images).every(i => i.complete)", timeout=60)
        data = self.call("Page.captureScreenshot", {"format": "png"}, timeout=120)["data"]
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(base64.b64decode(data))
        return path

    def data_keys(self) -> list[dict[str, Any]]:
        """Every element with ``data-key``: key, JSON value (``data-value``), text, name."""
        return self.evaluate(
            "Array.from(document.querySelectorAll('[data-key]')).map(e => ({key: e.dataset.key,"
            " value: e.dataset.value === undefined ? undefined : JSON.parse(e.dataset.value),"
            " text: e.textContent.trim(), name: e.dataset.name || null}))"
        )

    def errors(self) -> list[str]:
        return self.console_errors + self.http_errors

    def close(self) -> None:
        target = self.browser.targets.pop(self.session, None)
        if target:
            self.browser.call("Target.closeTarget", {"targetId": target})


class Browser:
    """Headless Chromium on a temporary profile, one websocket to the browser target."""

    def __init__(self, executable: str, workdir: Path | None = None) -> None:
        self.profile = Path(tempfile.mkdtemp(prefix="snapwarn-chromium-", dir=workdir))
        self.proc = subprocess.Popen(
            [executable, *FLAGS, f"--user-data-dir={self.profile}", "about:blank"],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = self.profile / "DevToolsActivePort"
        end = time.monotonic() + 60
        while not port_file.exists() or len(port_file.read_text().splitlines()) < 2:
            if self.proc.poll() is not None or time.monotonic() > end:
                self.close()
                raise RuntimeError(f"chromium did not start (exit code {self.proc.poll()})")
            time.sleep(0.1)
        port, path = port_file.read_text().splitlines()[:2]
        self._ws_context = connect(f"ws://127.0.0.1:{port}{path}", max_size=256 * 1024 * 1024,
                                   open_timeout=30)  # fmt: skip
        self.ws = self._ws_context.__enter__()
        self.ids = itertools.count(1)
        self.targets: dict[str, str] = {}
        self.tabs: dict[str, Tab] = {}
        self.events: list[dict[str, Any]] = []

    # ---------------------------------------------------------------------- protocol
    def call(
        self,
        method: str,
        params: dict[str, Any] | None = None,
        *,
        session: str | None = None,
        timeout: float = 60,
    ) -> Any:
        msg_id = next(self.ids)
        msg: dict[str, Any] = {"id": msg_id, "method": method, "params": params or {}}
        if session:
            msg["sessionId"] = session
        self.ws.send(json.dumps(msg))
        end = time.monotonic() + timeout
        while True:
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no answer to {method} in {timeout} s")
            m = json.loads(self.ws.recv(timeout=left))
            if m.get("id") == msg_id:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self._event(m)

    def pump(self, seconds: float) -> None:
        """Read events for ``seconds``."""
        end = time.monotonic() + seconds
        while (left := end - time.monotonic()) > 0:
            try:
                self._event(json.loads(self.ws.recv(timeout=left)))
            except TimeoutError:
                return

    def _event(self, m: dict[str, Any]) -> None:
        tab = self.tabs.get(m.get("sessionId", ""))
        if tab is None or "method" not in m:
            return
        self.events.append(m)
        p = m.get("params", {})
        meth = m["method"]
        if meth == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            args = " ".join(str(a.get("value", a.get("description", ""))) for a in p["args"])
            tab.console_errors.append(f"console.{p['type']}: {args}")
        elif meth == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            tab.console_errors.append(
                f"exception: {d.get('text')} {d.get('exception', {}).get('description', '')}"
            )
        elif meth == "Log.entryAdded" and p["entry"].get("level") == "error":
            e = p["entry"]
            tab.console_errors.append(f"log: {e.get('text')} {e.get('url', '')}")
        elif meth == "Network.loadingFailed" and not p.get("canceled"):
            tab.http_errors.append(f"load failed: {p.get('errorText')}")
        elif meth == "Network.responseReceived":
            r = p["response"]
            if r.get("status", 0) >= 400:
                tab.http_errors.append(f"HTTP {r['status']}: {r.get('url')}")

    # ---------------------------------------------------------------------- pages
    def open(
        self, url: str, *, timeout: float = 120, cookies: list[dict] | None = None,
        init_script: str | None = None,
    ) -> Tab:  # fmt: skip
        """A new tab showing ``url`` once its load event fired (and the network settled);
        ``init_script`` runs in every document of the tab before the page's own scripts."""
        target = self.call("Target.createTarget", {"url": "about:blank"})["targetId"]
        session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True})[
            "sessionId"
        ]
        tab = Tab(self, session, url)
        self.targets[session] = target
        self.tabs[session] = tab
        for domain in ("Runtime", "Log", "Network", "Page"):
            tab.call(f"{domain}.enable")
        for c in cookies or []:
            tab.call("Network.setCookie", c)
        if init_script:
            tab.call("Page.addScriptToEvaluateOnNewDocument", {"source": init_script})
        self.navigate(tab, url, timeout=timeout)
        return tab

    def navigate(self, tab: Tab, url: str, *, timeout: float = 120) -> None:
        start = len(self.events)
        tab.url = url
        tab.call("Page.navigate", {"url": url})
        end = time.monotonic() + timeout
        while not any(
            e.get("sessionId") == tab.session and e["method"] == "Page.loadEventFired"
            for e in self.events[start:]
        ):
            if time.monotonic() > end:
                raise TimeoutError(f"{url} did not load in {timeout} s")
            self.pump(0.2)
        self.pump(0.3)

    def close(self) -> None:
        ws = getattr(self, "ws", None)
        if ws is not None:
            try:
                self.call("Browser.close", timeout=10)
            except Exception:  # noqa: BLE001 - the browser may already be gone
                pass
            self._ws_context.__exit__(None, None, None)
        try:
            self.proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait(timeout=15)
        shutil.rmtree(self.profile, ignore_errors=True)
