"""A headless Chromium driven over the DevTools protocol (CDP), with no browser download: the
system ``chromium`` renders WebGL in software (SwiftShader) and a websocket (``websockets``, a
viser dependency) sends it commands. The viewer's tests and its load-time benchmark use it to
open the page as a user would, press keys on its sliders and take screenshots.

    with HeadlessChromium("http://127.0.0.1:8080", size=(960, 600)) as b:
        b.wait_until(lambda: len(server.get_clients()) > 0, 60, "the page connects")
        img = b.screenshot()            # [H, W, 3] uint8
"""

import base64
import io
import json
import os
import shutil
import socket
import subprocess
import tempfile
import time
import urllib.request
from collections.abc import Callable
from pathlib import Path

import numpy as np
from PIL import Image

FLAGS = ["--headless=new", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-gpu-sandbox", "--no-first-run", "--no-default-browser-check", "--mute-audio"]


def chromium_binary() -> str | None:
    """Path of the system Chromium (``$CHROMIUM`` first), or None."""
    for name in (os.environ.get("CHROMIUM"), "chromium", "chromium-browser", "google-chrome"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class HeadlessChromium:
    """A Chromium process showing ``url`` at a viewport of ``size`` = (width, height) px, and a
    CDP session to its page (``extra_flags``: more command-line flags, e.g. a dead proxy to
    check that a page needs no network). Use as a context manager; the process and its profile are removed
    on exit."""

    def __init__(self, url: str, size: tuple[int, int] = (960, 600), timeout: float = 30.0,
                 extra_flags: list[str] | None = None):
        from websockets.sync.client import connect

        exe = chromium_binary()
        if exe is None:
            raise FileNotFoundError("no chromium on PATH (Debian: apt-get install chromium; or set $CHROMIUM)")
        self.size = size
        self._profile = tempfile.mkdtemp(prefix="drawer_chromium_")
        port = _free_port()
        self.proc = subprocess.Popen([exe, *FLAGS, *(extra_flags or []), f"--remote-debugging-port={port}", f"--user-data-dir={self._profile}",
                                      f"--window-size={size[0]},{size[1]}", url],
                                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        t0, targets = time.monotonic(), None
        while targets is None:
            try:
                targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json", timeout=2))
            except OSError:
                if self.proc.poll() is not None or time.monotonic() - t0 > timeout:
                    self.close()
                    raise RuntimeError(f"{exe} did not open its DevTools port within {timeout} s") from None
                time.sleep(0.2)
        page = next(t for t in targets if t["type"] == "page")
        self.ws = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=timeout)
        self._id = 0
        self.cdp("Emulation.setDeviceMetricsOverride", width=size[0], height=size[1], deviceScaleFactor=1, mobile=False)
        # the page opens ``url`` itself: navigating an about:blank page to a file:// URL moves it
        # to another renderer and detaches this session

    def cdp(self, method: str, timeout: float = 120.0, **params) -> dict:
        """Send one command and return its result (events in between are dropped); a protocol
        error raises ``RuntimeError`` naming the method."""
        self._id += 1
        self.ws.send(json.dumps({"id": self._id, "method": method, "params": params}))
        t0 = time.monotonic()
        while True:
            msg = json.loads(self.ws.recv(timeout=max(0.1, timeout - (time.monotonic() - t0))))
            if msg.get("id") == self._id:
                if "error" in msg:
                    raise RuntimeError(f"CDP {method}: {msg['error']}")
                return msg.get("result", {})

    def evaluate(self, js: str):
        """Value of a JavaScript expression in the page (JSON-serialisable results only)."""
        r = self.cdp("Runtime.evaluate", expression=js, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"page script failed: {r['exceptionDetails'].get('text')} in {js[:80]!r}")
        return r.get("result", {}).get("value")

    def press(self, key: str, code: int) -> None:
        """Press and release a key (``key`` as in KeyboardEvent.key, ``code`` its virtual key
        code) on the focused element."""
        for typ in ("keyDown", "keyUp"):
            self.cdp("Input.dispatchKeyEvent", type=typ, key=key, code=key, windowsVirtualKeyCode=code)

    def screenshot(self, path: Path | None = None) -> np.ndarray:
        """The page as [H, W, 3] uint8 (also saved as PNG at ``path``)."""
        data = base64.b64decode(self.cdp("Page.captureScreenshot", format="png")["data"])
        if path is not None:
            Path(path).parent.mkdir(parents=True, exist_ok=True)
            Path(path).write_bytes(data)
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    @staticmethod
    def wait_until(cond: Callable[[], bool], timeout: float, what: str, poll: float = 0.1) -> float:
        """Seconds until ``cond()`` held; ``TimeoutError`` naming ``what`` after ``timeout`` s."""
        t0 = time.monotonic()
        while not cond():
            if time.monotonic() - t0 > timeout:
                raise TimeoutError(f"waited {timeout} s for {what}")
            time.sleep(poll)
        return time.monotonic() - t0

    def close(self) -> None:
        try:
            if getattr(self, "ws", None) is not None:
                self.ws.close()
        finally:
            if self.proc.poll() is None:
                self.proc.terminate()
                try:
                    self.proc.wait(10)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait(10)
            shutil.rmtree(self._profile, ignore_errors=True)

    def __enter__(self) -> "HeadlessChromium":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
