"""The object catalog: meshes, convex parts, centre of mass, r_max, pose.

Built-in objects (:data:`OBJECT_NAMES`) are unions of convex parts (see
``assets/objects/build_objects.py``): the parts are the collision geometry, the watertight
mesh is their union, so contacts found against the parts lie on the mesh. Imported objects
(``kinegrasp objects add``, :mod:`kinegrasp_env.world.importer`) keep their cleaned source mesh
for pictures and a convex decomposition of it as their collision geometry; their centre of
mass and r_max are those of the parts' union. Object frame: origin at the centre of the base,
+z up (metres); every object stands at :data:`OBJECT_POSITION` in the world (robot base)
frame unless its catalog entry gives a pose.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from kinegrasp_env.assets import asset_path
from kinegrasp_env.world.names import (  # noqa: F401 (is_object, object_names: re-exported)
    OBJECT_NAMES,
    OBJECT_POSITION,
    is_object,
    object_names,
    unknown_object,
)
from kinegrasp_env.world.object_geometry import (
    GivenMesh,
    MeshFile,
    builtin_geometry,
    split_rows,
)
from kinegrasp_env.world.polytope import ConvexPart, face_planes
from kinegrasp_env.world.store import (
    MESH_FILE,
    PARTS_FILE,
    CatalogError,
    entry_digest,
    imported_folder,
    read_entry,
)
from kinegrasp_env.world.support import SupportTable
from kinegrasp_env.world.surface_kernel import project_onto_parts

if TYPE_CHECKING:
    import trimesh


#: Density of an object whose catalog entry gives none, kg/m^3 (wood, or a plastic part with
#: air inside).
DEFAULT_DENSITY = 500.0

@dataclass(frozen=True, eq=False)
class GraspObject:
    """One catalog object.

    Attributes:
        name: catalog name.
        mesh_source: returns the triangle mesh (:attr:`mesh`; called on first use, so code
            that needs only the parts never loads trimesh).
        parts: convex parts, each an (n_i, 3) vertex array (object frame).
        planes: per part, (F_i, 4) outward face planes [normal (3), offset] with
            normal . x + offset <= 0 inside.
        center_of_mass: (3,) object frame (uniform density).
        r_max: largest distance from the centre of mass to a vertex of the parts' union
            (metres; for a built-in object, a vertex of its mesh).
        pose: (4, 4) object frame in the world frame.
        mesh_file: the mesh's file (for visual shapes), or None.
        imported: True for an object of the user's catalog.
        table: the support table under the object (:mod:`kinegrasp_env.world.support`), or
            None (the object floats at its pose: the paper's setting).
        base: for a placed object (``kinegrasp objects place ... --as NAME``), the object
            whose geometry (and, placed as the base is, shipped grasps) it has; else None.
        part_edges: per part, its true edges (E_i, 2, 3) as computed before, or None
            (:attr:`ConvexPart.edges` computes them).
        density: kg/m^3, uniform (:data:`DEFAULT_DENSITY` unless the catalog entry gives
            one); the mass is this times the mesh's volume (:attr:`mass`).
    """

    name: str
    mesh_source: Callable[[], trimesh.Trimesh] = field(repr=False)
    parts: tuple[np.ndarray, ...]
    planes: tuple[np.ndarray, ...] = field(repr=False)
    center_of_mass: np.ndarray = field(repr=False)
    r_max: float = 0.0
    pose: np.ndarray = field(default_factory=lambda: np.eye(4), repr=False)
    mesh_file: Path | None = field(default=None, repr=False)
    imported: bool = False
    table: SupportTable | None = None
    base: str | None = None
    part_edges: tuple[np.ndarray, ...] | None = field(default=None, repr=False)
    density: float = DEFAULT_DENSITY

    @cached_property
    def mesh(self) -> trimesh.Trimesh:
        """Triangle mesh, object frame: for a built-in object the watertight union of the
        parts, for an imported one its cleaned source mesh."""
        return self.mesh_source()

    @property
    def mass(self) -> float:
        """kg: :attr:`density` times the mesh's volume (uniform density)."""
        return float(self.density * self.mesh.volume)

    @property
    def torque_scale(self) -> float:
        """1 / r_max (GraspIt's convention), 1/metres."""
        return 1.0 / self.r_max

    @property
    def size(self) -> np.ndarray:
        """(3,) bounding-box extents, metres."""
        return self.mesh.extents

    @cached_property
    def pose_inverse(self) -> np.ndarray:
        """(4, 4) world -> object frame."""
        return np.linalg.inv(self.pose)

    def to_object(self, points_world: np.ndarray) -> np.ndarray:
        """World points (..., 3) to the object frame."""
        return frame_coordinates(self.pose, points_world)

    def to_world(self, points: np.ndarray) -> np.ndarray:
        """Object-frame points (..., 3) to the world frame."""
        return np.asarray(points) @ self.pose[:3, :3].T + self.pose[:3, 3]

    def surface(self, points: np.ndarray, part: np.ndarray | None = None,
                edge_tol: float = 5e-5) -> tuple[np.ndarray, np.ndarray]:
        """Project object-frame points (n, 3) lying on or near a part's boundary onto it.

        Args:
            points: (n, 3) object frame.
            part: (n,) index of the part each point belongs to; default: the part whose
                boundary is nearest.

            edge_tol: face planes within this distance of the outermost one (metres) mark
                the point as lying on an edge or corner of the part.

        Returns:
            (projected points (n, 3), inward unit normals (n, 3)): the outermost face plane
            of the part gives the normal and, unless the point is on an edge or corner, the
            projection (there the plane projection could leave the part: the point is kept).
        """
        points = np.ascontiguousarray(np.atleast_2d(np.asarray(points, dtype=float)))
        if part is None:
            part = self.nearest_part(points)
        out_p = np.empty_like(points)
        out_n = np.empty_like(points)
        project_onto_parts(*self.packed_planes, points,
                           np.ascontiguousarray(part, dtype=np.int64), float(edge_tol), out_p,
                           out_n)
        return out_p, out_n

    @cached_property
    def packed_planes(self) -> tuple[np.ndarray, np.ndarray]:
        """Every part's planes stacked (P, 4), and the (n_parts + 1,) int64 offsets of each
        part's rows."""
        counts = [len(p) for p in self.planes]
        return (np.ascontiguousarray(np.vstack(self.planes), dtype=float),
                np.concatenate([[0], np.cumsum(counts)]).astype(np.int64))

    def part_distance(self, points: np.ndarray) -> np.ndarray:
        """(n, n_parts) signed plane distance of points to each part (<= 0 inside)."""
        points = np.atleast_2d(points)
        return np.stack([np.max(points @ pl[:, :3].T + pl[:, 3], axis=1) for pl in self.planes],
                        axis=1)

    def ray_entry(self, origin: np.ndarray, direction: np.ndarray) -> float | None:
        """Distance along a ray (object frame, unit ``direction``) to where it first enters
        the object, or None if it misses (exact: ray against every convex part)."""
        best = None
        for planes in self.planes:
            normal_dot = planes[:, :3] @ direction
            start = planes[:, :3] @ origin + planes[:, 3]  # signed distance of the origin
            t_in, t_out = 0.0, np.inf
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -start / normal_dot
            entering, leaving = normal_dot < 0, normal_dot > 0
            if np.any((normal_dot == 0) & (start > 0)):
                continue
            if entering.any():
                t_in = max(t_in, float(t[entering].max()))
            if leaving.any():
                t_out = min(t_out, float(t[leaving].min()))
            if t_in <= t_out and (best is None or t_in < best):
                best = t_in
        return best

    @cached_property
    def convex_parts(self) -> tuple[ConvexPart, ...]:
        """The parts as :class:`ConvexPart` (exact closest points)."""
        edges = self.part_edges or (None,) * len(self.parts)
        return tuple(ConvexPart(v, p, e)
                     for v, p, e in zip(self.parts, self.planes, edges, strict=True))

    def closest_points(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact closest points on the object of object-frame points (n, 3).

        The signed distance is the smallest over the parts (what a collision checker
        reports for the union of convex parts): > 0 outside, < 0 inside a part.

        Returns:
            (closest (n, 3), signed distance (n,), part index (n,)).
        """
        points = np.atleast_2d(np.asarray(points, dtype=float))
        bound = self.part_distance(points)  # plane values: lower bounds of the distances
        best_d = np.full(len(points), np.inf)
        best_p = np.empty_like(points)
        best_i = np.zeros(len(points), dtype=np.intp)
        for index in np.argsort(bound.min(axis=0)):
            rows = np.flatnonzero(bound[:, index] < best_d)
            if rows.size == 0:
                continue
            closest, distance = self.convex_parts[index].closest(points[rows])
            better = distance < best_d[rows]
            rows = rows[better]
            best_d[rows], best_p[rows], best_i[rows] = distance[better], closest[better], index
        return best_p, best_d, best_i

    def nearest_part(self, points: np.ndarray) -> np.ndarray:
        """(n,) index of the part whose boundary is nearest (by plane distance)."""
        return np.argmin(np.abs(self.part_distance(points)), axis=1)


def default_pose() -> np.ndarray:
    """(4, 4) the default placement: object frame at :data:`OBJECT_POSITION`, axes aligned."""
    pose = np.eye(4)
    pose[:3, 3] = OBJECT_POSITION
    return pose


def _imported_folder_of(name: str) -> Path:
    """The catalog folder of imported object ``name``; ValueError (the message lists the
    known names) where there is none."""
    folder = imported_folder(name)
    if folder is None:
        raise unknown_object(name)
    return folder


def load_object(name: str) -> GraspObject:
    """Load a built-in or imported object by name.

    Raises:
        ValueError: for an unknown name (the message lists the known ones), or an imported
            entry that cannot be read.
    """
    if name in OBJECT_NAMES:
        return builtin_object(name)
    folder = _imported_folder_of(name)
    entry = read_entry(folder)  # an unreadable or newer entry: its one-line error
    if entry.get("base") is not None:
        return placed_object(str(folder), entry_digest(folder))
    return imported_object(str(folder), entry_digest(folder))


def as_object(obj: str | GraspObject) -> GraspObject:
    """``obj`` itself, or the catalog object it names (:func:`load_object`).

    Raises:
        TypeError: neither a name nor an object (one line, naming the value).
        ValueError: an unknown name.
    """
    if isinstance(obj, GraspObject):
        return obj
    if isinstance(obj, str):
        return load_object(obj)
    raise TypeError(f"obj must be a catalog object's name or a GraspObject, got "
                    f"{type(obj).__name__} {obj!r:.60}")


def source_to_object(name: str) -> np.ndarray | None:
    """(4, 4) the map from an imported object's source mesh frame (the file's own coordinates
    and units) to its object frame, as ``objects add`` recorded it (its scale times its up
    turn, then the translation to the base centre: ``p_object = A[:3, :3] @ p_source +
    A[:3, 3]``); a placed copy has its base's. None for a built-in object (or an entry that
    records none).

    Raises:
        ValueError: an unknown name (the message lists the known ones).
    """
    if name in OBJECT_NAMES:
        return None
    folder = _imported_folder_of(name)
    entry = read_entry(folder)
    if entry.get("base") is not None:
        return source_to_object(entry["base"])
    value = entry.get("source_to_object")
    return None if value is None else np.asarray(value, dtype=float)


def frame_coordinates(pose: np.ndarray, points_world: np.ndarray) -> np.ndarray:
    """World points (..., 3) in the frame whose world pose is ``pose`` (4, 4, rigid)."""
    return (np.asarray(points_world) - pose[:3, 3]) @ pose[:3, :3]


#: :func:`object_version` of every built-in object (they never change in a process).
BUILTIN_VERSION = "built-in"


def object_version(name: str) -> str:
    """What a per-object cache is keyed by besides the name: :data:`BUILTIN_VERSION` for a
    built-in object, else the digest of the imported entry's ``entry.json``
    (:func:`~kinegrasp_env.world.store.entry_digest`), which changes when the object is
    re-imported under the same name (``objects add --force``, here or in another process).

    Raises:
        ValueError: an unknown name (the message lists the known ones).
    """
    if name in OBJECT_NAMES:
        return BUILTIN_VERSION
    folder = _imported_folder_of(name)
    return entry_digest(folder)


@lru_cache(maxsize=8)
def builtin_object(name: str) -> GraspObject:
    """A built-in object (``assets/objects``)."""
    data = json.loads(asset_path("objects", f"{name}_parts.json").read_text())
    parts = tuple(np.asarray(p, dtype=float) for p in data["parts"])
    geometry = builtin_geometry(name)
    planes, edges = (split_rows(geometry[rows], geometry[offsets])
                     for rows, offsets in (("planes", "offsets"), ("edges", "edge_offsets")))
    obj_file = asset_path("objects", f"{name}.obj")
    return GraspObject(name, MeshFile(obj_file, True), parts, planes,
                       geometry["center_of_mass"], float(geometry["r_max"]), default_pose(),
                       obj_file, part_edges=edges)


@lru_cache(maxsize=8)
def imported_object(folder: str, version: str) -> GraspObject:
    """An imported object from its entry folder (cached per folder and
    :func:`object_version`, so a re-imported entry is read afresh)."""
    path = Path(folder)
    entry = read_entry(path)
    data = json.loads((path / PARTS_FILE).read_text())
    parts = [np.asarray(p, dtype=float) for p in data["parts"]]
    obj = object_from_parts(path.name, MeshFile(path / MESH_FILE, False), parts,
                            np.asarray(entry["center_of_mass"]), float(entry["r_max"]), None,
                            path / MESH_FILE)
    return replace(obj, density=float(entry.get("density", DEFAULT_DENSITY)),
                   **entry_placement(entry))


@lru_cache(maxsize=8)
def placed_object(folder: str, version: str) -> GraspObject:
    """A placed object (an entry with a ``base``): the base object's geometry under the
    entry's name, pose and table (cached per folder and :func:`object_version`).

    Raises:
        CatalogError: the base object is no longer in the catalog.
    """
    path = Path(folder)
    entry = read_entry(path)
    try:
        base = load_object(entry["base"])
    except ValueError:
        raise CatalogError(f"placed object {path.name!r} stands for {entry['base']!r}, which "
                           f"is no longer in the catalog; remove it with `kinegrasp objects "
                           f"remove {path.name}`") from None
    return replace(base, name=path.name, base=base.base or base.name,
                   density=float(entry.get("density", base.density)),
                   **entry_placement(entry))


def entry_placement(entry: dict) -> dict:
    """``pose`` (4, 4) and ``table`` of a catalog entry (default pose, no table when
    absent)."""
    pose = entry.get("pose")
    table = entry.get("table")
    return {"pose": default_pose() if pose is None else np.asarray(pose, dtype=float),
            "table": None if table is None else SupportTable.from_dict(table)}


def object_from_parts(name: str, mesh: trimesh.Trimesh | Callable[[], trimesh.Trimesh],
                      parts: list[np.ndarray],
                      center_of_mass: np.ndarray, r_max: float, pose: np.ndarray | None = None,
                      mesh_file: Path | None = None) -> GraspObject:
    """An imported object from its mesh (or a callable that returns it) and convex parts
    (object frame, metres)."""
    parts_t = tuple(np.ascontiguousarray(p, dtype=float) for p in parts)
    source = mesh if callable(mesh) else GivenMesh(mesh)
    return GraspObject(name, source, parts_t, tuple(face_planes(p) for p in parts_t),
                       np.asarray(center_of_mass, dtype=float), float(r_max),
                       default_pose() if pose is None else pose, mesh_file, True)
