"""Signed-distance grid of an object, for batched collision queries.

The grid holds, at every node of a regular lattice over the object's bounding box plus a
margin, the exact signed distance to the object's union of convex parts (the smallest
per-part signed distance: what pybullet reports for the same parts), computed by
:func:`kinegrasp_env.world.gridkernel.part_distances` for every object, built-in or imported.
Nodes farther than the margin from a part are given the margin (a lower bound). Queries
(:func:`kinegrasp_env.closing.capsule_gap.trilinear`) interpolate trilinearly; outside the
lattice the value at the nearest lattice point plus the distance to the lattice box is
returned (a lower bound away from the object).

Trilinear interpolation reproduces the distance exactly wherever it is linear (next to a face
of a part, inside or outside); near edges and corners it is within a fraction of the spacing.
The grids are built on first use (once: the build is slow next to a lookup) and cached on
disk, keyed by the object's
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


def grid_key(obj: GraspObject, spacing: float = SPACING, margin: float = MARGIN) -> str:
    """Hex key of a grid: the object's parts and the grid settings."""
    digest = hashlib.sha256()
    for part in obj.parts:
        digest.update(np.ascontiguousarray(part, dtype=np.float64).tobytes())
    digest.update(np.array([spacing, margin, FORMAT_VERSION], dtype=np.float64).tobytes())
    return digest.hexdigest()[:16]


def build_grid(obj: GraspObject, spacing: float = SPACING, margin: float = MARGIN,
               progress: bool = False) -> DistanceGrid:
    """Compute the grid of ``obj`` (exact distances at the nodes, :func:`node_distances`).

    The lattice covers the mesh's bounding box, widened where a part reaches beyond it by
    more than :data:`BEYOND` (an imported object's hulls may).
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
        dist = node_distances(part, grid, block.reshape(-1))
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


def node_distances(part: ConvexPart, nodes: np.ndarray, current: np.ndarray) -> np.ndarray:
    """Signed distances (n,) of nodes (n, 3) to ``part`` (metres), or ``current`` (n,) where
    the part's plane bound shows the distance is not smaller (see
    :mod:`kinegrasp_env.world.gridkernel`)."""
    return part_distances(np.ascontiguousarray(nodes, dtype=np.float64), part.planes,
                          part.edges, INSIDE_TOL * part.scale,
                          np.ascontiguousarray(current, dtype=np.float64))


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
