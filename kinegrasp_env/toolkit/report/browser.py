"""Open a page in the system's headless Chromium, driven by Playwright, with nothing leaving
the machine: console errors, load time, WebGL canvases and a screenshot.

Playwright (the ``screenshot`` extra: ``pip install 'kinegrasp-env[screenshot]'``) is imported
only when a browser starts; it drives the Chromium already installed (``/usr/bin/chromium``,
``$KINEGRASP_CHROMIUM`` first), it never downloads one. The network is off two ways: every host
name resolves to nothing (``--host-resolver-rules``), and every request outside ``file:``,
``data:``, ``blob:`` and ``about:`` is aborted by a route and recorded, so that a caller can
fail when one was attempted (:attr:`OfflineChromium.remote`). WebGL runs on the CPU
(SwiftShader).
"""

from __future__ import annotations

import io
import logging
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

#: Where Chromium is looked for, in order (``$KINEGRASP_CHROMIUM`` before all).
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
#: Software WebGL, and nothing that reaches for the network by itself (Playwright adds
#: ``--headless``, ``--no-sandbox`` and a fresh profile).
CHROMIUM_FLAGS = (
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--disable-gpu",
    "--disable-quic", "--no-first-run", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--disable-default-apps",
    "--disable-extensions", "--mute-audio", "--hide-scrollbars",
    "--host-resolver-rules=MAP * ~NOTFOUND",
)
LOCAL_SCHEMES = ("file:", "data:", "blob:", "about:")
#: The one-line message when Playwright is not installed.
MISSING_PLAYWRIGHT = ("the browser needs Playwright: pip install 'kinegrasp-env[screenshot]' "
                      "(it drives the system's Chromium; no browser is downloaded)")
#: A 3-D canvas counts as drawn (not blank, not just its axes) when the standard deviation
#: of its grey levels is at least MIN_STD and it shows at least MIN_COLOURS distinct colours.
#: Measured on a 500-draw evaluation page: its two scenes 37 and 44, 3,290 and 7,137 colours;
#: the same grasp scene with an invisible trace (axes and background panels only) 6.5, 68.
MIN_STD, MIN_COLOURS = 15.0, 500


class BrowserError(RuntimeError):
    """Chromium could not be started, or Playwright is missing."""


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


def load_playwright():
    """Playwright's ``sync_playwright`` (imported here, on first use); BrowserError with
    :data:`MISSING_PLAYWRIGHT` when the package is not installed."""
    try:
        from playwright.sync_api import sync_playwright as start
    except ImportError:
        raise BrowserError(MISSING_PLAYWRIGHT) from None
    return start


def from_playwright(exc: BaseException) -> bool:
    """Whether ``exc`` is one of Playwright's errors (its classes load with it, lazily)."""
    return type(exc).__module__.startswith("playwright")


def first_line(exc: BaseException) -> str:
    """The first line of an error's message (its class name when it has none)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def is_local(url: str) -> bool:
    """Whether ``url`` stays on the machine (file:, data:, blob:, about:)."""
    return url.startswith(LOCAL_SCHEMES)


class OfflineChromium:
    """The system's headless Chromium under Playwright, one context, no network.

    Use as a context manager. Every request of every page is kept in :attr:`requests`;
    those leaving the machine are aborted and are :attr:`remote` (a WebSocket counts too).
    :meth:`new_page` opens a page whose console errors, uncaught exceptions and failed local
    requests are collected in a list.

    Args:
        executable: the Chromium binary (default: :func:`find_chromium`).
        width, height: the viewport, CSS pixels (device scale factor 1).
    """

    def __init__(self, executable: str | None = None, width: int = 1400,
                 height: int = 1000) -> None:
        self.executable = executable or find_chromium()
        if self.executable is None:
            raise BrowserError("no chromium executable on PATH (Debian: apt-get install "
                               "chromium)")
        self.size = (width, height)
        self.requests: list[str] = []

    @property
    def remote(self) -> list[str]:
        """The requests that tried to leave the machine (all of them aborted)."""
        return [u for u in self.requests if not is_local(u)]

    def __enter__(self) -> OfflineChromium:
        start = load_playwright()
        self._playwright = start().start()
        try:
            self.browser = self._playwright.chromium.launch(
                executable_path=self.executable, headless=True, args=list(CHROMIUM_FLAGS))
            width, height = self.size
            self.context = self.browser.new_context(
                viewport={"width": width, "height": height}, device_scale_factor=1,
                service_workers="block")
            self.context.on("request", lambda request: self.requests.append(request.url))
            self.context.route("**/*", self._route)
        except Exception as exc:
            self._playwright.stop()
            if not from_playwright(exc):
                raise
            raise BrowserError(f"chromium did not start: {first_line(exc)}") from None
        return self

    def __exit__(self, *exc) -> None:
        try:
            self.context.close()
            self.browser.close()
        finally:
            self._playwright.stop()

    @staticmethod
    def _route(route) -> None:
        if is_local(route.request.url):
            route.continue_()
        else:
            route.abort("blockedbyclient")

    def new_page(self):
        """A new page and the list its errors go to (``console.error``, uncaught
        exceptions, local requests that failed), as text, in arrival order."""
        page = self.context.new_page()
        errors: list[str] = []

        def console(message) -> None:
            if message.type in ("error", "assert"):
                errors.append(f"console.{message.type}: {message.text}")

        def failed(request) -> None:
            if is_local(request.url):
                errors.append(f"request failed: {request.url} ({request.failure})")

        page.on("console", console)
        page.on("pageerror", lambda exc: errors.append(f"exception: {exc}"))
        page.on("requestfailed", failed)
        page.on("websocket", lambda socket: self.requests.append(socket.url))
        return page, errors


@dataclass
class PageCheck:
    """What loading a page in Chromium showed.

    Attributes:
        errors: console errors, uncaught exceptions and failed local requests, as text.
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
        return [u for u in self.requests if not is_local(u)]

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
            out.append("the page never finished drawing its figures (window.kgReady unset)"
                       if self.expected else "the page has no kinegrasp figure (not a "
                       "kinegrasp report?)")
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


