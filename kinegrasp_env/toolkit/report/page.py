"""Self-contained interactive HTML reports: one page per evaluation, one per ranking.

An evaluation page holds the grasp's 3-D view (object, hand, nominal contacts with friction
cones, every draw's contact points by outcome or finger), the arm's 3-D view (nominal links,
a few noisy draws' skeletons), Q's histogram over the force-closure draws, the outcome
counts, P(FC) with its Wilson interval, P(FC) against sigma when several sigmas were run, the
settings and the command that reproduces the page; under a noise model of several sources
(``--noise-spec``) it also lists the sources and their settings. A ranking page holds the
sortable table and each candidate's 3-D views on demand. The elbow page is
:mod:`~kinegrasp_env.toolkit.report.elbow`. Pages open offline (plotly.js is inline) and are
deterministic: the same runs give the same bytes.

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

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import DEFAULT_CHUNK, GraspStats, Noise
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import SOURCES
from kinegrasp_env.sampling.noise_spec import noise_model_from_spec
from kinegrasp_env.toolkit.report.charts import outcome_bars, pfc_curve, quality_histogram
from kinegrasp_env.toolkit.report.geometry import (
    closed_configuration,
    kinematics,
    noisy_configurations,
)
from kinegrasp_env.toolkit.report.html import (
    Figure,
    command_block,
    esc,
    note,
    page,
    settings_table,
)
from kinegrasp_env.toolkit.report.plotly import MeshLibrary, plotly_version
from kinegrasp_env.toolkit.report.scene import MAX_POINTS, arm_scene, contact_cloud, grasp_scene
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


def run_noise(stats: GraspStats) -> Noise:
    """The noise a run drew: its noise model (``stats.noise_model``) or its joint noise."""
    if stats.noise_model is not None:
        return noise_model_from_spec(stats.noise_model)
    return JointNoise(stats.sigma if isinstance(stats.sigma, float) else tuple(stats.sigma),
                      stats.noise)


#: Units of a noise spec's settings (docs/noise_example.yaml); friction's are plain numbers.
SPEC_UNITS = {"sigma": "rad", "bias": "rad", "covariance": "rad^2", "spread_sigma": "rad",
              "closing_sigma": "rad", "translation_sigma": "m", "rotation_sigma": "rad"}


def spec_settings(section: dict) -> str:
    """One source's settings as text: ``key value unit`` pairs."""
    def value(v):
        return ", ".join(value(x) for x in v) if isinstance(v, list) else (
            f"{v:g}" if isinstance(v, float) else str(v))

    return "; ".join(f"{k} {value(v)}" + (f" {SPEC_UNITS[k]}" if k in SPEC_UNITS else "")
                     for k, v in section.items())


def noise_sources_table(spec: dict) -> str:
    """The sources of a noise model's spec (``spec_of(model)``) and their settings; the
    sources it leaves out are exact."""
    rows = "".join(
        f'<tr><td class="kg-text">{esc(name)}</td><td class="kg-text">'
        f"{esc(spec_settings(spec[name]) if name in spec else 'exact (not in the spec)')}"
        "</td></tr>" for name in SOURCES)
    return (f"<table><tr><th class='kg-text'>source</th><th class='kg-text'>settings</th>"
            f"</tr>{rows}</table>")


def noise_label(stats: GraspStats) -> str:
    """What the run's noise was, in words."""
    if stats.noise_model == {}:
        return "a noise model with every source exact"
    if stats.noise_model is not None:
        return f"a noise model of {len(stats.noise_model)} sources ({', '.join(stats.noise_model)})"
    return f"sigma = {sigma_text(stats.sigma)} rad ({stats.noise})"


def headline(stats: GraspStats) -> str:
    lo, hi = stats.p_fc_ci
    q = (f"Q: nominal {stats.q_nominal:.5f}, mean {fmt(stats.q_mean)}, std {fmt(stats.q_std)},"
         f" skewness {fmt(stats.q_skew, 3)}")
    return (f"<p class='kg-headline'><b>P(FC) = {stats.p_fc:.4f}</b> (95% CI {lo:.4f} .. "
            f"{hi:.4f}) over {stats.samples} draws under {esc(noise_label(stats))}; {q}</p>")


def fmt(value: float, digits: int = 5) -> str:
    return "-" if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def runs_table(runs: Sequence[GraspStats]) -> str:
    head = "".join(f"<th>{h}</th>" for h in ("sigma [rad]", "P(FC)", "95% CI", "Q mean",
                                              "Q std", "draws"))
    rows = "".join(
        f"<tr><td>{esc(sigma_text(s.sigma))}</td><td>{s.p_fc:.4f}</td>"
        f"<td>{s.p_fc_ci[0]:.4f} .. {s.p_fc_ci[1]:.4f}</td><td>{fmt(s.q_mean)}</td>"
        f"<td>{fmt(s.q_std)}</td><td>{s.samples}</td></tr>" for s in runs)
    return f"<table><tr>{head}</tr>{rows}</table>"


