"""The HTML page of an elbow optimization (``kinegrasp elbow --report FILE``) of any robot.

It holds P(FC) along the grasp's self-motion with Wilson intervals (the nominal and the best
elbow angle marked), the whole robot closed on the object at the nominal and at the best
elbow in 3-D (the same palm pose, so the same nominal contacts; another arm), each with the
skeletons of its first noisy selection draws coloured by their outcome (hidden until
toggled), the re-weighted batch's fragile directions where it ran, the headline numbers (the
best and the nominal elbow scored on fresh draws, the paired gain, the certificate: how much
better than the chosen elbow any evaluated one can be), a table of the curve, the settings
and the command that reproduces the page. The page machinery (shell, figures, shared meshes)
is the evaluation page's (:mod:`~kinegrasp_env.toolkit.report.page`); the scenes are the
robot pages' (:func:`~kinegrasp_env.toolkit.report.robot.grasp_scene`).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.picture import robot_geometry
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.elbow import ElbowPoint, ElbowResult
from kinegrasp_env.toolkit.report.arms import NoisyArms
from kinegrasp_env.toolkit.report.charts import elbow_curve, fragility_chart
from kinegrasp_env.toolkit.report.html import Figure, command_block, esc, note, page, settings_table
from kinegrasp_env.toolkit.report.page import ARM_DRAWS, sigma_text, versions
from kinegrasp_env.toolkit.report.plotly import MeshLibrary
from kinegrasp_env.toolkit.report.robot import (
    geometry_note,
    grasp_scene,
    nominal_closings,
)
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import load_object


def curve_point(result: ElbowResult, psi: float) -> ElbowPoint:
    """The curve's point at elbow angle ``psi`` (the nominal and the best one are on it)."""
    return min(result.curve, key=lambda p: abs(p.psi - psi))


def noisy_arms(description: RobotDescription, point: ElbowPoint, noise: JointNoise, seed: int,
               arm_draws: int) -> NoisyArms:
    """The first ``arm_draws`` selection draws of ``point`` (rows 0 .. of run ``seed``'s
    joint noise, :func:`~kinegrasp_env.montecarlo.chunks.chunk_configurations`, the
    rows the optimization closed there) with the outcomes it recorded; none where it kept
    no outcomes (a re-weighted angle)."""
    shown = 0 if point.outcome is None else min(int(arm_draws), len(point.outcome))
    q = chunk_configurations(point.q, description.arm_dof, noise.sigma, noise.kind, seed, 0,
                             shown)
    return NoisyArms(q, np.zeros(0, dtype=np.int8) if point.outcome is None
                     else point.outcome[:shown])


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


def curve_table(result: ElbowResult, source: str = "selection draws") -> str:
    """The curve's points, psi ascending, on ``source`` (the selection draws, or one
    re-weighted batch) and on the fresh draws, the nominal and the best one named."""
    head = "".join(f"<th>{h}</th>" for h in ("psi [rad]", f"P(FC), {source}", "95% CI",
                                              "P(FC), fresh draws", ""))
    rows = []
    for p in sorted(result.curve, key=lambda p: p.psi):
        tag = " / ".join(name for name, psi in (("nominal", result.nominal_psi),
                                                 ("best", result.best_psi)) if p.psi == psi)
        fresh = "" if p.fresh_fc is None else f"{p.fresh_fc.mean():.4f}"
        rows.append(f"<tr><td>{p.psi:+.3f}</td><td>{p.p_fc:.4f}</td><td>{p.p_fc_ci[0]:.4f} .. "
                    f"{p.p_fc_ci[1]:.4f}</td><td>{fresh}</td><td class='kg-text'>{tag}</td></tr>")
    return f"<table><tr>{head}</tr>{''.join(rows)}</table>"


