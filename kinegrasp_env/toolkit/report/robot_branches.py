"""The HTML page of a 6-joint arm's IK-branch search (``kinegrasp elbow --robot NAME --report
FILE`` of a 6-joint arm, which has no self-motion): the headline (the chosen and the nominal
branch scored on fresh draws, the paired gain, the certificate), P(FC) per branch (selection
draws, or with ``--method reweight`` one batch re-weighted, with their 95% intervals beside
the fresh draws where a branch has them), the whole robot closed on the object
at the nominal and at the chosen branch (:func:`~kinegrasp_env.toolkit.report.robot.
grasp_scene`; the same palm pose, so the same nominal contacts; another arm), the table per
branch, the settings and the command that reproduces the page. Numbers come from
``BranchResult.to_json()``, the ones ``elbow --json`` prints.
"""

from __future__ import annotations

from dataclasses import replace

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.picture import robot_geometry
from kinegrasp_env.toolkit.elbow_search import BranchResult
from kinegrasp_env.toolkit.report.charts import fragility_chart
from kinegrasp_env.toolkit.report.html import Figure, command_block, esc, note, page, settings_table
from kinegrasp_env.toolkit.report.page import sigma_text, versions
from kinegrasp_env.toolkit.report.plotly import MeshLibrary, layout
from kinegrasp_env.toolkit.report.robot import geometry_note, grasp_scene, nominal_closings
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import load_object

#: The colours of the nominal and the chosen branch (the elbow page's).
MARKS = {"nominal": "#d62728", "chosen": "#2ca02c"}


def branch_chart(result: dict) -> dict:
    """P(FC) per IK branch (``result``: ``BranchResult.to_json()``): the selection draws'
    estimate with its 95% interval as a bar with error bars, the fresh draws' beside it, the
    nominal and the chosen branch named under their bars."""
    curve = result["curve"]
    names = []
    for point in curve:
        tags = [name for name, key in (("nominal", "nominal_branch"), ("chosen", "best_branch"))
                if result[key] == point["branch"]]
        names.append(f"{point['branch']}: {point['label']}"
                     + (f" ({', '.join(tags)})" if tags else ""))
    p = [point["p_fc"] for point in curve]
    estimate = ("re-weighted batch (95% interval)" if reweighted(result)
                else "selection draws (95% Wilson interval)")
    bars = [{"type": "bar", "name": estimate, "x": names, "y": p,
             "marker": {"color": "#1f77b4"},
             "error_y": {"type": "data", "symmetric": False,
                         "array": [c["p_fc_ci"][1] - v for c, v in zip(curve, p, strict=True)],
                         "arrayminus": [v - c["p_fc_ci"][0]
                                        for c, v in zip(curve, p, strict=True)]},
             "hovertemplate": "%{x}: P(FC) %{y:.4f}<extra>selection</extra>"},
            {"type": "bar", "name": "fresh draws", "x": names,
             "y": [point.get("fresh_p_fc") for point in curve], "marker": {"color": "#ff7f0e"},
             "hovertemplate": "%{x}: P(FC) %{y:.4f}<extra>fresh</extra>"}]
    return {"data": bars, "layout": layout(
        title={"text": "P(force closure) per IK branch", "x": 0.01, "font": {"size": 14}},
        barmode="group", yaxis={"title": {"text": "P(FC)"}, "range": [0, 1.02]},
        xaxis={"title": {"text": "IK branch (sign of det J and of the joints that tell the "
                                 "branches apart)"}},
        legend={"x": 1.0, "xanchor": "right", "y": 1.0},
        margin={"l": 60, "r": 20, "t": 40, "b": 90})}


def reweighted(result: dict) -> bool:
    """Whether the search re-weighted one batch (its certificate is the batch's)."""
    from kinegrasp_env.toolkit.elbow_certificate import METHOD

    return result["certificate"]["method"] != METHOD


def branch_headline(result: dict) -> str:
    """The chosen and the nominal branch on fresh draws, the paired gain, the certificate."""
    nlo, nhi = result["nominal_p_fc_ci"]
    lo, hi = result["best_p_fc_ci"]
    glo, ghi = result["gain_ci"]
    cert = result["certificate"]
    claim = cert["statement"]
    verdict = ("certified" if cert["certified"] else
               f"not certified at epsilon {cert['epsilon']:g}")
    return (f"<p class='kg-headline'>Nominal branch {result['nominal_branch']} "
            f"({esc(result['nominal_label'])}): P(FC) {result['nominal_p_fc']:.4f} (95% CI "
            f"{nlo:.4f} .. {nhi:.4f}); <b>chosen branch {result['best_branch']} "
            f"({esc(result['best_label'])}): P(FC) {result['best_p_fc']:.4f}</b> (95% CI "
            f"{lo:.4f} .. {hi:.4f}), both on {result['samples']} fresh draws; gain "
            f"{result['gain']:+.4f} (95% CI {glo:+.4f} .. {ghi:+.4f}, paired). "
            f"{esc(claim[:1].upper() + claim[1:])}: {esc(verdict)}; branches the IK starts "
            f"did not find not covered. Sigma = {esc(sigma_text(result['sigma']))} rad, "
            f"{esc(result['engine'])} engine.</p>")


