"""Headless Chromium for the report tests (Debian's `chromium`, installed by scripts/install-test-tools.sh):
the rendered DOM (`--dump-dom`), screenshots (`--screenshot`), and a page load watched through the DevTools
protocol over a pipe (`--remote-debugging-pipe`: JSON messages ending in a NUL byte, the browser reading
fd 3 and writing fd 4), which reports every request the page made, console messages, exceptions and log
entries, and evaluates expressions in the loaded page.

Each run gets a fresh profile directory, no network (the proxy points nowhere, every host resolves to
nothing), and a time limit.
"""

from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
SKIP = pytest.mark.skipif(CHROMIUM is None, reason="headless Chromium is not installed (scripts/install-test-tools.sh "
                                                   "installs Debian's chromium package)")
TIMEOUT = 60.0
# no network at all: nothing a page asks for can leave the machine, and a request is still seen by the protocol
OFFLINE = ["--proxy-server=127.0.0.1:9", "--host-resolver-rules=MAP * ~NOTFOUND", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-default-apps",
           "--disable-sync", "--metrics-recording-only", "--no-default-browser-check", "--mute-audio"]


def _base(profile: str) -> list[str]:
    assert CHROMIUM is not None
    return [CHROMIUM, "--headless", "--disable-gpu", "--no-sandbox", "--hide-scrollbars",
            f"--user-data-dir={profile}", *OFFLINE]


def dump_dom(page: Path, width: int = 1400) -> str:
    """The DOM of `page` after loading, as Chromium serialises it."""
    with tempfile.TemporaryDirectory() as profile:
        p = subprocess.run([*_base(profile), f"--window-size={width},1000", "--dump-dom", page.as_uri()],
                           capture_output=True, timeout=TIMEOUT, check=False)
    assert p.returncode == 0, p.stderr.decode(errors="replace")[-2000:]
    return p.stdout.decode("utf-8")


def screenshot(page: Path, out: Path, width: int, height: int) -> Path:
    """A PNG of `page` laid out `width` CSS pixels wide, its first `height` pixels (the DevTools protocol's
    device metrics: a headless window is never narrower than 500 pixels, so --window-size cannot give a phone's
    width)."""
    load(page, width=width, height=height, shot=out)
    assert out.is_file()
    return out


@dataclass
class Load:
    """What one page load did."""

    requests: list[str] = field(default_factory=list)  # every URL the page requested (itself included)
    console: list[dict[str, Any]] = field(default_factory=list)  # Runtime.consoleAPICalled
    exceptions: list[dict[str, Any]] = field(default_factory=list)  # Runtime.exceptionThrown
    log: list[dict[str, Any]] = field(default_factory=list)  # Log.entryAdded
    values: dict[str, Any] = field(default_factory=dict)  # expression -> its value in the loaded page

    def errors(self) -> list[str]:
        out = [json.dumps(c.get("args", [])) for c in self.console if c.get("type") in ("error", "assert")]
        out += [json.dumps(e.get("exceptionDetails", {}).get("text")) for e in self.exceptions]
        entries = [e.get("entry", {}) for e in self.log]
        return out + [str(e.get("text")) for e in entries if e.get("level") == "error"]


class _Pipe:
    def __init__(self, send: int, receive: int) -> None:
        self.send_fd, self.receive_fd = send, receive
        self.buffer = b""
        self.next_id = 0
        self.events: list[dict[str, Any]] = []

    def call(self, method: str, params: dict[str, Any] | None = None, session: str | None = None) -> dict[str, Any]:
        self.next_id += 1
        msg: dict[str, Any] = {"id": self.next_id, "method": method, "params": params or {}}
        if session is not None:
            msg["sessionId"] = session
        os.write(self.send_fd, json.dumps(msg).encode() + b"\0")
        while True:
            m = self.receive()
            if m.get("id") == self.next_id:
                assert "error" not in m, (method, m["error"])
                return m.get("result", {})
            self.events.append(m)

    def receive(self, deadline: float | None = None) -> dict[str, Any]:
        deadline = deadline or time.monotonic() + TIMEOUT
        while b"\0" not in self.buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("no message from Chromium")
            chunk = os.read(self.receive_fd, 1 << 16)
            if not chunk:
                raise EOFError("Chromium closed the pipe")
            self.buffer += chunk
        raw, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(raw)

    def wait_for(self, method: str) -> None:
        deadline = time.monotonic() + TIMEOUT
        while not any(e.get("method") == method for e in self.events):
            self.events.append(self.receive(deadline))


def load(page: Path, expressions: tuple[str, ...] = (), width: int = 1400, height: int = 1000,
         shot: Path | None = None) -> Load:
    """Load `page` in headless Chromium under the DevTools protocol, laid out `width` CSS pixels wide; what it
    requested and said, the values of `expressions` once it has loaded, and with `shot` a PNG of its first
    `height` pixels written there."""
    to_browser_r, to_browser_w = os.pipe()
    from_browser_r, from_browser_w = os.pipe()
    with tempfile.TemporaryDirectory() as profile:
        argv = [*_base(profile), f"--window-size={width},1000", "--remote-debugging-pipe", "about:blank"]
        wrapped = ["bash", "-c", f'exec "$@" 3<&{to_browser_r} 4>&{from_browser_w}', "chromium", *argv]
        proc = subprocess.Popen(wrapped, pass_fds=(to_browser_r, from_browser_w), stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        os.close(to_browser_r)
        os.close(from_browser_w)
        pipe = _Pipe(to_browser_w, from_browser_r)
        try:
            target = pipe.call("Target.createTarget", {"url": "about:blank"})["targetId"]
            session = pipe.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]
            for domain in ("Network", "Runtime", "Log", "Page"):
                pipe.call(f"{domain}.enable", session=session)
            pipe.call("Emulation.setDeviceMetricsOverride", {"width": width, "height": height, "deviceScaleFactor": 1,
                                                             "mobile": False}, session=session)
            pipe.call("Page.navigate", {"url": page.as_uri()}, session=session)
            pipe.wait_for("Page.loadEventFired")
            out = Load()
            if shot is not None:
                got = pipe.call("Page.captureScreenshot", {"format": "png", "clip": {
                    "x": 0, "y": 0, "width": width, "height": height, "scale": 1}, "captureBeyondViewport": True},
                    session=session)
                shot.write_bytes(base64.b64decode(got["data"]))
            for e in expressions:
                got = pipe.call("Runtime.evaluate", {"expression": e, "returnByValue": True}, session=session)
                out.values[e] = got.get("result", {}).get("value")
            for m in pipe.events:
                kind, params = m.get("method"), m.get("params", {})
                if kind == "Network.requestWillBeSent":
                    out.requests.append(params["request"]["url"])
                elif kind == "Runtime.consoleAPICalled":
                    out.console.append(params)
                elif kind == "Runtime.exceptionThrown":
                    out.exceptions.append(params)
                elif kind == "Log.entryAdded":
                    out.log.append(params)
            try:
                pipe.call("Browser.close")
            except (EOFError, OSError):
                pass
            return out
        finally:
            os.close(to_browser_w)
            os.close(from_browser_r)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
