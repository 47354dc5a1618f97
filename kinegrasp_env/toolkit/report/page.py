"""What every report page shares: the noise sources table, number formats, the versions
line, atomic writing, the size limit.

The page of an evaluation or a report (one or several grasps, one or several noise levels or
a noise model) is :mod:`~kinegrasp_env.toolkit.report.robot`'s, the ranking page
:mod:`~kinegrasp_env.toolkit.report.ranking`'s, the elbow page
:mod:`~kinegrasp_env.toolkit.report.elbow`'s. Pages open offline (plotly.js is inline) and
are deterministic: the same runs give the same bytes.

Size: plotly.js is about 4.8 MB; a 10,000-draw evaluation page stays under
:data:`PAGE_LIMIT_BYTES` because at most ``max_points`` contact points are drawn (a uniform
random subset past that, said on the page).
"""

from __future__ import annotations

import math
from importlib import metadata
from pathlib import Path

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.sampling.noise_model import SOURCES
from kinegrasp_env.toolkit.report.html import esc
from kinegrasp_env.toolkit.report.plotly import plotly_version

#: A 10,000-draw evaluation page stays under this size (bytes); tested.
PAGE_LIMIT_BYTES = 7_000_000
#: Noisy draws whose arm skeletons are drawn.
ARM_DRAWS = 20


def versions() -> str:
    try:
        own = metadata.version("kinegrasp-env")
    except metadata.PackageNotFoundError:  # pragma: no cover - running from a bare checkout
        own = "unknown"
    return f"written by kinegrasp {own} with plotly.js from plotly {plotly_version()}"


def sigma_text(sigma) -> str:
    return f"{sigma:g}" if isinstance(sigma, float) else ",".join(f"{s:g}" for s in sigma)


#: Units of a noise spec's settings (docs/noise_example.yaml); friction's are plain numbers.
SPEC_UNITS = {"sigma": "rad", "bias": "rad", "covariance": "rad^2", "spread_sigma": "rad",
              "closing_sigma": "rad", "translation_sigma": "m", "rotation_sigma": "rad"}


def spec_settings(section: dict, source: str = "") -> str:
    """One source's settings as text: ``key value unit`` pairs (friction's without units:
    its values are coefficients)."""
    def value(v):
        return ", ".join(value(x) for x in v) if isinstance(v, list) else (
            f"{v:g}" if isinstance(v, float) else str(v))

    units = {} if source == "friction" else SPEC_UNITS
    return "; ".join(f"{k} {value(v)}" + (f" {units[k]}" if k in units else "")
                     for k, v in section.items())


def noise_sources_table(spec: dict) -> str:
    """The sources of a noise model's spec (``spec_of(model)``) and their settings; the
    sources it leaves out are exact."""
    rows = "".join(
        f'<tr><td class="kg-text">{esc(name)}</td><td class="kg-text">'
        f"{esc(spec_settings(spec[name], name) if name in spec else 'exact (not in the spec)')}"
        "</td></tr>" for name in SOURCES)
    return (f"<table><tr><th class='kg-text'>source</th><th class='kg-text'>settings</th>"
            f"</tr>{rows}</table>")


def fmt(value: float, digits: int = 5) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def write_page(path: str | Path, content: str | bytes) -> Path:
    """Write a page (text, as UTF-8) or a screenshot (bytes) atomically
    (:func:`~kinegrasp_env.atomic_files.write_atomic`: a temporary file in the same folder,
    then a rename; a new file gets 0666 less the umask, a rewritten one keeps its mode)."""
    path = Path(path)
    write_atomic(path, content.encode() if isinstance(content, str) else content)
    return path
