"""The report page of any robot's grasps (``kinegrasp report``, ``evaluate --report``, a
ranking of a description robot's candidates).

One page per grasp set: the table of P(FC) (with its Wilson 95% interval) and Q's moments
over the force-closure draws for each grasp and sigma, and one rotatable 3-D scene per grasp
in the world (robot base) frame: the object at its pose, the whole robot at the grasp's
nominal closing (the reference closing from q0, :meth:`~kinegrasp_env.closing.
generic_reference.RobotWorld.auto_close`), hidden until toggled at its pre-shape q0, and the
nominal contacts with their friction cones; the contact points of the grasp's first run
(at most ``max_points``, coloured by outcome or by finger) and the skeletons of the arm at
its first ``arm_draws`` noisy configurations (the run's first draws: joint noise alone),
coloured by outcome; under the scene, where the grasp's first run kept its draws, Q's
histogram over its force-closure draws and its outcome counts, and where the grasp was run
at several sigmas, P(FC) against sigma; under a noise model, its sources and their
settings. The robot is drawn as
:func:`~kinegrasp_env.robot.picture.robot_geometry` reads it (the picture of ``kinegrasp
robots show``: pybullet's reading of the URDF; links with mesh visuals are drawn from their
collision geometry, and the page says which). Metres throughout; pages are deterministic.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.picture import RobotGeometry, robot_geometry
from kinegrasp_env.toolkit.report.arms import NoisyArms, noisy_traces
from kinegrasp_env.toolkit.report.charts import outcome_bars, pfc_curve, quality_histogram
from kinegrasp_env.toolkit.report.geometry import cone_meshes, transform
from kinegrasp_env.toolkit.report.html import (
    Figure,
    command_block,
    esc,
    note,
    page,
    settings_table,
)
from kinegrasp_env.toolkit.report.page import fmt, noise_sources_table, versions
from kinegrasp_env.toolkit.report.plotly import (
    BASE_LAYOUT,
    MeshLibrary,
    instanced_mesh,
    layout,
)
from kinegrasp_env.toolkit.report.scene import (
    CLOSE_UP_EYE,
    CONE_SCALE,
    LEGEND,
    LEGEND_MARGIN,
    MAX_POINTS,
    WHOLE_EYE,
    ContactCloud,
    close_up,
    cloud_traces,
    colour_buttons,
    contact_cloud,
    mesh_trace,
    object_traces,
    scene_axes,
)
from kinegrasp_env.wording import plural
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import GraspObject

#: Outcome counts shown in the table, in this order.
OUTCOME_COLUMNS = OUTCOMES
#: Height of the colour buttons (below the view buttons), as a fraction of the figure.
COLOUR_MENU_Y = 0.93


@dataclass(frozen=True)
class RobotRun:
    """One grasp evaluated at one sigma.

    Attributes:
        grasp: index of the grasp in the page's list.
        sigma: joint noise standard deviation, radians (scalar or one per arm joint).
        evaluation: :class:`~kinegrasp_env.montecarlo.evaluate.GraspEvaluation`.
    """

    grasp: int
    sigma: float | tuple[float, ...]
    evaluation: object


def nominal_closings(description: RobotDescription, obj: GraspObject,
                     grasps: Sequence[Grasp]) -> list[tuple[dict[str, float], bool]]:
    """Per grasp: (every movable joint's value at its nominal closing, True), or (its values
    at q0, False) when the hand starts in collision at q0 and does not close."""
    from kinegrasp_env.closing.generic_reference import RobotWorld

    world = RobotWorld(description, obj)
    out = []
    try:
        for grasp in grasps:
            values = {k: float(v) for k, v in description.model.expand(grasp.q0).items()}
            result = world.auto_close(np.asarray(grasp.q0, dtype=float))
            out.append(({**values, **result.joints}, True) if not result.start_collision
                       else (values, False))
    finally:
        world.close()
    return out


def robot_traces(geometry: RobotGeometry, index: int, name: str, library: MeshLibrary, *,
                 robot: str, opacity: float = 1.0, **extra) -> list[dict]:
    """The robot's pieces placed at ``geometry.frames[index]``: one Mesh3d per colour, one
    legend entry (the pieces are stored once in ``library``)."""
    by_colour: dict[str, list] = {}
    for k, shape in enumerate(geometry.shapes):
        key = library.add(f"robot:{robot}:{k}", shape.vertices, shape.faces)
        by_colour.setdefault(shape.color, []).append((key, geometry.frames[index][shape.link]))
    return [instanced_mesh(pieces, name, colour, opacity=opacity, legendgroup=name,
                           showlegend=i == 0, **extra)
            for i, (colour, pieces) in enumerate(by_colour.items())]


def contact_traces(grasp: Grasp, obj: GraspObject, description: RobotDescription,
                   friction: float, num_edges: int) -> list[dict]:
    """The nominal contacts (world frame markers, named by their finger's tip link) and
    their friction cones (one mesh, drawn outside the object)."""
    if len(grasp.points) == 0:
        return []
    points = transform(grasp.points, obj.pose)
    normals = np.asarray(grasp.normals) @ obj.pose[:3, :3].T
    height = CONE_SCALE * float(np.max(obj.size))
    vertices, faces = cone_meshes(points, normals, friction, num_edges, height)
    tips = description.fingertip_links
    labels = [f"finger {f + 1} ({tips[f] if f < len(tips) else '?'})" for f in grasp.fingers]
    return [mesh_trace(vertices, faces, f"friction cones (mu {friction:g}, {num_edges} edges, "
                       "drawn outside)", "#9467bd", opacity=0.6, showlegend=True),
            {"type": "scatter3d", "mode": "markers", "name": "nominal contacts",
             "x": points[:, 0].tolist(), "y": points[:, 1].tolist(),
             "z": points[:, 2].tolist(), "text": labels, "hoverinfo": "text+name",
             "marker": {"size": 6, "color": "black", "symbol": "diamond"}}]


def world_cloud(cloud: ContactCloud, obj: GraspObject) -> ContactCloud:
    """``cloud`` (object frame) in the world frame of the object at its pose."""
    return dataclasses.replace(cloud, points=transform(cloud.points, obj.pose))


def view_buttons(obj: GraspObject, whole_first: bool = False) -> dict:
    """Buttons switching a scene between a close-up of the object and the whole robot (the
    active one: the whole robot with ``whole_first``)."""
    low, high = (transform(c, obj.pose) for c in close_up(obj))
    low, high = np.minimum(low, high), np.maximum(low, high)
    extent = high - low
    near = {f"scene.{a}axis.range": [float(low[k]), float(high[k])]
            for k, a in enumerate("xyz")}
    near.update({"scene.aspectmode": "manual", "scene.aspectratio": dict(zip(
        "xyz", (extent / extent.max()).tolist(), strict=True)),
        "scene.camera.eye": dict(CLOSE_UP_EYE)})
    whole = {f"scene.{a}axis.autorange": True for a in "xyz"}
    whole.update({"scene.aspectmode": "data", "scene.camera.eye": dict(WHOLE_EYE)})
    return {"type": "buttons", "direction": "right", "x": 0.0, "y": 1.0, "xanchor": "left",
            "yanchor": "top", "showactive": True, "active": int(whole_first),
            "buttons": [{"label": "close-up", "method": "relayout", "args": [near]},
                        {"label": "whole robot", "method": "relayout", "args": [whole]}]}


def grasp_scene(description: RobotDescription, obj: GraspObject, grasp: Grasp,
                geometry: RobotGeometry, closed: int, shaped: int, library: MeshLibrary, *,
                did_close: bool, friction: float, num_edges: int, title: str,
                whole_first: bool = False, cloud: ContactCloud | None = None,
                arms: NoisyArms | None = None) -> dict:
    """One grasp's scene in the world frame: the object, the robot at
    ``geometry.frames[closed]`` (its nominal closing) and, hidden until toggled, at
    ``geometry.frames[shaped]`` (its pre-shape q0), the nominal contacts and cones, the
    draws' contact points ``cloud`` (world frame; buttons colour them by outcome or by
    finger) and the skeletons of ``arms``. Opens on the close-up of the object (a button
    shows the whole robot), or with ``whole_first`` on the whole robot (a button shows the
    close-up)."""
    label = "robot (closed, nominal)" if did_close else "robot (q0: starts in collision)"
    data = object_traces(obj, library, obj.pose, parts=False)
    data[0]["showlegend"] = True  # a mesh trace has no legend entry unless asked
    data += robot_traces(geometry, closed, label, library, robot=description.name,
                         opacity=0.55)
    data += robot_traces(geometry, shaped, "robot (pre-shape q0)", library,
                         robot=description.name, opacity=0.3, visible="legendonly")
    data += contact_traces(grasp, obj, description, friction, num_edges)
    menus = [view_buttons(obj, whole_first)]
    if cloud is not None and cloud.shown:
        by_outcome, by_finger = cloud_traces(cloud)
        menus.append({**colour_buttons(len(data), len(by_outcome), len(by_finger)),
                      "y": COLOUR_MENU_Y})
        data += by_outcome + by_finger
    if arms is not None and len(arms.q):
        data += noisy_traces(description, arms)
    box = tuple(transform(c, obj.pose) for c in close_up(obj))
    scene = scene_axes(None if whole_first else (np.minimum(*box), np.maximum(*box)))
    return {"data": data, "layout": layout(
        scene=scene, updatemenus=menus, legend=LEGEND,
        margin={**BASE_LAYOUT["margin"], "b": LEGEND_MARGIN},
        uirevision="grasp",
        title={"text": title, "x": 0.01, "font": {"size": 14}})}


def sigma_words(sigma) -> str:
    return f"{sigma:g}" if isinstance(sigma, float) else ",".join(f"{s:g}" for s in sigma)


def results_table(grasps: Sequence[Grasp], runs: Sequence[RobotRun],
                  spec: bool = False) -> str:
    """The table of every run: its sigma (``spec``: the runs drew a noise model, named in
    the column instead), P(FC) (``class="kg-pfc"``, its full value in ``data-value``), its
    interval, Q nominal, Q's moments over the force-closure draws, the outcomes."""
    head = ("grasp", "noise" if spec else "sigma [rad]", "P(FC)", "95% CI", "Q nominal",
            "Q mean", "Q std", "Q skewness", *(c.replace("_", " ") for c in OUTCOME_COLUMNS),
            "draws")
    rows = []
    for run in runs:
        e, grasp = run.evaluation, grasps[run.grasp]
        cells = [f'<td class="kg-text">{esc(grasp.id)}</td>',
                 f"<td>{'noise spec' if spec else esc(sigma_words(run.sigma))}</td>",
                 f'<td class="kg-pfc" data-grasp="{esc(grasp.id)}" '
                 f'data-value="{e.p_fc!r}">{e.p_fc:.4f}</td>',
                 f"<td>{e.ci[0]:.4f} .. {e.ci[1]:.4f}</td>", f"<td>{fmt(grasp.q_nominal)}</td>",
                 f"<td>{fmt(e.q_mean)}</td>", f"<td>{fmt(e.q_std)}</td>",
                 f"<td>{fmt(e.q_skew, 3)}</td>",
                 *(f"<td>{e.counts.get(c, 0)}</td>" for c in OUTCOME_COLUMNS), f"<td>{e.n}</td>"]
        rows.append(f"<tr>{''.join(cells)}</tr>")
    header = "".join(f"<th>{esc(h)}</th>" for h in head)
    return f"<table><tr>{header}</tr>{''.join(rows)}</table>"