def elbow_page(description: RobotDescription, grasp: Grasp, result: ElbowResult,
               noise: JointNoise, *, command: str, settings: dict, friction: float = 0.5,
               num_edges: int = 8, arm_draws: int = ARM_DRAWS,
               fragility: dict | None = None, reweighted: bool = False) -> str:
    """The HTML page of ``result`` (``optimize_robot_elbow`` of ``grasp``, whose curve points
    keep their outcomes, or the re-weighted search's).

    Args:
        description: the grasp's robot.
        grasp: the grasp (its q0 is the nominal elbow).
        result: the optimization.
        noise: the joint noise it ran with (the arm views redraw its first draws).
        command: the command line that reproduces the page; settings: name -> value.
        friction, num_edges: the contacts' friction cones, as drawn.
        arm_draws: noisy selection draws whose skeletons each arm view shows.
        fragility: for a curve from one re-weighted batch, its picture
            (``ReweightEvidence.picture()``, None where no closing of the batch failed):
            drawn as the page's third chart.
        reweighted: the curve comes from one re-weighted batch (labelled so).
    """
    obj = load_object(grasp.object)
    nominal, best = curve_point(result, result.nominal_psi), curve_point(result, result.best_psi)
    elbows = [(label, point, replace(grasp, q0=point.q.copy()))
              for label, point in (("nominal", nominal), ("best", best))]
    closings = nominal_closings(description, obj, [g for _, _, g in elbows])
    frames = []
    for (_, _, g), (values, _) in zip(elbows, closings, strict=True):
        frames += [values, {k: float(v) for k, v in description.model.expand(g.q0).items()}]
    geometry = robot_geometry(description, frames)
    library, views, shown = MeshLibrary(), [], {}
    for k, ((label, point, g), (_, did_close)) in enumerate(zip(elbows, closings, strict=True)):
        arms = noisy_arms(description, point, noise, result.seed, arm_draws)
        shown[label] = len(arms.q)
        title = f"{label} elbow, psi = {point.psi:+.3f} rad: world (robot base) frame"
        views.append(Figure(f"arm-{label}", grasp_scene(
            description, obj, g, geometry, 2 * k, 2 * k + 1, library, did_close=did_close,
            friction=friction, num_edges=num_edges, title=title, whole_first=True,
            arms=arms), "49%", "520px"))
    curve = Figure("elbow", elbow_curve(
        [p.to_json() for p in result.curve], result.nominal_psi, result.best_psi,
        "one re-weighted batch, 95% intervals" if reweighted else
        "selection draws, 95% Wilson intervals"), "99%", "340px")
    curve_note = (f"The curve: P(FC) of each evaluated elbow angle on the same "
                  f"{result.samples} selection draws (common random numbers), with 95% Wilson "
                  "intervals; the headline scores the chosen and the nominal elbow again on "
                  "draws the selection never used." if not reweighted else
                  "The curve: P(FC) of each elbow angle from one batch of closings over the "
                  "palm's deviation, re-weighted to that angle (95% Wilson intervals at each "
                  "angle's effective number of draws); the headline scores the chosen and the "
                  "nominal elbow on fresh direct draws. " + (
                      "The third chart says why: the batch's palm deviations in the two "
                      "directions in which force closure is lost soonest, and each elbow's "
                      "error ellipse there." if fragility is not None else
                      "No closing of the batch failed: there is no fragile direction to "
                      "draw."))
    drawn = ""
    if len(set(shown.values())) == 1 and shown["nominal"]:
        drawn = (f" and, toggled in the legend, the arm's skeleton at its first "
                 f"{shown['nominal']} selection draws coloured by their outcome")
    elif any(shown.values()):
        drawn = (" and, toggled in the legend, the arm's skeleton at the direct draws the "
                 f"search closed there (nominal {shown['nominal']}, best {shown['best']}: a "
                 "re-weighted angle has them only where its batch fell short) coloured by "
                 "their outcome")
    notes = [curve_note,
             f"Each view shows the whole robot closed on the object at its elbow{drawn} "
             "(toggle its pre-shape in the legend, or the close-up of the hand): the palm pose "
             "and the nominal contacts are the same, the arm is not.",
             geometry_note(geometry)]
    if nominal is best:
        notes.append("The best elbow is the nominal one: both views show the same arm.")
    title = f"kinegrasp elbow report: robot {description.name}, {grasp.object} grasp {grasp.id}"
    return elbow_layout(title, result, curve, views, notes, library, command=command,
                        settings=settings, fragility=fragility, reweighted=reweighted)


def elbow_layout(title: str, result: ElbowResult, curve: Figure, views: list[Figure],
                 notes: list[str], library: MeshLibrary, *, command: str, settings: dict,
                 fragility: dict | None = None, reweighted: bool = False) -> str:
    """An elbow page from its parts: the headline, the curve, the fragile directions (where a
    re-weighted batch gives them), the two arm views side by side, the notes, the curve's
    table, the settings and the command."""
    extra, source = [], "one re-weighted batch" if reweighted else "selection draws"
    if fragility is not None:
        extra = [Figure("fragility", fragility_chart(fragility), "99%", "520px")]
    body = (f"<h1>{esc(title)}</h1>{headline(result)}"
            f"<div class='kg-row'>{curve.div()}</div>"
            + "".join(f"<div class='kg-row'>{f.div()}</div>" for f in extra) +
            f"<div class='kg-row'>{views[0].div()}{views[1].div()}</div>"
            f"{''.join(note(n) for n in notes)}"
            f"<h2>P(FC) of every evaluated elbow angle</h2>{curve_table(result, source)}"
            f"<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    return page(title, body, [curve, *extra, *views], library, versions())
