"""An object's convex parts packed as flat arrays for the exact segment search
(:mod:`kinegrasp_env.closing.segment_distance`): planes, edges (in blocks of nearby edges),
the faces each edge bounds, and bounding spheres of parts and blocks.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from itertools import pairwise

import numpy as np

from kinegrasp_env.world.objects import GraspObject, load_object
from kinegrasp_env.world.polytope import INSIDE_TOL, ConvexPart

#: An edge bounds a face when both its ends lie within this of the face's plane (metres).
FACE_RESIDUAL = 1e-12
#: Largest number of edges in a block: each part's edges are ordered so that blocks of
#: nearby edges are consecutive, and a block whose bounding sphere cannot beat the best
#: distance is skipped whole (the spray flask's 48-gon prisms have 144 edges a part).
BLOCK_EDGES = 4
#: Edges whose plane residuals are computed at once (a (rows, P) array each time).
EDGE_ROWS = 256


@dataclass(frozen=True, eq=False)
class PackedGeometry:
    """An object's parts as flat arrays for the kernel.

    Attributes:
        planes: (P, 4) all parts' planes (unit normals); plane_start: (n_parts + 1,) offsets.
        edges: (E, 2, 3) all parts' edges; edge_start: (n_parts + 1,) offsets.
        scale: (n_parts,) part sizes (tolerance of the on-face test).
        edge_mid: (E, 3) edge midpoints; edge_half: (E,) half lengths (bounding spheres).
        edge_faces: (E, 2) int64 rows of ``planes`` of the two faces each edge bounds (-1
            where no plane of its part holds both its ends within ``FACE_RESIDUAL``).
        part_center: (n_parts, 3), part_radius: (n_parts,): a sphere holding each part
            (centre: the mean of its edges' end points; radius: the farthest of them).
        block_start: (n_parts + 1,) int64 offsets of each part's edge blocks;
            block_edge: (n_blocks + 1,) int64 offsets of each block's edges (a part's edges
            are ordered by :func:`spatial_blocks`); block_center (n_blocks, 3),
            block_radius (n_blocks,): a sphere holding each block's edges.
    """

    planes: np.ndarray
    plane_start: np.ndarray
    edges: np.ndarray
    edge_start: np.ndarray
    scale: np.ndarray
    edge_mid: np.ndarray
    edge_half: np.ndarray
    edge_faces: np.ndarray
    part_center: np.ndarray
    part_radius: np.ndarray
    block_start: np.ndarray
    block_edge: np.ndarray
    block_center: np.ndarray
    block_radius: np.ndarray


def _two_smallest(values: np.ndarray) -> np.ndarray:
    """(E, min(P, 2)) int64: per row of values (E, P) the columns of its two smallest, as
    ``np.argsort(values, axis=1, kind="stable")[:, :2]`` gives them (ties by column, NaN
    last), in O(P) a row where no third value ties the second and the second is a number."""
    if values.shape[1] <= 2:
        return np.argsort(values, axis=1, kind="stable")[:, :2]
    pair = np.argpartition(values, 1, axis=1)[:, :2]
    low = np.take_along_axis(values, pair, axis=1)
    swap = (low[:, 1] < low[:, 0]) | ((low[:, 1] == low[:, 0]) & (pair[:, 1] < pair[:, 0]))
    pair[swap] = pair[swap][:, ::-1]
    second = np.take_along_axis(values, pair[:, 1:], axis=1)
    crowded = ((values <= second).sum(axis=1) > 2) | np.isnan(second[:, 0])
    if crowded.any():  # ties for second place: the stable sort's choice
        pair[crowded] = np.argsort(values[crowded], axis=1, kind="stable")[:, :2]
    return pair


def edge_faces(planes: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """(E, 2) int64: for each edge (E, 2, 3) the two planes (P, 4) nearest to both its ends,
    -1 where that is above ``FACE_RESIDUAL`` (metres)."""
    out = np.empty((len(edges), 2), dtype=np.int64)
    for first in range(0, len(edges), EDGE_ROWS):  # (rows, P) at a time: bounded memory
        rows = edges[first:first + EDGE_ROWS]
        residual = np.abs(rows @ planes[:, :3].T + planes[:, 3]).max(axis=1)
        nearest = _two_smallest(residual)
        close = np.take_along_axis(residual, nearest, axis=1) < FACE_RESIDUAL
        out[first:first + EDGE_ROWS] = np.where(close, nearest, -1)
    return out


def spatial_blocks(mid: np.ndarray, size: int = BLOCK_EDGES) -> list[np.ndarray]:
    """Indices of points mid (E, 3) in blocks of at most ``size`` nearby points: halved at
    the median of the widest coordinate until small enough (a k-d tree's leaves, in order)."""
    todo, leaves = [np.arange(len(mid))], []
    while todo:
        idx = todo.pop()
        if len(idx) <= size:
            leaves.append(idx)
            continue
        axis = int(np.argmax(np.ptp(mid[idx], axis=0)))
        idx = idx[np.argsort(mid[idx, axis], kind="stable")]
        todo += [idx[len(idx) // 2:], idx[:len(idx) // 2]]  # the lower half next
    return leaves


def pack_each(parts) -> tuple[tuple, ...]:
    """Each convex part packed as one part (its :func:`parts_tuple`): the hulls, one at a
    time, that the exact segment search of :mod:`~kinegrasp_env.closing.hull_edges` reads."""
    return tuple(parts_tuple(pack_parts([part])) for part in parts)


def pack(obj: GraspObject) -> PackedGeometry:
    """An object's convex parts packed (:func:`pack_parts`)."""
    return pack_parts(obj.convex_parts)


def pack_parts(parts: tuple[ConvexPart, ...] | list[ConvexPart]) -> PackedGeometry:
    """Convex parts (an object's, or a link's hulls, in their own frame) packed for the
    exact segment search."""
    planes = np.ascontiguousarray(np.vstack([p.planes for p in parts]), dtype=float)
    plane_start = np.concatenate([[0], np.cumsum([len(p.planes) for p in parts])]
                                 ).astype(np.int64)
    part_edges, faces, blocks = [], [], []
    for part, first in zip(parts, plane_start[:-1], strict=True):
        leaves = spatial_blocks(part.edges.mean(axis=1)) if len(part.edges) else []
        ordered = part.edges[np.concatenate(leaves)] if leaves else part.edges
        part_edges.append(ordered)
        found = edge_faces(part.planes, ordered)
        faces.append(np.where(found >= 0, found + first, -1))
        blocks.append([len(leaf) for leaf in leaves])
    edges = np.concatenate(part_edges)
    edge_start = np.cumsum([0] + [len(e) for e in part_edges])
    corners = [p.edges.reshape(-1, 3) for p in parts]
    center = np.array([c.mean(axis=0) for c in corners])
    radius = np.array([np.linalg.norm(c - m, axis=1).max()
                       for c, m in zip(corners, center, strict=True)])
    block_edge = np.cumsum([0] + [n for part in blocks for n in part])
    block_start = np.cumsum([0] + [len(part) for part in blocks])
    ends = [edges[a:b].reshape(-1, 3) for a, b in pairwise(block_edge)]
    block_center = np.array([0.5 * (e.min(axis=0) + e.max(axis=0)) for e in ends])
    # a sphere holding both ends of every edge of the block holds the edges (convex); the
    # relative margin covers the rounding of the distances it is compared with
    block_radius = np.array([np.linalg.norm(e - c, axis=1).max() for e, c in
                             zip(ends, block_center, strict=True)]) * (1 + 1e-9) + 1e-12
    return PackedGeometry(planes, plane_start,
                          np.ascontiguousarray(edges), edge_start.astype(np.int64),
                          np.array([p.scale for p in parts]),
                          np.ascontiguousarray(edges.mean(axis=1)),
                          0.5 * np.linalg.norm(edges[:, 1] - edges[:, 0], axis=1),
                          np.concatenate(faces).astype(np.int64), center, radius,
                          block_start.astype(np.int64), block_edge.astype(np.int64),
                          np.ascontiguousarray(block_center.reshape(-1, 3)),
                          block_radius.reshape(-1))


def packed(name: str) -> PackedGeometry:
    """The packed parts of catalog object ``name`` as it is now: an object re-imported
    under the same name is a new :class:`GraspObject` (``load_object`` keys it by its
    catalog version), so it is packed afresh."""
    return packed_object(load_object(name))


@lru_cache(maxsize=8)
def packed_object(obj: GraspObject) -> PackedGeometry:
    """:func:`pack` of ``obj``, cached per object (by identity, not by name: two objects of
    one name, before and after a re-import, never share an entry)."""
    return pack(obj)


def geometry_tuple(obj: GraspObject) -> tuple:
    """The object's packed parts as the kernels' ``geo`` tuple: planes, plane_start, edges,
    edge_start, scale, edge_mid, edge_half, edge_faces, part_center, part_radius, the
    relative on-face tolerance, block_start, block_edge, block_center, block_radius
    (:class:`PackedGeometry`)."""
    return parts_tuple(packed_object(obj))


def parts_tuple(geo: PackedGeometry) -> tuple:
    """Packed parts as the kernels' ``geo`` tuple (:func:`geometry_tuple`)."""
    return (geo.planes, geo.plane_start, geo.edges, geo.edge_start, geo.scale, geo.edge_mid,
            geo.edge_half, geo.edge_faces, geo.part_center, geo.part_radius, INSIDE_TOL,
            geo.block_start, geo.block_edge, geo.block_center, geo.block_radius)
