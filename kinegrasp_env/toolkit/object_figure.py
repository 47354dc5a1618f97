"""A picture of an object: its mesh next to its convex parts (``kinegrasp objects show``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.spatial import ConvexHull

from kinegrasp_env.toolkit.plots import few_ticks, save_figure
from kinegrasp_env.wording import plural
from kinegrasp_env.world.objects import GraspObject

#: Triangles drawn at most per panel (a dense scan is thinned evenly).
MAX_TRIANGLES = 20_000


def plot_object(obj: GraspObject, path: str | Path, title: str = "") -> Path:
    """Write a PNG: the object's mesh (left) and its convex parts, one colour each (right),
    object frame, metres, equal axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(10, 5))
    mesh_tris = np.asarray(obj.mesh.triangles)
    step = max(1, len(mesh_tris) // MAX_TRIANGLES)
    left = fig.add_subplot(1, 2, 1, projection="3d")
    left.add_collection3d(Poly3DCollection(mesh_tris[::step], facecolor="#c8a878",
                                           edgecolor="#7a6040", linewidths=0.1, alpha=0.9))
    left.set_title(f"mesh: {len(mesh_tris)} triangles")
    right = fig.add_subplot(1, 2, 2, projection="3d")
    colours = plt.get_cmap("tab20")
    for index, part in enumerate(obj.parts):
        hull = ConvexHull(part)
        right.add_collection3d(Poly3DCollection(
            hull.points[hull.simplices], facecolor=colours(index % 20), edgecolor="k",
            linewidths=0.1, alpha=0.85))
    right.set_title(f"{plural(len(obj.parts), 'convex part')}")
    lo, hi = obj.mesh.bounds
    centre, half = (lo + hi) / 2, float(np.max(hi - lo)) / 2 or 1.0
    for ax in (left, right):
        ax.set_xlim(centre[0] - half, centre[0] + half)
        ax.set_ylim(centre[1] - half, centre[1] + half)
        ax.set_zlim(centre[2] - half, centre[2] + half)
        ax.set_box_aspect((1, 1, 1))
        for axis in (ax.xaxis, ax.yaxis, ax.zaxis):  # few ticks: the corners' labels clashed
            axis.set_major_locator(few_ticks(4))
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_zlabel("z [m]")
    fig.suptitle(title or obj.name)
    return save_figure(fig, path)
