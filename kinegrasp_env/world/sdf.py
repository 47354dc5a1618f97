"""Signed-distance grid of an object, for batched collision queries.

The grid holds, at every node of a regular lattice over the object's bounding box plus a
margin, the exact signed distance to the object's union of convex parts (the smallest
per-part signed distance: what pybullet reports for the same parts), computed by
:meth:`kinegrasp_env.world.objects.GraspObject.closest_points`. Nodes farther than the margin from
a part are given the margin (a lower bound). Queries interpolate trilinearly; outside the
lattice the value at the nearest lattice point plus the distance to the lattice box is
returned (a lower bound away from the object).

Trilinear interpolation reproduces the distance exactly wherever it is linear (next to a face
of a part, inside or outside); near edges and corners it is within a fraction of the spacing.
The grids are built on first use (a few seconds) and cached on disk, keyed by the object's
parts and the grid settings: ``$KINEGRASP_CACHE`` or ``~/.cache/kinegrasp``; an imported
object's grid is built at import and kept in its catalog entry (:mod:`kinegrasp_env.world.store`).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from kinegrasp_env.paths import cache_root
from kinegrasp_env.world.gridkernel import part_distances
from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.polytope import INSIDE_TOL, ConvexPart
from kinegrasp_env.world.store import imported_folder

#: Lattice spacing (metres).
SPACING = 1.5e-3
#: Margin around the object's bounding box, and the largest distance stored (metres).
MARGIN = 0.03
#: Bump when the way grids are computed changes (invalidates the cache).
FORMAT_VERSION = 1
#: Nodes per block when building.
BUILD_BLOCK = 200_000
#: A part reaching beyond the mesh's bounding box by more than this widens the lattice (m).
BEYOND = 1e-6


def cache_dir() -> Path:
    """Where built grids are kept."""
    return cache_root() / "sdf"


@dataclass(frozen=True, eq=False)
class DistanceGrid:
    """Trilinear signed-distance lattice (object frame).

    Attributes:
        origin: (3,) position of node (0, 0, 0), metres.
        spacing: node spacing h, metres.
        values: (nx, ny, nz) float64 signed distances, metres.
    """

    origin: np.ndarray
    spacing: float
    values: np.ndarray

    @property
    def shape(self) -> tuple[int, int, int]:
        return self.values.shape

    def _cells(self, points: np.ndarray):
        """Cell corner flat index (n,), fractions (n, 3) and distance outside the box (n,)."""
        nx, ny, nz = self.shape
        # times the inverse spacing, as the compiled twin (capsule_gap.trilinear) computes it
        # (three divisions per lookup made one compiled grid gap 14% slower)
        rel = (points - self.origin) * (1.0 / self.spacing)
        upper = np.array([nx - 1, ny - 1, nz - 1], dtype=float)
        clamped = np.minimum(np.maximum(rel, 0.0), upper)
        d = rel - clamped
        outside = np.sqrt(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1]
                          + d[..., 2] * d[..., 2]) * self.spacing
        cell = np.minimum(clamped.astype(np.intp), np.array([nx - 2, ny - 2, nz - 2]))
        frac = clamped - cell
        flat = (cell[..., 0] * ny + cell[..., 1]) * nz + cell[..., 2]
        return flat, frac, outside

    def distance(self, points: np.ndarray, gradient: bool = False):
        """Signed distance at points (..., 3); with ``gradient``, also d/dx (..., 3)."""
        points = np.asarray(points, dtype=float)
        flat, frac, outside = self._cells(points)
        _, ny, nz = self.shape
        v = self.values.reshape(-1)
        fx, fy, fz = frac[..., 0], frac[..., 1], frac[..., 2]
        c000 = v[flat]
        c001 = v[flat + 1]
        c010 = v[flat + nz]
        c011 = v[flat + nz + 1]
        step = ny * nz
        c100 = v[flat + step]
        c101 = v[flat + step + 1]
        c110 = v[flat + step + nz]
        c111 = v[flat + step + nz + 1]
        c00 = c000 + (c001 - c000) * fz
        c01 = c010 + (c011 - c010) * fz
        c10 = c100 + (c101 - c100) * fz
        c11 = c110 + (c111 - c110) * fz
        c0 = c00 + (c01 - c00) * fy
        c1 = c10 + (c11 - c10) * fy
        value = c0 + (c1 - c0) * fx + outside
        if not gradient:
            return value
        gx = c1 - c0
        gy = (c01 - c00) * (1 - fx) + (c11 - c10) * fx
        dz0 = (c001 - c000) * (1 - fy) + (c011 - c010) * fy
        dz1 = (c101 - c100) * (1 - fy) + (c111 - c110) * fy
        gz = dz0 * (1 - fx) + dz1 * fx
        return value, np.stack([gx, gy, gz], axis=-1) / self.spacing


def grid_key(obj: GraspObject, spacing: float = SPACING, margin: float = MARGIN) -> str:
    """Hex key of a grid: the object's parts and the grid settings."""
    digest = hashlib.sha256()
    for part in obj.parts:
        digest.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
    digest.update(np.array([spacing, margin, FORMAT_VERSION], dtype=np.float64).tobytes())
    return digest.hexdigest()[:16]