CANVAS_RECTS = """Array.from(document.querySelectorAll('.js-plotly-plot .gl-container canvas'))
  .map(c => c.getBoundingClientRect()).filter(r => r.width > 0 && r.height > 0)
  .map(r => [r.x + window.scrollX, r.y + window.scrollY, r.width, r.height])"""
WEBGL_RENDERER = """(() => { const gl = document.createElement('canvas').getContext('webgl');
  return gl ? String(gl.getParameter(gl.RENDERER)) + ' / ' + String(gl.getParameter(
    gl.VERSION)) : ''; })()"""


#: When a page is done: a report has set ``window.kgReady``; a page of no report figure (no
#: ``div.kg-plot``, not a kinegrasp page) has loaded, with nothing to wait for.
READY = ("window.kgReady !== undefined || (document.readyState === 'complete' "
         "&& !document.querySelector('div.kg-plot'))")


def _wait_ready(page, timeout: float) -> tuple[float | None, float]:
    """``window.kgReady`` once set (None after ``timeout`` seconds, or at once where the
    page has loaded with no report figure) and the seconds waited."""
    start = time.monotonic()
    try:
        page.wait_for_function(READY, timeout=timeout * 1000, polling=50)
    except Exception as exc:  # playwright's TimeoutError, imported lazily
        if not (from_playwright(exc) and type(exc).__name__ == "TimeoutError"):
            raise
        return None, time.monotonic() - start
    ready = page.evaluate("window.kgReady")
    return (None if ready is None else float(ready)), time.monotonic() - start


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
        executable, width, height: as for :class:`OfflineChromium`.
    """
    path = Path(path)
    try:
        check = _check(path, timeout, settle, before_screenshot, probe,
                       OfflineChromium(executable, width, height))
    except Exception as exc:
        if not from_playwright(exc):
            raise
        raise BrowserError(f"{path}: {first_line(exc)}") from None
    log.info("%s: ready after %s ms, %d errors", path, check.ready_ms, len(check.errors))
    return check


def _check(path: Path, timeout: float, settle: float, before_screenshot: str | None,
           probe: str | None, chromium: OfflineChromium) -> PageCheck:
    check = PageCheck()
    with chromium as browser:
        page, errors = browser.new_page()
        page.goto(path.resolve().as_uri(), wait_until="commit")
        check.ready_ms, check.wall_s = _wait_ready(page, timeout)
        page.wait_for_timeout(settle * 1000)
        if before_screenshot:
            page.evaluate(before_screenshot)
            page.wait_for_timeout((settle + 1.0) * 1000)
        check.parsed_ms = page.evaluate(
            "performance.getEntriesByType('navigation')[0].domContentLoadedEventStart")
        check.rendered = int(page.evaluate("window.kgRendered || 0"))
        check.expected = int(page.evaluate(
            "document.querySelectorAll('div.kg-plot:not([data-lazy])').length"))
        check.webgl = page.evaluate(WEBGL_RENDERER) or ""
        check.canvases = [tuple(r) for r in page.evaluate(CANVAS_RECTS) or []]
        check.screenshot = page.screenshot(full_page=True, type="png")
        check.probe = page.evaluate(probe) if probe else None
        check.errors = list(errors)
        check.requests = list(browser.requests)
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