def geometry_note(geometry: RobotGeometry) -> str:
    """Which links are drawn from which geometry."""
    visual, collision = geometry.links_from("visual"), geometry.links_from("collision")
    parts = []
    if visual:
        parts.append(f"from their visual geometry (primitives): {', '.join(visual)}")
    if collision:
        parts.append("from their collision geometry (their visuals are meshes, whose "
                     "triangles pybullet does not give; meshes drawn as the convex hulls "
                     f"pybullet collides with): {', '.join(collision)}")
    return "Links drawn " + "; ".join(parts) + "." if parts else "The robot has no geometry."


def objects_closings(description: RobotDescription, objects: Sequence[GraspObject],
                     grasps: Sequence[Grasp]) -> list[tuple[dict[str, float], bool]]:
    """:func:`nominal_closings` of grasps on objects of their own (``objects[k]`` grasp
    k's), one world per object, in the grasps' order."""
    out: list = [None] * len(grasps)
    for name in dict.fromkeys(o.name for o in objects):
        rows = [k for k, o in enumerate(objects) if o.name == name]
        found = nominal_closings(description, objects[rows[0]], [grasps[k] for k in rows])
        for k, closing in zip(rows, found, strict=True):
            out[k] = closing
    return out


def grasps_geometry(description: RobotDescription, objects: Sequence[GraspObject],
                    grasps: Sequence[Grasp]) -> tuple[list, RobotGeometry]:
    """(:func:`objects_closings` of the grasps on their objects, the robot's geometry with
    grasp k's nominal closing as frames ``2k`` and its pre-shape q0 as ``2k + 1``): what
    a page's scenes draw."""
    closings = objects_closings(description, objects, grasps)
    configurations = []
    for grasp, (values, _) in zip(grasps, closings, strict=True):
        configurations += [values, {k: float(v) for k, v in
                                    description.model.expand(grasp.q0).items()}]
    return closings, robot_geometry(description, configurations)