def build_grid(obj: GraspObject, spacing: float = SPACING, margin: float = MARGIN,
               progress: bool = False) -> DistanceGrid:
    """Compute the grid of ``obj`` (exact distances at the nodes).

    The lattice covers the mesh's bounding box, widened where a part reaches beyond it by
    more than :data:`BEYOND` (an imported object's hulls may). An imported object's nodes go
    through the compiled :func:`kinegrasp_env.world.gridkernel.part_distances` (the same
    method; its parts have many more edges), the built-in objects' through
    :meth:`~kinegrasp_env.world.polytope.ConvexPart.closest` (their grids stay bit for bit).
    """
    lo, hi = obj.mesh.bounds
    p_lo = np.min([p.min(axis=0) for p in obj.parts], axis=0)
    p_hi = np.max([p.max(axis=0) for p in obj.parts], axis=0)
    lo = np.where(p_lo < lo - BEYOND, p_lo, lo)
    hi = np.where(p_hi > hi + BEYOND, p_hi, hi)
    origin = lo - margin
    shape = tuple(int(np.ceil(s)) + 1 for s in (hi - lo + 2 * margin) / spacing)
    values = np.full(shape, margin, dtype=np.float64)
    axes = [origin[k] + spacing * np.arange(shape[k]) for k in range(3)]
    parts = obj.convex_parts
    iterator = range(len(parts))
    if progress:
        from tqdm import tqdm

        iterator = tqdm(iterator, desc=f"distance grid {obj.name}", unit="part")
    for index in iterator:
        part = parts[index]
        p_lo, p_hi = part.vertices.min(axis=0) - margin, part.vertices.max(axis=0) + margin
        ranges = [np.flatnonzero((axes[k] >= p_lo[k] - spacing) & (axes[k] <= p_hi[k] + spacing))
                  for k in range(3)]
        grid = np.stack(np.meshgrid(*(axes[k][ranges[k]] for k in range(3)), indexing="ij"),
                        axis=-1).reshape(-1, 3)
        block = values[np.ix_(*ranges)]
        dist = node_distances(part, grid, block.reshape(-1), compiled=obj.imported)
        np.minimum(block, dist.reshape(block.shape), out=block)
        values[np.ix_(*ranges)] = block
    # kept in float32 precision (2e-9 m at the margin) so a fresh grid equals a cached one
    return DistanceGrid(origin, spacing, values.astype(np.float32).astype(np.float64))


def object_grid(name: str, spacing: float = SPACING, margin: float = MARGIN) -> DistanceGrid:
    """The distance grid of catalog object ``name`` as it is now: an object re-imported
    under the same name is a new :class:`GraspObject` (``load_object`` keys it by its
    catalog version), so it gets its new grid."""
    return grid_of(load_object(name), spacing, margin)


@lru_cache(maxsize=8)
def grid_of(obj: GraspObject, spacing: float = SPACING, margin: float = MARGIN
            ) -> DistanceGrid:
    """The distance grid of a catalog object, loaded from disk or built and saved; cached
    per object (by identity, not by name)."""
    folder = imported_folder(obj.name) if obj.imported else None
    path = (folder or cache_dir()) / grid_file_name(obj, spacing, margin)
    if path.exists():
        try:
            with np.load(path) as data:
                return DistanceGrid(data["origin"], float(data["spacing"]),
                                    data["values"].astype(np.float64))
        except (OSError, ValueError, KeyError):
            pass  # unreadable cache entry: rebuild it
    grid = build_grid(obj, spacing, margin)
    try:
        save_grid(grid, path)
    except OSError:
        pass  # read-only home: keep the grid in memory only
    return grid


def node_distances(part: ConvexPart, nodes: np.ndarray, current: np.ndarray,
                   compiled: bool = False) -> np.ndarray:
    """Signed distances (n,) of nodes (n, 3) to ``part``; ``compiled``: or ``current`` (n,)
    where the part's plane bound shows the distance is not smaller (see
    :mod:`kinegrasp_env.world.gridkernel`)."""
    if compiled:
        return part_distances(nodes, part.planes, part.edges, INSIDE_TOL * part.scale,
                              np.ascontiguousarray(current, dtype=np.float64))
    dist = np.empty(len(nodes))
    for start in range(0, len(nodes), BUILD_BLOCK):
        dist[start:start + BUILD_BLOCK] = part.closest(nodes[start:start + BUILD_BLOCK])[1]
    return dist


def grid_file_name(obj: GraspObject, spacing: float = SPACING, margin: float = MARGIN) -> str:
    """``<name>-<key>.npz``: the file name of an object's grid."""
    return f"{obj.name}-{grid_key(obj, spacing, margin)}.npz"


def save_grid(grid: DistanceGrid, path: Path) -> None:
    """Write a grid (float32 values) through a temporary file and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
    np.savez(tmp, origin=grid.origin, spacing=grid.spacing,
             values=grid.values.astype(np.float32))
    os.replace(tmp, path)
