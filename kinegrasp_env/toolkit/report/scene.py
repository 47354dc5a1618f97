"""The pieces of the report's rotatable 3-D scenes as plotly traces (plain dicts): the
object mesh and, toggled, its convex parts; every draw's contact points coloured by outcome
or, by a button, by finger; skeleton polylines; the axes, the close-up box and the colours.
The scenes themselves (the whole robot closed on the object) are
:func:`~kinegrasp_env.toolkit.report.robot.grasp_scene`'s. Metres throughout.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.draws import OUTCOMES, DrawBatch
from kinegrasp_env.toolkit.report.plotly import (
    MESH_STYLE,
    MeshLibrary,
    instanced_mesh,
    typed_array,
)
from kinegrasp_env.world.objects import GraspObject

OUTCOME_COLOURS = {"start_collision": "#7f7f7f", "missed": "#d62728",
                   "no_force_closure": "#ff7f0e", "force_closure": "#2ca02c"}
FINGER_COLOURS = ("#e41a1c", "#4daf4a", "#377eb8")
PART_COLOURS = ("#8dd3c7", "#bebada", "#fb8072", "#80b1d3", "#fdb462", "#b3de69", "#fccde5",
                "#bc80bd", "#ccebc5", "#ffed6f")
#: Most draw contact points drawn in one view; past it a uniform random subset is drawn.
MAX_POINTS = 15_000
#: A scene's legend: in rows under the scene (in the margin :data:`LEGEND_MARGIN` keeps),
#: off the objects and hands it names.
LEGEND = {"orientation": "h", "x": 0.0, "y": 0.0, "xanchor": "left", "yanchor": "top",
          "itemsizing": "constant", "font": {"size": 11}}
#: The bottom margin (pixels) of a scene's figure: the legend's rows.
LEGEND_MARGIN = 95
#: The grasp view shows the object's bounding box grown on each side by this fraction of its
#: largest extent plus CLOSE_UP_PAD metres (the hand beyond it is clipped).
CLOSE_UP_MARGIN, CLOSE_UP_PAD = 0.1, 0.04
#: Friction cones' axis length as a fraction of the object's largest extent.
CONE_SCALE = 0.12
#: Where a scene's camera looks from (plotly's eye, in units of the scene's box): on the
#: close-up and on the whole robot; far enough that the box's corners stay in the panel.
CLOSE_UP_EYE = {"x": 1.3, "y": 1.3, "z": 0.85}
WHOLE_EYE = {"x": 1.85, "y": 1.85, "z": 1.2}


def mesh_trace(vertices: np.ndarray, faces: np.ndarray, name: str, color: str, *,
               opacity: float = 1.0, **extra) -> dict:
    """A Mesh3d trace of vertices (V, 3) and triangles (F, 3)."""
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    return {"type": "mesh3d", "name": name, "color": color, "opacity": opacity,
            "x": typed_array(vertices[:, 0]), "y": typed_array(vertices[:, 1]),
            "z": typed_array(vertices[:, 2]), "i": typed_array(faces[:, 0], "<u4"),
            "j": typed_array(faces[:, 1], "<u4"), "k": typed_array(faces[:, 2], "<u4"),
            **MESH_STYLE, **extra}


def object_traces(obj: GraspObject, library: MeshLibrary, frame: np.ndarray | None = None,
                  parts: bool = True) -> list[dict]:
    """The object mesh and (hidden until toggled in the legend) its convex parts, placed by
    ``frame`` (4, 4; default: the object frame)."""
    pose = np.eye(4) if frame is None else frame
    key = library.add(f"object:{obj.name}", obj.mesh.vertices, obj.mesh.faces)
    traces = [instanced_mesh([(key, pose)], f"object ({obj.name})", "#b0b0b0", opacity=0.45)]
    if parts:
        from scipy.spatial import ConvexHull

        for index, part in enumerate(obj.parts):
            key = library.add(f"part:{obj.name}:{index}", part, ConvexHull(part).simplices)
            traces.append(instanced_mesh([(key, pose)], "convex parts",
                                         PART_COLOURS[index % len(PART_COLOURS)], opacity=0.8,
                                         legendgroup="parts", showlegend=index == 0,
                                         visible="legendonly"))
    return traces


@dataclass
class ContactCloud:
    """The draws' contact points, flattened (object frame) and possibly decimated.

    Attributes:
        points: (m, 3); outcome, finger, draw: (m,) per point; quality: (m,) Q of its draw.
        total: contact points before decimation; shown: m.
    """

    points: np.ndarray
    outcome: np.ndarray
    finger: np.ndarray
    draw: np.ndarray
    quality: np.ndarray
    total: int

    @property
    def shown(self) -> int:
        return len(self.points)

    @property
    def decimated(self) -> bool:
        return self.shown < self.total


def contact_cloud(draws: DrawBatch, limit: int = MAX_POINTS, seed: int = 0) -> ContactCloud:
    """Every contact of every draw; past ``limit`` points a uniform random subset of
    ``limit`` of them (seeded, in draw order)."""
    draw, slot = np.nonzero(draws.finger >= 0)
    total = len(draw)
    if total > limit:
        keep = np.sort(np.random.default_rng(seed).choice(total, size=limit, replace=False))
        draw, slot = draw[keep], slot[keep]
    return ContactCloud(draws.points[draw, slot], draws.outcome[draw], draws.finger[draw, slot],
                        draw, draws.quality[draw], total)


def _points_trace(cloud: ContactCloud, rows: np.ndarray, name: str, colour: str,
                  visible) -> dict:
    pts = cloud.points[rows]
    custom = np.stack([cloud.draw[rows], cloud.quality[rows]], axis=1)
    return {"type": "scatter3d", "mode": "markers", "name": name, "visible": visible,
            "x": typed_array(pts[:, 0]), "y": typed_array(pts[:, 1]),
            "z": typed_array(pts[:, 2]), "customdata": typed_array(custom),
            "hovertemplate": "draw %{customdata[0]:.0f}<br>Q %{customdata[1]:.5f}"
                             f"<extra>{name}</extra>",
            "marker": {"size": 2, "color": colour, "opacity": 0.8}}


def cloud_traces(cloud: ContactCloud) -> tuple[list[dict], list[dict]]:
    """(traces by outcome, shown; traces by finger, hidden): one per class present."""
    by_outcome = [_points_trace(cloud, np.flatnonzero(cloud.outcome == k), name.replace("_", " "),
                                OUTCOME_COLOURS[name], True)
                  for k, name in enumerate(OUTCOMES) if np.any(cloud.outcome == k)]
    by_finger = [_points_trace(cloud, np.flatnonzero(cloud.finger == f), f"finger {f + 1}",
                               FINGER_COLOURS[f], False)
                 for f in range(len(FINGER_COLOURS)) if np.any(cloud.finger == f)]
    return by_outcome, by_finger


def colour_buttons(first: int, outcome_count: int, finger_count: int) -> dict:
    """An updatemenu switching the draw points between colour by outcome and by finger."""
    indices = list(range(first, first + outcome_count + finger_count))
    by_outcome = [True] * outcome_count + [False] * finger_count
    by_finger = [False] * outcome_count + [True] * finger_count
    return {"type": "buttons", "direction": "right", "x": 0.0, "y": 1.0, "xanchor": "left",
            "yanchor": "top", "showactive": True, "active": 0,
            "buttons": [{"label": "colour by outcome", "method": "restyle",
                         "args": [{"visible": by_outcome}, indices]},
                        {"label": "colour by finger", "method": "restyle",
                         "args": [{"visible": by_finger}, indices]}]}


def scene_axes(box: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """A 3-D scene with equal scales on x, y, z (metres), showing the axis-aligned ``box``
    (lower (3,), upper (3,) corners; what lies outside is clipped) or all the data."""
    axis = {"showbackground": True, "backgroundcolor": "#f4f4f8", "gridcolor": "#d0d0d8",
            "zerolinecolor": "#b0b0b8"}
    scene = {"aspectmode": "data", "annotations": [],
             "camera": {"eye": dict(CLOSE_UP_EYE if box is not None else WHOLE_EYE)},
             "domain": {"x": [0, 1], "y": [0, 1]}}
    for k, name in enumerate("xyz"):
        scene[f"{name}axis"] = {**axis, "title": {"text": f"{name} [m]"}}
        if box is not None:
            scene[f"{name}axis"]["range"] = [float(box[0][k]), float(box[1][k])]
    if box is not None:
        extent = np.asarray(box[1]) - np.asarray(box[0])
        scene["aspectmode"] = "manual"
        scene["aspectratio"] = dict(zip("xyz", (extent / extent.max()).tolist(), strict=True))
    return scene


def close_up(obj: GraspObject) -> tuple[np.ndarray, np.ndarray]:
    """The object's bounding box grown on each side by :data:`CLOSE_UP_MARGIN` times its
    largest extent plus :data:`CLOSE_UP_PAD` (lower (3,), upper (3,) corners, metres)."""
    lower, upper = obj.mesh.bounds
    pad = CLOSE_UP_MARGIN * float(np.max(upper - lower)) + CLOSE_UP_PAD
    return lower - pad, upper + pad


def skeleton_trace(points: np.ndarray, name: str, colour: str, width: float, **extra) -> dict:
    """Polylines (n, L, 3) as one Scatter3d line trace (NaN rows separate them)."""
    points = np.asarray(points, dtype=float)
    gaps = np.full((points.shape[0], 1, 3), np.nan)
    flat = np.concatenate([points, gaps], axis=1).reshape(-1, 3)
    return {"type": "scatter3d", "mode": "lines", "name": name, "connectgaps": False,
            "x": typed_array(flat[:, 0]), "y": typed_array(flat[:, 1]),
            "z": typed_array(flat[:, 2]), "hoverinfo": "name",
            "line": {"color": colour, "width": width}, **extra}