def branch_table(result: dict) -> str:
    """Every branch: its label, arm joints, P(FC) on the selection and on the fresh draws."""
    estimate = "P(FC), re-weighted" if reweighted(result) else "P(FC), selection draws"
    head = "".join(f"<th>{h}</th>" for h in ("branch", "label", "arm joints [rad]",
                                              estimate, "95% CI", "P(FC), fresh draws", ""))
    rows = []
    for point, branch in zip(result["curve"], result["branches"], strict=True):
        tag = " / ".join(name for name, key in (("nominal", "nominal_branch"),
                                                ("chosen", "best_branch"))
                         if result[key] == point["branch"])
        joints = ", ".join(f"{v:+.3f}" for v in branch["q"])
        rows.append(f"<tr><td>{point['branch']}</td><td class='kg-text'>"
                    f"{esc(point['label'])}</td><td class='kg-text'>{joints}</td>"
                    f"<td>{point['p_fc']:.4f}</td><td>{point['p_fc_ci'][0]:.4f} .. "
                    f"{point['p_fc_ci'][1]:.4f}</td><td>{fresh_text(point)}</td>"
                    f"<td class='kg-text'>{tag}</td></tr>")
    return f"<table><tr>{head}</tr>{''.join(rows)}</table>"


def fresh_text(point: dict) -> str:
    """A curve point's fresh P(FC), or a dash where it has none (a re-weighted search scores
    only the chosen and the nominal branch on fresh draws)."""
    return f"{point['fresh_p_fc']:.4f}" if "fresh_p_fc" in point else "-"


def robot_branch_page(description: RobotDescription, grasp: Grasp, branches: BranchResult,
                      *, command: str, settings: dict, friction: float = 0.5,
                      num_edges: int = 8, fragility: dict | None = None) -> str:
    """The page of ``branches`` (``optimize_robot_branches`` of ``grasp``).

    Args:
        description: the grasp's robot (a 6-joint arm).
        grasp: the grasp (its q0 is the nominal branch).
        branches: the search.
        command: the command line that reproduces the page; settings: name -> value.
        friction, num_edges: the contacts' friction cones, as drawn.
        fragility: a re-weighted search's picture (``ReweightEvidence.picture()``): drawn
            as a chart of why the chosen branch fails less
            (:func:`~kinegrasp_env.toolkit.report.charts.fragility_chart`).
    """
    result = branches.to_json()
    obj = load_object(grasp.object)
    points = branches.result.curve
    arms = [(label, index, replace(grasp, q0=points[index].q.copy())) for label, index in
            (("nominal", branches.nominal), ("chosen", branches.best))]
    closings = nominal_closings(description, obj, [g for _, _, g in arms])
    frames = []
    for (_, _, g), (values, _) in zip(arms, closings, strict=True):
        frames += [values, {k: float(v) for k, v in description.model.expand(g.q0).items()}]
    geometry = robot_geometry(description, frames)
    library, views = MeshLibrary(), []
    for k, ((label, index, g), (_, did_close)) in enumerate(zip(arms, closings, strict=True)):
        title = (f"{label} branch {index} ({branches.branches[index].label}): world (robot "
                 "base) frame")
        views.append(Figure(f"arm-{label}", grasp_scene(
            description, obj, g, geometry, 2 * k, 2 * k + 1, library, did_close=did_close,
            friction=friction, num_edges=num_edges, title=title, whole_first=True), "49%",
            "520px"))
    chart = Figure("branches", branch_chart(result), "99%", "380px")
    why = (None if fragility is None else
           Figure("fragility", fragility_chart(fragility, "branch"), "99%", "520px"))
    chosen_on = ("one batch of closings re-weighted to each branch (the blue bars, with "
                 "their 95% intervals; the chosen and the nominal branch again on fresh "
                 "draws, orange); the branch is chosen on the batch"
                 if reweighted(result) else
                 "the same selection draws (the blue bars, with their 95% intervals) and "
                 "again on fresh draws (orange); the branch is chosen on the selection draws")
    notes = [f"The chart: P(FC) of each IK branch on {chosen_on}, and the headline scores it "
             "and the nominal branch on the fresh ones.",
             "Each view shows the whole robot closed on the object at its branch (toggle its "
             "pre-shape in the legend, or the close-up of the hand): the palm pose and the "
             "nominal contacts are the same, the arm is not.", geometry_note(geometry)]
    if why is not None:
        notes.append("Why this branch: the batch's palm deviations in the two directions in "
                     "which force closure is lost soonest (failures red), with the nominal "
                     "and the chosen branch's error ellipses: the branch whose ellipse is "
                     "shorter along a fragile direction fails less.")
    if branches.best == branches.nominal:
        notes.append("The chosen branch is the nominal one: both views show the same arm.")
    title = (f"kinegrasp elbow report: robot {description.name}, {grasp.object} grasp "
             f"{grasp.id}, IK branches")
    body = (f"<h1>{esc(title)}</h1>{branch_headline(result)}"
            f"<div class='kg-row'>{chart.div()}</div>"
            + ("" if why is None else f"<div class='kg-row'>{why.div()}</div>") +
            f"<div class='kg-row'>{views[0].div()}{views[1].div()}</div>"
            f"{''.join(note(n) for n in notes)}"
            f"<h2>P(FC) of every IK branch</h2>{branch_table(result)}"
            f"<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    figures = [chart, *([] if why is None else [why]), *views]
    return page(title, body, figures, library, versions())
