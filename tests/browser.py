"""A real headless browser for the viewer tests: Chromium (or Chrome) driven over the
DevTools protocol, with the websockets client that viser already depends on.

:func:`find_browser` looks for ``$WBC_BROWSER``, then the usual executable names on PATH
(Debian: ``apt-get install chromium``). WebGL runs on the CPU (SwiftShader).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import signal
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import numpy as np

NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome", "chrome-headless-shell")


def find_browser() -> str | None:
    """Path of a Chromium-family browser: ``$WBC_BROWSER`` or the first of NAMES on PATH."""
    explicit = os.environ.get("WBC_BROWSER")
    if explicit:
        return explicit
    return next((path for path in map(shutil.which, NAMES) if path), None)


class HeadlessBrowser:
    """One headless browser process with one page (``width`` x ``height`` CSS pixels)."""

    def __init__(self, executable: str, width: int = 900, height: int = 650, timeout: float = 60.0):
        from websockets.sync.client import connect

        self.timeout = timeout
        self._profile = tempfile.TemporaryDirectory(prefix="wbc-browser-", ignore_cleanup_errors=True)
        arguments = [executable, "--headless", "--remote-debugging-port=0", f"--user-data-dir={self._profile.name}",
                     f"--window-size={width},{height}", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
                     "--no-first-run", "--no-default-browser-check", "--disable-background-networking",
                     "--disable-component-update", "--disable-extensions", "--hide-scrollbars", "about:blank"]
        if hasattr(os, "geteuid") and os.geteuid() == 0:
            arguments.insert(1, "--no-sandbox")  # Chromium refuses to run as root with its sandbox
        # a session of its own: close() ends the browser's helper processes with it
        self._process = subprocess.Popen(arguments, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                         start_new_session=True)
        try:
            port = self._devtools_port()
            with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=timeout) as response:
                page = next(target for target in json.load(response) if target["type"] == "page")
            self._socket = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=timeout)
        except BaseException:
            self.close()
            raise
        self._next_id = 0
        self.events: list[dict] = []
        self.call("Page.enable")
        self.call("Network.enable")
        self.call("Runtime.enable")
        # the viewport itself (--window-size counts the invisible window frame too)
        self.call("Emulation.setDeviceMetricsOverride", width=width, height=height, deviceScaleFactor=1, mobile=False)

    def _devtools_port(self) -> int:
        """The port the browser chose, from the DevToolsActivePort file of its profile."""
        marker = Path(self._profile.name) / "DevToolsActivePort"
        deadline = time.monotonic() + self.timeout
        while time.monotonic() < deadline:
            if self._process.poll() is not None:
                raise RuntimeError(f"the browser exited with status {self._process.returncode}")
            if marker.exists() and marker.read_text().strip():
                return int(marker.read_text().split()[0])
            time.sleep(0.1)
        raise TimeoutError("the browser did not open its DevTools port")

    def call(self, method: str, **params) -> dict:
        """Send one DevTools command and return its result (events are kept in ``events``)."""
        self._next_id += 1
        self._socket.send(json.dumps({"id": self._next_id, "method": method, "params": params}))
        while True:
            message = json.loads(self._socket.recv(timeout=self.timeout))
            if message.get("id") == self._next_id:
                if "error" in message:
                    raise RuntimeError(f"{method}: {message['error']}")
                return message.get("result", {})
            self.events.append(message)

    def open(self, url: str) -> None:
        """Navigate to ``url`` and wait for its load event."""
        self.call("Page.navigate", url=url)
        deadline = time.monotonic() + self.timeout
        while not any(event.get("method") == "Page.loadEventFired" for event in self.events):
            if time.monotonic() > deadline:
                raise TimeoutError(f"{url} did not load")
            self.events.append(json.loads(self._socket.recv(timeout=self.timeout)))

    def hide(self, selector: str) -> None:
        """Hide the page's elements matching the CSS ``selector``, now and when they appear later."""
        style = f"{selector} {{ display: none !important; }}"
        self.evaluate(f"document.head.appendChild(document.createElement('style')).textContent = {json.dumps(style)}")

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page."""
        return self.call("Runtime.evaluate", expression=expression, returnByValue=True)["result"].get("value")

    def screenshot(self) -> np.ndarray:
        """The page as an (height, width, 3) uint8 RGB array."""
        import base64

        from PIL import Image

        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB"))

    def wait_for(self, condition, poll: float = 0.5):
        """Screenshots until ``condition(image)`` holds; returns that image (TimeoutError after ``timeout``)."""
        deadline = time.monotonic() + self.timeout
        while True:
            image = self.screenshot()
            if condition(image):
                return image
            if time.monotonic() > deadline:
                raise TimeoutError("the page never showed what was waited for")
            time.sleep(poll)

    def requested_urls(self) -> list[str]:
        """Every URL the page requested so far (documents, scripts, fetches, images, sockets...)."""
        urls = [event["params"]["request"]["url"] for event in self.events
                if event.get("method") == "Network.requestWillBeSent"]
        urls += [event["params"]["url"] for event in self.events if event.get("method") == "Network.webSocketCreated"]
        return urls

    def close(self) -> None:
        socket = getattr(self, "_socket", None)
        if socket is not None:
            socket.close()
        for sig in (signal.SIGTERM, signal.SIGKILL):
            try:
                os.killpg(self._process.pid, sig)
                self._process.wait(timeout=10)
                break
            except ProcessLookupError:
                break
            except subprocess.TimeoutExpired:
                continue
        self._profile.cleanup()

    def __enter__(self) -> HeadlessBrowser:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
