"""Headless Chromium driven over the Chrome DevTools Protocol, for the web view's test.

Chromium is Debian's ``chromium`` package (``/usr/bin/chromium``). It is started with
``--remote-debugging-pipe``: the protocol's JSON messages, each ended by a NUL byte,
go in on the browser's file descriptor 3 and come out on its descriptor 4, so no
WebSocket client is needed. WebGL, which rerun's web viewer draws with, runs on
SwiftShader, Chromium's software renderer, as there is no GPU.
"""

from __future__ import annotations

import base64
import json
import os
import subprocess
from pathlib import Path
from typing import Any

__all__ = ["CHROMIUM", "Chromium"]

#: Debian's Chromium (``apt-get install -y chromium``).
CHROMIUM = Path("/usr/bin/chromium")

_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    # WebGL on the software renderer: rerun's web viewer needs WebGL or WebGPU.
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--remote-debugging-pipe",
)


class Chromium:
    """One headless Chromium with one page; a context manager that ends it."""

    def __init__(self, profile: Path, width: int, height: int) -> None:
        to_browser, browser_in = os.pipe()
        browser_out, from_browser = os.pipe()

        def descriptors() -> None:  # in the child, before exec: its fds 3 and 4
            reads, writes = os.dup(to_browser), os.dup(from_browser)
            os.dup2(reads, 3)
            os.dup2(writes, 4)

        self.process = subprocess.Popen(
            [str(CHROMIUM), *_FLAGS, f"--user-data-dir={profile}", "about:blank"],
            preexec_fn=descriptors,  # noqa: PLW1509  (no threads start in the test)
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            close_fds=False,
        )
        os.close(to_browser)
        os.close(from_browser)
        self._out, self._in = browser_in, browser_out
        self._pending = b""
        self._last_id = 0
        self._session = ""
        try:
            target = self.call("Target.createTarget", url="about:blank")["targetId"]
            attached = self.call("Target.attachToTarget", targetId=target, flatten=True)
            self._session = attached["sessionId"]
            self.call(
                "Emulation.setDeviceMetricsOverride",
                page=True,
                width=width,
                height=height,
                deviceScaleFactor=1,
                mobile=False,
            )
        except BaseException:
            self.__exit__()
            raise

    def call(self, method: str, page: bool = False, **params: Any) -> dict[str, Any]:
        """Send one command (to the page if ``page``) and return its result."""
        self._last_id += 1
        message: dict[str, Any] = {"id": self._last_id, "method": method, "params": params}
        if page:
            message["sessionId"] = self._session
        os.write(self._out, json.dumps(message).encode() + b"\0")
        while True:
            while b"\0" not in self._pending:
                chunk = os.read(self._in, 1 << 20)
                if not chunk:
                    raise RuntimeError(f"chromium ended while answering {method}")
                self._pending += chunk
            line, self._pending = self._pending.split(b"\0", 1)
            answer = json.loads(line)
            if answer.get("id") == self._last_id:  # events and other answers pass by
                if "error" in answer:
                    raise RuntimeError(f"{method}: {answer['error']}")
                return dict(answer["result"])

    def open(self, url: str) -> None:
        """Load ``url`` in the page."""
        self.call("Page.navigate", page=True, url=url)

    def screenshot(self) -> bytes:
        """The page as it is drawn now, a PNG file's bytes."""
        return base64.b64decode(
            self.call("Page.captureScreenshot", page=True, format="png")["data"]
        )

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc: object) -> None:
        os.close(self._out)
        os.close(self._in)
        self.process.kill()
        self.process.wait()
