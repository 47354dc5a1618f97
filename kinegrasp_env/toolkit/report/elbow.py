"""The HTML page of an elbow optimization (``kinegrasp elbow --report FILE``).

It holds P(FC) along the grasp's self-motion with Wilson intervals (the nominal and the best
elbow angle marked), the arm at the nominal and at the best elbow in 3-D (each with the
skeletons of its first noisy selection draws coloured by outcome, and the other elbow's
skeleton for comparison: same palm pose, another arm), the headline numbers (the best and
the nominal elbow scored on fresh draws, the paired gain, the certificate: how much better
than the chosen elbow any evaluated one can be), a table of the curve, the settings and the
command that reproduces the page. The page machinery (shell, figures, shared meshes) is the
evaluation page's (:mod:`~kinegrasp_env.toolkit.report.page`).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.evaluate import DEFAULT_CHUNK, Noise
from kinegrasp_env.toolkit.elbow import ElbowPoint, ElbowResult
from kinegrasp_env.toolkit.report.charts import elbow_curve, fragility_chart
from kinegrasp_env.toolkit.report.geometry import (
    closed_configuration,
    noisy_configurations,
    skeletons,
)
from kinegrasp_env.toolkit.report.html import Figure, command_block, esc, note, page, settings_table
from kinegrasp_env.toolkit.report.page import ARM_DRAWS, sigma_text, versions
from kinegrasp_env.toolkit.report.plotly import MeshLibrary
from kinegrasp_env.toolkit.report.scene import arm_scene, skeleton_trace
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import GraspObject, load_object

#: The other elbow's skeleton in an arm view.
OTHER_COLOUR = "#505050"


def curve_point(result: ElbowResult, psi: float) -> ElbowPoint:
    """The curve's point at elbow angle ``psi`` (the nominal and the best one are on it)."""
    return min(result.curve, key=lambda p: abs(p.psi - psi))


def elbow_arm_figure(obj: GraspObject, point: ElbowPoint, other: np.ndarray, label: str,
                     other_label: str, library: MeshLibrary, noise: Noise, seed: int,
                     samples: int, arm_draws: int, chunk: int) -> tuple[dict, int]:
    """The arm at ``point``'s configuration, closed on the object, with the skeletons of its
    first ``arm_draws`` selection draws by outcome and the skeleton of the configuration
    ``other`` (14,) dashed; returns the figure and the number of noisy draws drawn."""
    closed, _ = closed_configuration(point.q, obj)
    noisy = noisy_configurations(point.q, noise, seed, samples, arm_draws, chunk)
    outcomes = None if point.outcome is None else point.outcome[:len(noisy)]
    if outcomes is None:
        noisy = noisy[:0]
    figure = arm_scene(obj, closed, library, noisy, outcomes,
                       f"{label} elbow, psi = {point.psi:+.3f} rad: world frame",
                       label=f"{label} elbow, no noise")
    figure["data"].append(skeleton_trace(
        skeletons(other), f"skeleton at the {other_label} elbow", OTHER_COLOUR, 5,
        line={"color": OTHER_COLOUR, "width": 5, "dash": "dash"}))
    return figure, len(noisy)


def headline(result: ElbowResult) -> str:
    nlo, nhi = result.nominal_p_fc_ci
    lo, hi = result.best_p_fc_ci
    glo, ghi = result.gain_ci
    cert = result.certificate
    claim = cert.statement()
    return (f"<p class='kg-headline'>Nominal elbow {result.nominal_psi:+.3f} rad: P(FC) "
            f"{result.nominal_p_fc:.4f} (95% CI {nlo:.4f} .. {nhi:.4f}); <b>best elbow "
            f"{result.best_psi:+.3f} rad: P(FC) {result.best_p_fc:.4f}</b> (95% CI "
            f"{lo:.4f} .. {hi:.4f}), both on {result.samples} fresh draws; gain "
            f"{result.gain:+.4f} (95% CI {glo:+.4f} .. {ghi:+.4f}, paired). "
            f"{esc(claim[:1].upper() + claim[1:])}: {esc(cert.verdict())}; angles between "
            f"the {result.grid_step:.3f} rad grid points not covered. Sigma = "
            f"{esc(sigma_text(result.sigma))} rad, {esc(result.engine)} engine.</p>")


