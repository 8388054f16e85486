"""Headless Chromium driven over the DevTools protocol (CDP) on a pipe: open a page, wait, screenshot.

Chromium's plain `--screenshot` fires before a WebAssembly app (the Rerun web viewer) has drawn, so
the page is driven instead: `--remote-debugging-pipe` gives CDP on file descriptors 3 (commands in)
and 4 (replies out), NUL-separated JSON, no websocket and no port. One class, `HeadlessChromium`.
"""

from __future__ import annotations

import base64
import contextlib
import fcntl
import json
import os
import select
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from types import TracebackType
from typing import Any, Final

from pmsm_hil.dashboards.errors import DashboardError

#: Flags for a closed network and a root user (see the machine notes in docs/dashboards.md).
CHROMIUM_FLAGS: Final = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                         "--disable-background-networking", "--disable-component-update", "--disable-sync",
                         "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio")


def find_chromium() -> str | None:
    """Path of a Chromium/Chrome binary on PATH (or $CHROMIUM), None if there is none."""
    env = os.environ.get("CHROMIUM")
    if env and Path(env).is_file():
        return env
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        found = shutil.which(name)
        if found:
            return found
    return None


class HeadlessChromium:
    """A headless Chromium process with one page target, driven over the CDP pipe.

    `width`/`height`: viewport in CSS pixels. `console`: keep the page's last 50 console messages in
    `self.console` (off by default: the Rerun web viewer logs ≈ 11 000 debug messages, 87 MB of DevTools JSON,
    while it starts). Use as a context manager; `close()` ends the process."""

    def __init__(self, binary: str | None = None, *, width: int = 1600, height: int = 1000,
                 timeout_s: float = 30.0, console: bool = False) -> None:
        exe = binary or find_chromium()
        if exe is None:
            raise DashboardError("chromium: no Chromium binary found (install Debian's `chromium`)")
        self.timeout_s = timeout_s
        self._profile = tempfile.mkdtemp(prefix="hil-chromium-")
        cmd_r, self._cmd_w = os.pipe()
        self._out_r, out_w = os.pipe()

        def child_fds() -> None:  # runs in the child before exec: CDP wants fds 3 (in) and 4 (out)
            high_in = fcntl.fcntl(cmd_r, fcntl.F_DUPFD, 10)
            high_out = fcntl.fcntl(out_w, fcntl.F_DUPFD, 10)
            os.dup2(high_in, 3)
            os.dup2(high_out, 4)

        args = [exe, *CHROMIUM_FLAGS, f"--user-data-dir={self._profile}", "--remote-debugging-pipe",
                f"--window-size={width},{height}", "about:blank"]
        try:
            self._proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                          stderr=subprocess.DEVNULL, preexec_fn=child_fds, close_fds=False)
        except OSError as exc:
            self._cleanup_fds((cmd_r, out_w, self._cmd_w, self._out_r))
            shutil.rmtree(self._profile, ignore_errors=True)
            raise DashboardError(f"chromium: cannot start {exe} ({exc})") from None
        os.close(cmd_r)
        os.close(out_w)
        self._buf = b""
        self._next_id = 0
        self._session: str | None = None
        self.console: list[str] = []
        try:
            target = self.call("Target.createTarget", {"url": "about:blank"}, session=False)["targetId"]
            self._session = self.call("Target.attachToTarget", {"targetId": target, "flatten": True},
                                      session=False)["sessionId"]
            self.call("Page.enable")
            if console:  # console events are only sent while the Runtime domain is enabled
                self.call("Runtime.enable")
            self.call("Emulation.setDeviceMetricsOverride",
                      {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
        except BaseException:
            self.close()
            raise

    @staticmethod
    def _cleanup_fds(fds: tuple[int, ...]) -> None:
        for fd in fds:
            with contextlib.suppress(OSError):
                os.close(fd)

    def _read_message(self, deadline: float) -> dict[str, Any]:
        while b"\0" not in self._buf:
            left = deadline - time.monotonic()
            if left <= 0:
                raise DashboardError(f"chromium: no DevTools reply within {self.timeout_s} s")
            ready, _, _ = select.select([self._out_r], [], [], left)
            if not ready:
                continue
            chunk = os.read(self._out_r, 1 << 20)
            if not chunk:
                raise DashboardError(f"chromium: browser closed its DevTools pipe (exit code {self._proc.poll()})")
            self._buf += chunk
        raw, self._buf = self._buf.split(b"\0", 1)
        msg: dict[str, Any] = json.loads(raw)
        return msg

    def call(self, method: str, params: dict[str, Any] | None = None, *, session: bool = True) -> dict[str, Any]:
        """Send one CDP command and wait for its result (events seen meanwhile are kept as console text)."""
        self._next_id += 1
        msg: dict[str, Any] = {"id": self._next_id, "method": method, "params": params or {}}
        if session and self._session is not None:
            msg["sessionId"] = self._session
        try:
            os.write(self._cmd_w, json.dumps(msg).encode() + b"\0")
        except OSError as exc:
            raise DashboardError(f"chromium: cannot send {method} ({exc})") from None
        deadline = time.monotonic() + self.timeout_s
        while True:
            reply = self._read_message(deadline)
            if reply.get("id") == self._next_id:
                if "error" in reply:
                    raise DashboardError(f"chromium: {method} failed: {reply['error'].get('message')}")
                result: dict[str, Any] = reply.get("result", {})
                return result
            if reply.get("method") == "Runtime.consoleAPICalled":
                args = reply["params"].get("args", [])
                text = " ".join(str(a.get("value", a.get("description", ""))) for a in args)
                self.console = [*self.console[-49:], text[:300]]

    def navigate(self, url: str) -> None:
        """Open `url` in the page and wait for its load event (document.readyState == complete)."""
        result = self.call("Page.navigate", {"url": url})
        if result.get("errorText"):
            raise DashboardError(f"chromium: cannot open {url}: {result['errorText']}")
        self.wait_for("document.readyState === 'complete'", timeout_s=self.timeout_s)

    def evaluate(self, expression: str) -> Any:
        """Value of a JavaScript expression in the page (JSON-serialisable values only)."""
        result = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        if "exceptionDetails" in result:
            raise DashboardError(f"chromium: script error in {expression!r}: {result['exceptionDetails'].get('text')}")
        return result.get("result", {}).get("value")

    def wait_for(self, expression: str, *, timeout_s: float, poll_s: float = 0.25) -> bool:
        """Poll a JavaScript expression until it is truthy; False on timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.evaluate(expression):
                return True
            time.sleep(poll_s)
        return False

    def screenshot(self, path: Path) -> bytes:
        """Save a PNG of the viewport to `path`; returns the PNG bytes."""
        data = base64.b64decode(self.call("Page.captureScreenshot", {"format": "png"})["data"])
        path.write_bytes(data)
        return data

    def close(self) -> None:
        """End the browser and remove its profile directory (idempotent)."""
        if getattr(self, "_proc", None) is None:
            return
        with contextlib.suppress(DashboardError, OSError, ValueError):
            os.write(self._cmd_w, json.dumps({"id": 0, "method": "Browser.close"}).encode() + b"\0")
        try:
            self._proc.wait(5.0)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait(5.0)
        self._cleanup_fds((self._cmd_w, self._out_r))
        self._proc = None  # type: ignore[assignment]
        shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> HeadlessChromium:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
