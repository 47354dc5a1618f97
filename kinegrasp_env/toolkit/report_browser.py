"""Open a report in headless Chromium with the network off: console errors, load time,
WebGL canvases and a screenshot (no extra Python dependency).

Chromium is driven over its DevTools protocol on a pipe (``--remote-debugging-pipe``: file
descriptors 3 and 4 of the browser, JSON messages ending in a NUL byte). The network is off
three ways: every host name resolves to nothing (``--host-resolver-rules``), the page's
network is emulated offline, and every request the page makes is recorded, so a caller can
check that none left ``file:`` and ``data:`` URLs. WebGL runs on the CPU (SwiftShader).
"""

from __future__ import annotations

import base64
import fcntl
import io
import json
import logging
import os
import queue
import shutil
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
#: Headless, software WebGL, and nothing that reaches for the network by itself.
CHROMIUM_FLAGS = (
    "--headless", "--no-sandbox", "--disable-gpu", "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--disable-default-apps", "--disable-extensions", "--mute-audio", "--hide-scrollbars",
    "--host-resolver-rules=MAP * ~NOTFOUND", "--remote-debugging-pipe",
)
LOCAL_SCHEMES = ("file:", "data:", "blob:", "about:")
#: A 3-D canvas counts as drawn (not blank, not just its axes) when the standard deviation
#: of its grey levels is at least MIN_STD and it shows at least MIN_COLOURS distinct colours.
#: Measured on a 500-draw evaluation page: its two scenes 37 and 44, 3,290 and 7,137 colours;
#: the same grasp scene with an invisible trace (axes and background panels only) 6.5, 68.
MIN_STD, MIN_COLOURS = 15.0, 500


class BrowserError(RuntimeError):
    """Chromium could not be started or did not answer."""


def find_chromium() -> str | None:
    """Path of a Chromium executable on PATH (``$KINEGRASP_CHROMIUM`` first), or None."""
    override = os.environ.get("KINEGRASP_CHROMIUM")
    if override:
        return shutil.which(override)
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def _high_pipe() -> tuple[int, int]:
    """A close-on-exec pipe whose two ends are numbered 10 or above (never 3 or 4, which the
    child maps them onto)."""
    ends = []
    for fd in os.pipe():
        ends.append(fcntl.fcntl(fd, fcntl.F_DUPFD_CLOEXEC, 10))
        os.close(fd)
    return ends[0], ends[1]


class Chromium:
    """A headless Chromium with one page, driven over the DevTools pipe.

    Use as a context manager; :meth:`call` sends a command to the page (or, with
    ``browser=True``, to the browser) and returns its result; events are kept in
    :attr:`events` in arrival order.
    """

    def __init__(self, executable: str | None = None, width: int = 1400,
                 height: int = 1000) -> None:
        self.executable = executable or find_chromium()
        if self.executable is None:
            raise BrowserError("no chromium executable on PATH")
        self.size = (width, height)
        self.events: list[dict] = []
        self._replies: queue.Queue = queue.Queue()
        self._next_id = 0
        self.session = ""

    def __enter__(self) -> Chromium:
        self._profile = tempfile.TemporaryDirectory(prefix="kinegrasp-chromium-")
        to_browser_r, self._to_browser = _high_pipe()
        self._from_browser, from_browser_w = _high_pipe()
        width, height = self.size
        command = [self.executable, *CHROMIUM_FLAGS, f"--user-data-dir={self._profile.name}",
                   f"--window-size={width},{height}", "about:blank"]
        def wire() -> None:  # in the child, before exec: the pipe ends become fds 3 and 4
            os.dup2(to_browser_r, 3)
            os.dup2(from_browser_w, 4)

        # close_fds=False: fds 3 and 4 survive the exec; every other descriptor Python made
        # is close-on-exec (PEP 446), the pipe ends above included
        self.process = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL, preexec_fn=wire, close_fds=False)
        os.close(to_browser_r)
        os.close(from_browser_w)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        target = self.call("Target.createTarget", {"url": "about:blank"}, browser=True)
        self.session = self.call("Target.attachToTarget", {"targetId": target["targetId"],
                                                           "flatten": True},
                                 browser=True)["sessionId"]
        return self

    def __exit__(self, *exc) -> None:
        try:
            self.call("Browser.close", browser=True, timeout=5)
        except BrowserError:
            pass
        try:
            self.process.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        os.close(self._to_browser)
        self._profile.cleanup()

    def _read(self) -> None:
        buffer = b""
        with os.fdopen(self._from_browser, "rb", buffering=0) as pipe:
            while chunk := pipe.read(1 << 16):
                buffer += chunk
                *messages, buffer = buffer.split(b"\0")
                for raw in messages:
                    message = json.loads(raw)
                    (self._replies.put if "id" in message else self.events.append)(message)
        self._replies.put(None)

    def call(self, method: str, params: dict | None = None, *, browser: bool = False,
             timeout: float = 60.0) -> dict:
        """Send one DevTools command and wait for its reply; BrowserError on an error."""
        self._next_id += 1
        message = {"id": self._next_id, "method": method, "params": params or {}}
        if not browser:
            message["sessionId"] = self.session
        try:
            os.write(self._to_browser, json.dumps(message).encode() + b"\0")
        except OSError as exc:
            raise BrowserError(f"chromium is gone ({exc})") from None
        deadline = time.monotonic() + timeout
        while True:
            try:
                reply = self._replies.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise BrowserError(f"no reply to {method} within {timeout:g} s") from None
            if reply is None:
                raise BrowserError(f"chromium closed the pipe during {method}")
            if reply["id"] == self._next_id:
                if "error" in reply:
                    raise BrowserError(f"{method}: {reply['error'].get('message')}")
                return reply.get("result", {})

    def evaluate(self, expression: str):
        """The value of a JavaScript expression in the page (JSON-serializable)."""
        result = self.call("Runtime.evaluate", {"expression": expression,
                                                "returnByValue": True, "awaitPromise": True})
        return result.get("result", {}).get("value")