def curve_table(result: ElbowResult) -> str:
    """The curve's points, psi ascending, on the selection and on the fresh draws, the nominal
    and the best one named."""
    head = "".join(f"<th>{h}</th>" for h in ("psi [rad]", "P(FC), selection draws", "95% CI",
                                              "P(FC), fresh draws", ""))
    rows = []
    for p in sorted(result.curve, key=lambda p: p.psi):
        tag = " / ".join(name for name, psi in (("nominal", result.nominal_psi),
                                                 ("best", result.best_psi)) if p.psi == psi)
        fresh = "" if p.fresh_fc is None else f"{p.fresh_fc.mean():.4f}"
        rows.append(f"<tr><td>{p.psi:+.3f}</td><td>{p.p_fc:.4f}</td><td>{p.p_fc_ci[0]:.4f} .. "
                    f"{p.p_fc_ci[1]:.4f}</td><td>{fresh}</td><td class='kg-text'>{tag}</td></tr>")
    return f"<table><tr>{head}</tr>{''.join(rows)}</table>"


def elbow_page(grasp: Grasp, result: ElbowResult, noise: Noise, *, command: str,
               settings: dict, arm_draws: int = ARM_DRAWS,
               chunk: int = DEFAULT_CHUNK, fragility: dict | None = None) -> str:
    """The HTML page of ``result`` (``optimize_elbow(grasp, noise, ...)``; its curve points
    keep their outcomes, as ``optimize_elbow`` gives them).

    Args:
        grasp: the grasp (its q0 is the nominal elbow).
        result: the optimization.
        noise: the noise it ran with (the arm views redraw its first draws).
        command: the command line that reproduces the page.
        settings: name -> value, shown as a table.
        arm_draws: noisy draws whose skeletons each arm view shows.
        chunk: the draws per chunk the optimization used.
        fragility: for a curve from one re-weighted batch, its picture
            (``ReweightEvidence.picture()``): drawn as the page's third chart.
    """
    obj = load_object(grasp.object)
    library = MeshLibrary()
    nominal, best = curve_point(result, result.nominal_psi), curve_point(result, result.best_psi)
    views = []
    for key, point, other, label, other_label in (("arm-nominal", nominal, best.q, "nominal",
                                                   "best"),
                                                  ("arm-best", best, nominal.q, "best",
                                                   "nominal")):
        figure, shown = elbow_arm_figure(obj, point, other, label, other_label, library, noise,
                                         result.seed, result.samples, arm_draws, chunk)
        views.append(Figure(key, figure, "49%", "520px"))
    curve = Figure("elbow", elbow_curve(
        [p.to_json() for p in result.curve], result.nominal_psi, result.best_psi,
        "selection draws, 95% Wilson intervals" if fragility is None else
        "one re-weighted batch, 95% intervals"), "99%", "340px")
    curve_note = (f"The curve: P(FC) of each evaluated elbow angle on the same "
                  f"{result.samples} selection draws (common random numbers), with 95% Wilson "
                  "intervals; the headline scores the chosen and the nominal elbow again on "
                  "draws the selection never used." if fragility is None else
                  "The curve: P(FC) of each elbow angle from one batch of closings over the "
                  "palm's deviation, re-weighted to that angle (95% normal intervals of the "
                  "weights' standard error); the headline scores the chosen and the nominal "
                  "elbow on fresh direct draws. The third chart says why: the batch's palm "
                  "deviations in the two directions in which force closure is lost soonest, "
                  "and each elbow's error ellipse there.")
    skeletons = (f", the skeletons of its first {shown} selection draws coloured by their "
                 "outcome," if shown else "")
    notes = [curve_note,
             f"Each arm view shows the arm and the closed hand at its elbow{skeletons} and the "
             "other elbow's skeleton dashed: the palm pose and the contacts are the same, the "
             "arm is not. Toggle any of them in the legend."]
    if nominal is best:
        notes.append("The best elbow is the nominal one: both views show the same arm.")
    title = f"kinegrasp elbow report: {grasp.object} grasp {grasp.id}"
    return elbow_layout(title, result, curve, views, notes, library, command=command,
                        settings=settings, fragility=fragility)


def elbow_layout(title: str, result: ElbowResult, curve: Figure, views: list[Figure],
                 notes: list[str], library: MeshLibrary, *, command: str, settings: dict,
                 fragility: dict | None = None) -> str:
    """An elbow page from its parts: the headline, the curve, the fragile directions (where a
    re-weighted batch gives them), the two arm views side by side, the notes, the curve's
    table, the settings and the command."""
    extra = []
    if fragility is not None:
        extra = [Figure("fragility", fragility_chart(fragility), "99%", "520px")]
    body = (f"<h1>{esc(title)}</h1>{headline(result)}"
            f"<div class='kg-row'>{curve.div()}</div>"
            + "".join(f"<div class='kg-row'>{f.div()}</div>" for f in extra) +
            f"<div class='kg-row'>{views[0].div()}{views[1].div()}</div>"
            f"{''.join(note(n) for n in notes)}"
            f"<h2>P(FC) of every evaluated elbow angle</h2>{curve_table(result)}"
            f"<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    return page(title, body, [curve, *extra, *views], library, versions())
