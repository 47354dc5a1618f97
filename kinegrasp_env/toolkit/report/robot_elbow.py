"""The HTML page of a description robot's elbow optimization (``kinegrasp elbow --robot NAME
--report FILE``, a 7-joint arm's self-motion): the default robot's elbow page
(:mod:`~kinegrasp_env.toolkit.report.elbow`: the headline, P(FC) along the self-motion with
the nominal and the best elbow marked, the re-weighted batch's fragile directions where it
ran, the curve's table) with the robot's own scenes: the whole robot closed on the object at
the nominal and at the best elbow (:func:`~kinegrasp_env.toolkit.report.robot.grasp_scene`;
the same palm pose, so the same nominal contacts; another arm).
"""

from __future__ import annotations

from dataclasses import replace

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.picture import robot_geometry
from kinegrasp_env.toolkit.elbow import ElbowResult
from kinegrasp_env.toolkit.report.charts import elbow_curve
from kinegrasp_env.toolkit.report.elbow import curve_point, elbow_layout
from kinegrasp_env.toolkit.report.html import Figure
from kinegrasp_env.toolkit.report.plotly import MeshLibrary
from kinegrasp_env.toolkit.report.robot import geometry_note, grasp_scene, nominal_closings
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import load_object


def robot_elbow_page(description: RobotDescription, grasp: Grasp, result: ElbowResult, *,
                     command: str, settings: dict, friction: float = 0.5, num_edges: int = 8,
                     fragility: dict | None = None) -> str:
    """The page of ``result`` (``optimize_robot_elbow`` of ``grasp``, or the re-weighted
    search's; ``fragility``: then its batch's picture, ``ReweightEvidence.picture()``).

    Args:
        description: the grasp's robot.
        grasp: the grasp (its q0 is the nominal elbow).
        result: the optimization.
        command: the command line that reproduces the page; settings: name -> value.
        friction, num_edges: the contacts' friction cones, as drawn.
    """
    obj = load_object(grasp.object)
    nominal, best = curve_point(result, result.nominal_psi), curve_point(result, result.best_psi)
    elbows = [(label, replace(grasp, q0=point.q.copy())) for label, point in
              (("nominal", nominal), ("best", best))]
    closings = nominal_closings(description, obj, [g for _, g in elbows])
    frames = []
    for (_, g), (values, _) in zip(elbows, closings, strict=True):
        frames += [values, {k: float(v) for k, v in description.model.expand(g.q0).items()}]
    geometry = robot_geometry(description, frames)
    library, views = MeshLibrary(), []
    for k, ((label, g), (_, did_close)) in enumerate(zip(elbows, closings, strict=True)):
        point = nominal if label == "nominal" else best
        title = f"{label} elbow, psi = {point.psi:+.3f} rad: world (robot base) frame"
        views.append(Figure(f"arm-{label}", grasp_scene(
            description, obj, g, geometry, 2 * k, 2 * k + 1, library, did_close=did_close,
            friction=friction, num_edges=num_edges, title=title, whole_first=True), "49%",
            "520px"))
    curve = Figure("elbow", elbow_curve(
        [p.to_json() for p in result.curve], result.nominal_psi, result.best_psi,
        "selection draws, 95% Wilson intervals" if fragility is None else
        "one re-weighted batch, 95% intervals"), "99%", "340px")
    notes = ["The curve: P(FC) of each evaluated elbow angle (on the same selection draws, or "
             "from one re-weighted batch); the headline scores the chosen and the nominal "
             "elbow again on fresh draws.",
             "Each view shows the whole robot closed on the object at its elbow (toggle its "
             "pre-shape in the legend, or the close-up of the hand): the palm pose and the "
             "nominal contacts are the same, the arm is not.", geometry_note(geometry)]
    if nominal is best:
        notes.append("The best elbow is the nominal one: both views show the same arm.")
    title = f"kinegrasp elbow report: robot {description.name}, {grasp.object} grasp {grasp.id}"
    return elbow_layout(title, result, curve, views, notes, library, command=command,
                        settings=settings, fragility=fragility)