@dataclass
class PageCheck:
    """What loading a page in Chromium showed.

    Attributes:
        errors: console errors, uncaught exceptions and error log entries, as text.
        requests: every URL the page requested; remote: those outside file:/data:/blob:.
        ready_ms: ``window.kgReady`` (ms from navigation start until every eager figure was
            drawn), None if never set; parsed_ms: ms until the document was parsed (the
            DOMContentLoaded event: plotly.js and the data read, drawing starts); wall_s:
            seconds from navigation to ready (or to the timeout).
        rendered: figures drawn (``window.kgRendered``); expected: eager figures on the page.
        webgl: the renderer string of a fresh WebGL context ('' if WebGL is unavailable).
        canvases: (x, y, width, height) CSS pixels of each 3-D scene's WebGL canvas.
        screenshot: PNG of the whole page.
        probe: the value of the caller's ``probe`` expression, evaluated last.
    """

    errors: list[str] = field(default_factory=list)
    requests: list[str] = field(default_factory=list)
    ready_ms: float | None = None
    parsed_ms: float | None = None
    wall_s: float = 0.0
    rendered: int = 0
    expected: int = 0
    webgl: str = ""
    canvases: list[tuple[float, float, float, float]] = field(default_factory=list)
    screenshot: bytes = b""
    probe: object = None

    @property
    def remote(self) -> list[str]:
        return [u for u in self.requests if not u.startswith(LOCAL_SCHEMES)]

    def problems(self, scenes: int, min_std: float = MIN_STD,
                 min_colours: int = MIN_COLOURS) -> list[str]:
        """What is wrong with the page, one line each (empty: it works).

        A page works when it raised no console error, requested nothing outside the file,
        drew every eager figure, and shows at least ``scenes`` WebGL canvases, each with a
        grey-level standard deviation of at least ``min_std`` and ``min_colours`` distinct
        colours (a blank canvas, or one with axes only, fails).
        """
        out = [f"console: {e}" for e in self.errors]
        out += [f"network request: {u}" for u in self.remote]
        if self.ready_ms is None:
            out.append("the page never finished drawing its figures (window.kgReady unset)")
        if self.rendered < self.expected:
            out.append(f"{self.rendered} of {self.expected} figures drawn")
        if not self.webgl:
            out.append("WebGL is unavailable")
        if len(self.canvases) < scenes:
            out.append(f"{len(self.canvases)} WebGL canvases, expected {scenes}")
        for rect in self.canvases:
            stats = pixel_stats(self.screenshot, rect)
            if stats["std"] < min_std or stats["colours"] < min_colours:
                out.append(f"canvas at {tuple(round(v) for v in rect)} looks blank: grey "
                           f"level std {stats['std']:.1f}, {stats['colours']} colours")
        return out


def _errors(events: list[dict]) -> list[str]:
    """Console errors, uncaught exceptions and error log entries among DevTools events."""
    out = []
    for event in events:
        method, params = event.get("method"), event.get("params", {})
        if method == "Runtime.exceptionThrown":
            details = params.get("exceptionDetails", {})
            text = details.get("exception", {}).get("description") or details.get("text", "")
            out.append(f"exception: {text}")
        elif method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            args = params.get("args", [])
            out.append("console.error: " + " ".join(str(a.get("value", a.get("description")))
                                                    for a in args))
        elif method == "Log.entryAdded" and params.get("entry", {}).get("level") == "error":
            entry = params["entry"]
            out.append(f"log ({entry.get('source')}): {entry.get('text')} {entry.get('url', '')}")
    return out


CANVAS_RECTS = """Array.from(document.querySelectorAll('.js-plotly-plot .gl-container canvas'))
  .map(c => c.getBoundingClientRect()).filter(r => r.width > 0 && r.height > 0)
  .map(r => [r.x + window.scrollX, r.y + window.scrollY, r.width, r.height])"""
