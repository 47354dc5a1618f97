"""Self-contained interactive HTML reports and the browser that checks them.

The pages, the same for every robot: one per evaluation or report of a robot's grasps
(``robot``), one per ranking (``ranking``), one per elbow optimization (``elbow``) and a
6-joint arm's IK branches (``robot_branches``); what they share (``page``); what they are
built from: the 3-D scenes (``scene``), the arm at noisy draws (``arms``) and their geometry
(``geometry``), the 2-D charts (``charts``), plotly.js figures and shared meshes
(``plotly``) and the HTML around them (``html``). Pages open offline (plotly.js is inline)
and are deterministic. ``browser`` opens a page in the system's headless Chromium through
Playwright (the ``screenshot`` extra, imported only when a browser starts) with every
request off the machine refused: console errors, WebGL canvases, a screenshot. Uses the
toolkit's elbow results, ``montecarlo`` and below.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "page": ("write_page", "PAGE_LIMIT_BYTES", "ARM_DRAWS"),
    "ranking": ("rank_page",),
    "elbow": ("elbow_page",),
    "robot": ("robot_page",),
    "robot_branches": ("robot_branch_page",),
    "scene": ("MAX_POINTS",),
    "browser": ("OfflineChromium", "PageCheck", "BrowserError", "check_page", "find_chromium",
                "pixel_stats"),
})