def evaluation_figures(grasp: Grasp, stats: GraspStats, library: MeshLibrary, *,
                       friction: float, num_edges: int, max_points: int, arm_draws: int,
                       chunk: int) -> tuple[list, list[str]]:
    """The 3-D views, histogram and outcome bars of one run with draws, and the notes."""
    obj = load_object(grasp.object)
    draws = stats.draws
    cloud = contact_cloud(draws, max_points)
    noisy = noisy_configurations(grasp.q0, run_noise(stats), stats.seed, stats.samples,
                                 arm_draws, chunk)
    closed, did_close = closed_configuration(grasp.q0, obj)
    title = f"{grasp.object} grasp {grasp.id}: object frame"
    figures = [
        Figure("grasp", grasp_scene(obj, grasp, library, closed, friction=friction,
                                    num_edges=num_edges, cloud=cloud, title=title),
               "58%", "600px"),
        Figure("arm", arm_scene(obj, closed, library, noisy, draws.outcome[:len(noisy)],
                                "arm: world (robot base) frame"), "40%", "600px"),
        Figure("quality", quality_histogram(draws.quality[draws.outcome == FORCE_CLOSURE],
                                            stats.q_mean, stats.q_nominal), "49%", "340px"),
        Figure("outcomes", outcome_bars(stats.outcomes), "49%", "340px")]
    notes = ["The hand is drawn closed on the object from the pre-shape of q0 (the reference "
             "auto-close, as in every draw); its pre-shape can be shown from the legend."
             if did_close else "The hand starts in collision at q0 and does not close: it "
             "is drawn at its pre-shape.",
             f"The arm view shows the skeletons of the first {len(noisy)} draws (the first "
             "draws of the run, same noise), coloured by their outcome; toggle them, the arm "
             "or the object in its legend."]
    model = stats.noise_model or {}
    unseen = [s for s in ("palm", "object", "friction") if s in model]
    if unseen:
        notes.append(f"The arm view draws each draw's joint{' and hand' if 'hand' in model else ''}"
                     f" errors; its {', '.join(unseen)} errors act on the grasp but are not "
                     "drawn there (the object stays where it was believed to be). The contact "
                     "points of the grasp view, the counts and Q include every source.")
    if cloud.decimated:
        notes.append(f"The grasp view shows {cloud.shown:,} of the {cloud.total:,} contact "
                     "points of the draws (a uniform random subset, seed 0) to keep the page "
                     f"small; every count and statistic on this page uses all {len(draws):,} "
                     "draws.")
    return figures, notes


def evaluation_page(grasp: Grasp, runs: Sequence[GraspStats], *, command: str,
                    settings: dict, friction: float = 0.5, num_edges: int = 8,
                    max_points: int = MAX_POINTS, arm_draws: int = ARM_DRAWS,
                    chunk: int = DEFAULT_CHUNK) -> str:
    """The HTML page of one grasp evaluated at one or several noise levels.

    Args:
        grasp: the grasp.
        runs: one GraspStats per sigma; the first must carry its draws
            (``evaluate_grasp(..., return_draws=True)``): the 3-D views, the histogram and
            the outcome counts are of that run.
        command: the command line that reproduces the page.
        settings: name -> value, shown as a table.
    """
    detail = runs[0]
    if detail.draws is None:
        raise ValueError("the first run must keep its draws (return_draws=True)")
    library = MeshLibrary()
    figures, notes = evaluation_figures(grasp, detail, library, friction=friction,
                                        num_edges=num_edges, max_points=max_points,
                                        arm_draws=arm_draws, chunk=chunk)
    curve = ""
    if len(runs) > 1:
        figures.append(Figure("pfc", pfc_curve(runs, f"{grasp.object} grasp {grasp.id}"),
                              "60%", "380px"))
        notes.append(f"The 3-D views, the histogram and the outcome counts are for sigma = "
                     f"{sigma_text(detail.sigma)} rad (the first value given); the curve and "
                     "the table use every sigma.")
        curve = (f"<h2>P(FC) against sigma</h2><div class='kg-row'>{figures[-1].div()}"
                 f"<div>{runs_table(runs)}</div></div>")
    sources = ("" if detail.noise_model is None else
               f"<h2>Noise sources</h2>{noise_sources_table(detail.noise_model)}")
    title = f"kinegrasp report: {grasp.object} grasp {grasp.id}"
    body = (f"<h1>{esc(title)}</h1>{headline(detail)}"
            f"<div class='kg-row'>{figures[0].div()}{figures[1].div()}</div>"
            f"{''.join(note(n) for n in notes)}"
            f"<div class='kg-row'>{figures[2].div()}{figures[3].div()}</div>{curve}"
            f"{sources}<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    return page(title, body, figures, library, versions())


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