WEBGL_RENDERER = """(() => { const gl = document.createElement('canvas').getContext('webgl');
  return gl ? String(gl.getParameter(gl.RENDERER)) + ' / ' + String(gl.getParameter(
    gl.VERSION)) : ''; })()"""


def _open(browser: Chromium, path: Path) -> None:
    for domain in ("Page", "Runtime", "Log", "Network"):
        browser.call(f"{domain}.enable")
    browser.call("Network.emulateNetworkConditions", {
        "offline": True, "latency": 0, "downloadThroughput": -1, "uploadThroughput": -1})
    width, height = browser.size
    browser.call("Emulation.setDeviceMetricsOverride", {
        "width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
    browser.call("Page.navigate", {"url": path.resolve().as_uri()})


def _wait_ready(browser: Chromium, timeout: float) -> tuple[float | None, float]:
    start = time.monotonic()
    while time.monotonic() - start < timeout:
        ready = browser.evaluate("window.kgReady === undefined ? null : window.kgReady")
        if ready is not None:
            return float(ready), time.monotonic() - start
        time.sleep(0.05)
    return None, time.monotonic() - start


def screenshot(browser: Chromium) -> bytes:
    """PNG of the whole page (beyond the viewport)."""
    size = browser.evaluate("[document.documentElement.scrollWidth, "
                            "document.documentElement.scrollHeight]")
    shot = browser.call("Page.captureScreenshot", {
        "format": "png", "captureBeyondViewport": True,
        "clip": {"x": 0, "y": 0, "width": size[0], "height": size[1], "scale": 1}})
    return base64.b64decode(shot["data"])


def check_page(path: str | Path, *, timeout: float = 60.0, settle: float = 0.5,
               before_screenshot: str | None = None, probe: str | None = None,
               executable: str | None = None, width: int = 1400,
               height: int = 1000) -> PageCheck:
    """Load a report in headless Chromium (network off) and report what happened.

    Args:
        path: the HTML file.
        timeout: seconds to wait for ``window.kgReady``.
        settle: seconds to wait after it (WebGL frames, late errors) before the screenshot.
        before_screenshot: JavaScript to run first (e.g. open a ranking's 3-D view); the page
            settles again after it.
        probe: a JavaScript expression evaluated last; its (JSON) value is kept.
    """
    path = Path(path)
    check = PageCheck()
    with Chromium(executable, width, height) as browser:
        _open(browser, path)
        check.ready_ms, check.wall_s = _wait_ready(browser, timeout)
        time.sleep(settle)
        if before_screenshot:
            browser.evaluate(before_screenshot)
            time.sleep(settle + 1.0)
        check.parsed_ms = browser.evaluate(
            "performance.getEntriesByType('navigation')[0].domContentLoadedEventStart")
        check.rendered = int(browser.evaluate("window.kgRendered || 0"))
        check.expected = int(browser.evaluate(
            "document.querySelectorAll('div.kg-plot:not([data-lazy])').length"))
        check.webgl = browser.evaluate(WEBGL_RENDERER) or ""
        check.canvases = [tuple(r) for r in browser.evaluate(CANVAS_RECTS) or []]
        check.screenshot = screenshot(browser)
        check.probe = browser.evaluate(probe) if probe else None
        check.errors = _errors(browser.events)
        check.requests = [e["params"]["request"]["url"] for e in browser.events
                          if e.get("method") == "Network.requestWillBeSent"]
    log.info("%s: ready after %s ms, %d errors", path, check.ready_ms, len(check.errors))
    return check


def pixel_stats(png: bytes, rect: tuple[float, float, float, float] | None = None) -> dict:
    """Statistics of a screenshot's pixels inside ``rect`` (x, y, width, height; CSS pixels
    at scale 1), or of the whole image.

    Returns:
        ``std`` (standard deviation of the grey level, 0..255), ``colours`` (distinct RGB
        values) and ``foreground`` (fraction of pixels differing by more than 8 grey levels,
        in some channel, from the most common colour: the background).
    """
    from PIL import Image

    image = np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)
    if rect is not None:
        x, y, w, h = (round(v) for v in rect)
        image = image[max(0, y):y + h, max(0, x):x + w]
    flat = image.reshape(-1, 3)
    packed = (flat[:, 0].astype(np.int64) << 16) | (flat[:, 1] << 8) | flat[:, 2]
    values, counts = np.unique(packed, return_counts=True)
    top = values[np.argmax(counts)]
    background = np.array([(top >> 16) & 255, (top >> 8) & 255, top & 255])
    differs = np.abs(flat - background).max(axis=1) > 8
    return {"std": float(flat.mean(axis=1).std()), "colours": len(values),
            "foreground": float(differs.mean()), "pixels": len(flat)}
