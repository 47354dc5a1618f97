"""Self-contained interactive HTML reports and the browser that checks them.

The pages: one per evaluation and one per ranking (``page``), one per elbow optimization
(``elbow``); what they are built from: the 3-D scenes (``scene``) and their geometry
(``geometry``), the 2-D charts (``charts``), plotly.js figures and shared meshes
(``plotly``) and the HTML around them (``html``). Pages open offline (plotly.js is inline)
and are deterministic. ``browser`` opens a page in the system's headless Chromium through
Playwright (the ``screenshot`` extra, imported only when a browser starts) with every
request off the machine refused: console errors, WebGL canvases, a screenshot. Uses the
toolkit's elbow results, ``montecarlo`` and below.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "evaluation_page": "page",
    "rank_page": "page",
    "write_page": "page",
    "PAGE_LIMIT_BYTES": "page",
    "ARM_DRAWS": "page",
    "elbow_page": "elbow",
    "MAX_POINTS": "scene",
    "OfflineChromium": "browser",
    "PageCheck": "browser",
    "BrowserError": "browser",
    "check_page": "browser",
    "find_chromium": "browser",
    "pixel_stats": "browser",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
