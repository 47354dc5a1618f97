"""Preparing an imported mesh: cleaning, solidity and size checks, the object frame.

* :func:`clean_mesh`: merge duplicate vertices, drop degenerate and repeated faces and
  unused vertices, make the winding consistent and the normals point outwards.
* :func:`check_solid`: at least 4 faces and not flat (a solid has a volume).
* :func:`check_size`: the SDH-like hand must be able to hold it (see :data:`HAND_SPAN`);
  :func:`check_not_tiny`: the too-small half of it, also checked before cleaning.
* :func:`open_edges`: edges that do not join exactly two faces (an open or non-manifold
  mesh; :func:`kinegrasp_env.world.importer.prepare` warns what the import does with it).
* :func:`object_frame`: the import convention for the object frame, the one of the built-in
  objects (docs/conventions.md): origin at the centre of the bottom of the bounding box,
  axes those of the source file, +z up.
"""

from __future__ import annotations

import numpy as np
import trimesh
from scipy.spatial import ConvexHull, QhullError

from kinegrasp_env.wording import plural
from kinegrasp_env.world.meshfile import MeshError

# The hand's proportions (assets/robots/build_kuka_sdh.py; tests check them against the URDF).
#: Radius of the circle the finger bases sit on (metres).
FINGER_BASE_RADIUS = 0.038
#: Proximal + distal phalanx length (metres).
FINGER_LENGTH = 0.0865 + 0.0685
#: Capsule radius of the phalanges (metres): a fingertip is 22 mm thick.
PHALANX_RADIUS = 0.011
#: The widest gap between opposed fingertips (metres): the thumb and fingers 1/2 at spread 0
#: (their bases 1.5 x 38 mm apart across the palm) fully opened (flexion -90 degrees),
#: capsule surface to capsule surface. An object wider than this in every direction cannot
#: be spanned.
HAND_SPAN = 1.5 * FINGER_BASE_RADIUS + 2 * FINGER_LENGTH - 2 * PHALANX_RADIUS
#: The smallest object accepted (metres, largest extent): half a fingertip's thickness.
SMALLEST = PHALANX_RADIUS
#: Relative thickness under which a mesh counts as flat.
FLAT = 1e-4
#: A typical object size for the ``--scale`` suggestion (metres).
TYPICAL_SIZE = 0.1


def open_edges(mesh: trimesh.Trimesh) -> tuple[int, int]:
    """(boundary, non-manifold): the mesh's edges used by one face (holes, an open surface)
    and by more than two faces. Both 0: the mesh is closed (watertight)."""
    if len(mesh.faces) == 0:
        return 0, 0
    _, counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)
    return int(np.sum(counts == 1)), int(np.sum(counts > 2))


def clean_mesh(vertices: np.ndarray, faces: np.ndarray) -> trimesh.Trimesh:
    """The cleaned mesh (see the module docstring); :class:`MeshError` on non-finite
    vertices or out-of-range face indices."""
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if not np.all(np.isfinite(vertices)):
        raise MeshError("the mesh has non-finite vertex coordinates")
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise MeshError("the mesh has faces that index missing vertices")
    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.update_faces(mesh.unique_faces())
    mesh.remove_unreferenced_vertices()
    if len(mesh.faces):
        with np.errstate(divide="ignore", invalid="ignore"):  # a flat mesh has no volume
            trimesh.repair.fix_normals(mesh, multibody=True)
    return mesh


def thickness(vertices: np.ndarray) -> float:
    """Smallest width of the points' convex hull across one of its face normals (metres;
    0 when the points are coplanar)."""
    try:
        hull = ConvexHull(vertices)
    except (QhullError, ValueError):
        return 0.0
    eq = hull.equations
    return float((-(hull.points[hull.vertices] @ eq[:, :3].T + eq[:, 3]).min(axis=0)).min())


def check_solid(mesh: trimesh.Trimesh) -> float:
    """:class:`MeshError` unless the cleaned mesh could bound a solid; returns its thickness
    (smallest hull width, metres)."""
    faces = len(mesh.faces)
    if faces < 4:
        raise MeshError(f"the mesh has {plural(faces, 'non-degenerate face')}; a solid needs "
                        "at least 4")
    size = float(np.max(mesh.extents))
    width = thickness(mesh.vertices)
    if width <= FLAT * size:
        raise MeshError(f"the mesh is flat (zero volume): {width:.3g} thick for "
                        f"{size:.3g} across")
    return width


def check_size(mesh: trimesh.Trimesh, width: float, scale: float = 1.0) -> None:
    """:class:`MeshError` when the hand could not hold the mesh (in metres): narrower than
    :data:`HAND_SPAN` in no direction (``width`` is its smallest width), or smaller than
    :data:`SMALLEST` in every direction (:func:`check_not_tiny`). The message gives the size
    and a fix (:func:`suggest`; ``scale``: the factor from the file's units to metres that
    made the mesh this size)."""
    extents = np.asarray(mesh.extents, dtype=float)
    if width > HAND_SPAN:
        raise MeshError(f"too large for the hand: {_sizes(extents)} m (at least {width:.3g} m "
                        f"across in every direction; the hand spans at most {HAND_SPAN:.3f} "
                        f"m); {suggest(float(extents.max()), scale)}")
    check_not_tiny(extents, scale)


def check_not_tiny(extents: np.ndarray, scale: float = 1.0) -> None:
    """:class:`MeshError` when a mesh of these (3,) extents (metres; ``scale``: as
    :func:`check_size`'s) is smaller than :data:`SMALLEST` in every direction. Checked before
    :func:`clean_mesh` too, whose vertex merging collapses a mesh scaled far too small to no
    face at all."""
    extents = np.asarray(extents, dtype=float)
    if extents.max() < SMALLEST:
        raise MeshError(f"too small for the hand: {_sizes(extents)} m (a fingertip is "
                        f"{2 * PHALANX_RADIUS:.3f} m thick); "
                        f"{suggest(float(extents.max()), scale)}")


def _sizes(extents: np.ndarray) -> str:
    return ", ".join(f"{v:.4g}" for v in extents)


def suggest(largest: float, scale: float = 1.0) -> str:
    """A ``--units``/``--scale`` hint that brings a mesh ``largest`` metres across, read from
    its file with ``scale`` (file units to metres; 1: none given), to a graspable size: the
    units the file's own numbers suggest (where none were given), else the ``--scale`` that
    makes it :data:`TYPICAL_SIZE` across."""
    wanted = scale * TYPICAL_SIZE / largest
    if scale == 1.0:
        for units, factor in (("mm", 1e-3), ("cm", 1e-2)):
            if 0.02 <= largest * factor <= 0.5:
                return f"if the file is in {units}, import it with --units {units}; " \
                       f"else give --scale (e.g. --scale {wanted:.3g})"
    instead = "" if scale == 1.0 else ", instead of the units or scale given"
    return f"give --scale (e.g. --scale {wanted:.3g} makes it {TYPICAL_SIZE:g} m " \
           f"across{instead})"


def object_frame(mesh: trimesh.Trimesh) -> np.ndarray:
    """(4, 4) translation from the source frame to the object frame: origin at the centre
    of the bottom face of the axis-aligned bounding box."""
    lo, hi = mesh.bounds
    transform = np.eye(4)
    transform[:3, 3] = -np.array([(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, lo[2]])
    return transform