def grasp_charts(key: int, grasp: Grasp, runs: Sequence[RobotRun]) -> list[Figure]:
    """A grasp's 2-D charts: Q's histogram over the force-closure draws and the outcome
    counts of its first run (where it keeps its draws), and P(FC) against sigma where it was
    run at several sigmas."""
    figures = []
    first = runs[0].evaluation
    draws = getattr(first, "draws", None)
    if draws is not None:
        quality = draws.quality[draws.outcome == FORCE_CLOSURE]
        figures += [Figure(f"quality-{key}", quality_histogram(quality, first.q_mean,
                                                                grasp.q_nominal),
                           "49%", "340px"),
                    Figure(f"outcomes-{key}", outcome_bars(first.counts), "49%", "340px")]
    if len(runs) > 1:
        points = [(float(np.max(r.sigma)), r.evaluation.p_fc, tuple(r.evaluation.ci))
                  for r in runs]
        figures.append(Figure(f"pfc-{key}", pfc_curve(points, f"{grasp.object} grasp "
                                                      f"{grasp.id}"), "60%", "380px"))
    return figures


def robot_page(description: RobotDescription, obj: GraspObject | Mapping[str, GraspObject],
               grasps: Sequence[Grasp], runs: Sequence[RobotRun], *, command: str,
               settings: dict, friction: float = 0.5, num_edges: int = 8,
               max_points: int = MAX_POINTS, arms: Sequence[NoisyArms] | None = None,
               noise_spec: dict | None = None) -> str:
    """The HTML page of a description robot's grasps.

    Args:
        description: the robot; obj: the object of every grasp, or object name -> object
            (grasps of several objects).
        grasps: the grasps, in the order of the page.
        runs: the evaluations (:class:`RobotRun`), in the order of the table; each grasp's
            first run's draws, where it keeps them, give its contact points (at most
            ``max_points``; a ranking's runs keep counts only).
        command: the command line that reproduces the page; settings: name -> value.
        arms: per grasp, the noisy arms its scene draws (None: none).
        noise_spec: the runs' noise model as its spec (:func:`~kinegrasp_env.sampling.
            noise_spec.spec_of`; None: joint noise of each run's sigma): its sources are
            listed.
    """
    objects = [obj if isinstance(obj, GraspObject) else obj[g.object] for g in grasps]
    closings, geometry = grasps_geometry(description, objects, grasps)
    library, figures, sections = MeshLibrary(), [], []
    by_grasp: dict[int, list[RobotRun]] = {}
    for run in runs:
        by_grasp.setdefault(run.grasp, []).append(run)
    first = {k: grasp_runs[0] for k, grasp_runs in by_grasp.items()}
    for k, (grasp, (_, did_close), here) in enumerate(zip(grasps, closings, objects,
                                                          strict=True)):
        title = f"{description.name}: {here.name} grasp {grasp.id}, world (robot base) frame"
        draws = getattr(first[k].evaluation, "draws", None) if k in first else None
        cloud = None if draws is None else world_cloud(contact_cloud(draws, max_points), here)
        figure = Figure(f"scene-{k}", grasp_scene(
            description, here, grasp, geometry, 2 * k, 2 * k + 1, library, did_close=did_close,
            friction=friction, num_edges=num_edges, title=title, cloud=cloud,
            arms=None if arms is None else arms[k]), "100%", "560px")
        figures.append(figure)
        state = ("drawn closed on the object from the pre-shape of q0 (by the reference "
                 "closing, which every engine's closing follows)" if did_close else
                 "starts in collision at q0 and does not close: drawn at q0")
        drawn = "" if cloud is None else (
            f" The contact points of its first run's draws: {cloud.shown} of {cloud.total}"
            f"{' (a uniform random subset)' if cloud.decimated else ''}.")
        if arms is not None and len(arms[k].q):
            drawn += (f" The arm's skeleton at its first {len(arms[k].q)} draws (toggled in "
                      "the legend).")
        charts = grasp_charts(k, grasp, by_grasp[k]) if k in by_grasp else []
        if draws is not None and len(by_grasp[k]) > 1:
            drawn += (f" Its contact points, Q's histogram and the outcome counts are of its "
                      f"first run (sigma = {sigma_words(first[k].sigma)} rad); the curve and "
                      "the table use every sigma.")
        figures += charts
        sections.append(f"<h2>Grasp {esc(grasp.id)}</h2><p>Q nominal "
                        f"{fmt(grasp.q_nominal)}; the hand is {esc(state)}.{esc(drawn)}</p>"
                        f"{figure.div()}<div class='kg-row'>"
                        f"{''.join(c.div() for c in charts)}</div>")
    model = description.contact_model
    count = plural(len(grasps), "grasp")
    names = ", ".join(dict.fromkeys(o.name for o in objects))
    title = f"kinegrasp report: robot {description.name}, {count} of {names}"
    finite = [r for r in runs if math.isfinite(r.evaluation.p_fc)]
    best = max(finite, key=lambda r: r.evaluation.p_fc) if finite else None
    at = "" if noise_spec is not None or best is None else (
        f" at sigma {sigma_words(best.sigma)} rad")
    lead = ("" if best is None else f" Highest P(FC): grasp {grasps[best.grasp].id} "
            f"({best.evaluation.p_fc:.4f}{at}).")
    noise = (f"joint noise on the {description.arm_dof} arm joints" if noise_spec is None
             else f"a noise model of {len(noise_spec)} sources ({', '.join(noise_spec)})"
             if noise_spec else "a noise model with every source exact")
    sources = ("" if noise_spec is None else
               f"<h2>Noise sources</h2>{noise_sources_table(noise_spec)}")
    body = (f"<h1>{esc(title)}</h1><p class='kg-headline'>P(FC) and Q (Ferrari-Canny, "
            f"{esc(model)} contacts) under {esc(noise)}; Q's moments over the force-closure "
            f"draws.{esc(lead)}</p>"
            f"<h2>Results</h2>{results_table(grasps, runs, noise_spec is not None)}"
            f"{note(geometry_note(geometry))}{''.join(sections)}{sources}"
            f"<h2>Settings</h2>{settings_table(settings)}"
            f"<h2>Command that reproduces this page</h2>{command_block(command)}")
    return page(title, body, figures, library, versions())
