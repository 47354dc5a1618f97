"""Self-contained interactive HTML reports: what every page shares (the noise sources
table, the versions line, atomic writing) and the ranking page.

A ranking page holds the sortable table and each candidate's 3-D views on demand. The page
of an evaluation or a report (one or several grasps, one or several noise levels or a noise
model) is :mod:`~kinegrasp_env.toolkit.report.robot`'s; the elbow page is
:mod:`~kinegrasp_env.toolkit.report.elbow`'s. Pages open offline (plotly.js is inline) and
are deterministic: the same runs give the same bytes.

Size: plotly.js is about 4.8 MB; a 10,000-draw evaluation page stays under
:data:`PAGE_LIMIT_BYTES` because at most ``max_points`` contact points are drawn (a uniform
random subset past that, said on the page).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path

import numpy as np

from kinegrasp_env.montecarlo.evaluate import Noise
from kinegrasp_env.sampling.noise_model import SOURCES
from kinegrasp_env.toolkit.report.geometry import (
    closed_configuration,
    kinematics,
    noisy_configurations,
)
from kinegrasp_env.toolkit.report.html import (
    Figure,
    command_block,
    esc,
    page,
    settings_table,
)
from kinegrasp_env.toolkit.report.plotly import MeshLibrary, plotly_version
from kinegrasp_env.toolkit.report.scene import arm_scene, grasp_scene
from kinegrasp_env.world.grasps import Grasp, write_atomic
from kinegrasp_env.world.objects import load_object

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


def candidate_figures(grasp: Grasp, key: str, noisy: np.ndarray, library: MeshLibrary, *,
                      friction: float, num_edges: int) -> list[Figure]:
    """A ranking candidate's two 3-D views (drawn on demand)."""
    obj = load_object(grasp.object)
    closed, _ = closed_configuration(grasp.q0, obj)
    return [Figure(f"{key}-grasp", grasp_scene(obj, grasp, library, closed, friction=friction,
                                               num_edges=num_edges,
                                               title=f"grasp {grasp.id}: object frame"),
                   "49%", "460px", lazy=True),
            Figure(f"{key}-arm", arm_scene(obj, closed, library, noisy, None,
                                           "arm: world frame"), "49%", "460px", lazy=True)]


RANK_COLUMNS = ("rank", "id", "P(FC)", "95% CI", "Q mean", "Q std", "Q nominal",
                "elbow psi [rad]", "draws", "3-D")


def rank_row(position: int, row: dict, psi: float, key: str) -> str:
    """One sortable table row (numbers in ``data-value``)."""
    def num(value, text):
        shown = text if value is not None and math.isfinite(value) else "-"
        stored = value if value is not None and math.isfinite(value) else "NaN"
        return f'<td data-value="{stored}">{shown}</td>'

    cells = [num(position, str(position)), f'<td class="kg-text">{esc(row["id"])}</td>',
             num(row["p_fc"], f'{row["p_fc"]:.4f}'),
             num(row["p_fc_lo"], f'{row["p_fc_lo"]:.4f} .. {row["p_fc_hi"]:.4f}'),
             num(row["q_mean"], fmt(row["q_mean"])), num(row["q_std"], fmt(row["q_std"])),
             num(row["q_nominal"], fmt(row["q_nominal"])), num(psi, f"{psi:.3f}"),
             num(row["samples"], str(row["samples"])),
             f'<td><button class="kg-show" data-detail="detail-{key}" '
             f'onclick="kgToggle(this)">show 3-D</button></td>']
    return (f'<tr class="kg-item" data-detail="detail-{key}" data-id="{esc(row["id"])}">'
            f'{"".join(cells)}</tr>')


def rank_page(grasps: Sequence[Grasp], rows: Sequence[dict], *, command: str, settings: dict,
              noise: Noise, seed: int, samples: int, arm_draws: int = 10,
              friction: float = 0.5, num_edges: int = 8) -> str:
    """The HTML page of a ranking.

    Args:
        grasps: the candidates, in file order.
        rows: best first; each with ``index`` (into grasps), ``id``, ``p_fc``, ``p_fc_lo``,
            ``p_fc_hi``, ``q_mean``, ``q_std``, ``q_nominal``, ``samples``.
        noise, seed, samples: the ranking's noise (the skeletons of the first ``arm_draws``
            draws are drawn, the same for every candidate: common random numbers).
    """
    psi = kinematics().arm_angle(np.stack([g.q0 for g in grasps]))
    figures, body_rows, library = [], [], MeshLibrary()
    for position, row in enumerate(rows, 1):
        grasp = grasps[row["index"]]
        key = f"c{row['index']}"
        noisy = noisy_configurations(grasp.q0, noise, seed, samples, arm_draws)
        views = candidate_figures(grasp, key, noisy, library, friction=friction,
                                  num_edges=num_edges)
        figures += views
        body_rows.append(rank_row(position, row, float(psi[row["index"]]), key))
        body_rows.append(f'<tr id="detail-{key}" style="display: none;"><td colspan='
                         f'"{len(RANK_COLUMNS)}"><div class="kg-row">'
                         f'{"".join(v.div() for v in views)}</div></td></tr>')
    head = "".join(f'<th{" class=kg-text" if c == "id" else ""}>{esc(c)}</th>'
                   for c in RANK_COLUMNS)
    object_name = grasps[0].object
    title = f"kinegrasp ranking: {len(rows)} candidates of {object_name}"
    body = (f"<h1>{esc(title)}</h1><p class='kg-headline'>Click a column header to sort; "
            "<i>show 3-D</i> draws a candidate's grasp (object frame) and arm (world frame, "
            f"with the skeletons of the first {arm_draws} noisy draws, the same noise for "
            "every candidate).</p>"
            f'<table class="kg-sortable"><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body_rows)}</tbody></table>"
            f"<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    return page(title, body, figures, library, versions())


def write_page(path: str | Path, content: str | bytes) -> Path:
    """Write a page (text, as UTF-8) or a screenshot (bytes) atomically
    (:func:`~kinegrasp_env.world.grasps.write_atomic`: a temporary file in the same folder,
    then a rename; a new file gets 0666 less the umask, a rewritten one keeps its mode)."""
    path = Path(path)
    write_atomic(path, content.encode() if isinstance(content, str) else content)
    return path
