"""Test grasps of the Coulomb consistency benchmark and their critical friction coefficients.

A test grasp is a free rigid object (a box or a regular triangular frustum, uniform density,
its centre of mass at the origin, world frame = object frame), k point contacts (points on its
faces, unit normals pointing into the object), a normal force per contact (the force, newtons,
with which the simulated finger presses along that normal) and a disturbance wrench (force,
newtons; torque about the centre of mass, newton metres) applied to the object.

Two numbers per grasp, both from the project's quality code
(:func:`kinegrasp_env.quality.wrench_matrix`, :func:`kinegrasp_env.quality.ferrari_canny`)
with its linearized friction cone of ``m`` edges (docs/conventions.md):

* :func:`resist_mu` -- mu*: the smallest mu at which contact forces with exactly the given
  normal components, each in the m-edge cone, balance the disturbance:
  sum_i F_i wn_i + sum_ij nu_ij t_ij = -w_ext, sum_j nu_ij = mu F_i, nu >= 0, where wn_i is
  contact i's normal wrench (``wrench_matrix`` at mu = 0) and t_ij = (wrench of edge j at
  mu = 1) - wn_i its tangential part. Substituting nu_ij = mu lambda_ij makes the problem one
  linear program in (nu, mu) (SciPy's HiGHS), minimising mu: no bisection. Infinite when no mu
  will do (e.g. a torque about the axis of a two-finger pinch: point contacts have no
  torsional friction).
* :func:`closure_mu` -- mu*_FC: the smallest mu at which the contacts are in force closure
  (Ferrari-Canny Q > 0), by bisection (Q > 0 is monotone in mu for an even m: a cone edge at
  mu' < mu is a convex combination of two opposite edges at mu).

The m-edge cone is inscribed in Coulomb's circular cone: along an edge direction it reaches
mu F, midway between two edges mu F cos(pi / m). So mu* (m edges) lies between the Coulomb
value and the Coulomb value / cos(pi / m) (1.082 at m = 8); the benchmark also reports mu* at
m = 32 (within 0.5% of Coulomb's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import linprog
from scipy.spatial import ConvexHull

from kinegrasp_env.quality import ferrari_canny, wrench_matrix

#: Density of every test object, kg/m^3.
DENSITY = 500.0
#: Normal force of one finger, newtons.
FORCE = 10.0
#: Half extents of the test box, metres (x: the pinch axis).
BOX_HALF = (0.03, 0.02, 0.02)
#: Regular triangular frustum: circumradius of the bottom and top triangles and height, metres
#: (the side faces lean in by FRUSTUM_SLANT from the vertical).
FRUSTUM_HEIGHT = 0.04
FRUSTUM_SLANT = np.radians(14.0)
FRUSTUM_BOTTOM = 0.04


@dataclass(frozen=True)
class CoulombGrasp:
    """One test grasp (see the module docstring).

    Attributes:
        name: short name.
        description: what it is, in words.
        shape: ``"box"`` or ``"frustum"``.
        vertices: (v, 3) the object's vertices, metres, centre of mass at the origin.
        points: (k, 3) contact points on the faces, metres.
        normals: (k, 3) unit normals into the object.
        forces: (k,) normal force of each finger, newtons.
        wrench: (6,) disturbance: force (N) and torque about the centre of mass (N m).
    """

    name: str
    description: str
    shape: str
    vertices: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    forces: np.ndarray
    wrench: np.ndarray

    @property
    def mass(self) -> float:
        """kg (uniform density :data:`DENSITY`)."""
        return DENSITY * ConvexHull(self.vertices).volume

    @property
    def r_max(self) -> float:
        """Largest distance of a vertex from the centre of mass, metres."""
        return float(np.linalg.norm(self.vertices, axis=1).max())


def box_vertices(half: tuple[float, float, float] = BOX_HALF) -> np.ndarray:
    """(8, 3) corners of a box centred at the origin."""
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    return signs * np.asarray(half, dtype=float)


def frustum_vertices() -> np.ndarray:
    """(6, 3) vertices of the regular triangular frustum, shifted so that its centre of mass
    (of the solid, uniform density) is the origin."""
    inradius_drop = FRUSTUM_HEIGHT * np.tan(FRUSTUM_SLANT)  # inradius shrinks by this
    top = FRUSTUM_BOTTOM - 2.0 * inradius_drop  # circumradius = 2 x inradius
    angles = 2.0 * np.pi * np.arange(3) / 3.0
    ring = np.stack([np.cos(angles), np.sin(angles), np.zeros(3)], axis=1)
    bottom = ring * FRUSTUM_BOTTOM + [0.0, 0.0, -FRUSTUM_HEIGHT / 2]
    upper = ring * top + [0.0, 0.0, FRUSTUM_HEIGHT / 2]
    vertices = np.vstack([bottom, upper])
    return vertices - solid_centroid(vertices)


def solid_centroid(vertices: np.ndarray) -> np.ndarray:
    """(3,) centre of mass of the solid convex hull of ``vertices`` (v, 3), uniform density:
    tetrahedra from an interior point to each hull facet, weighted by volume."""
    hull = ConvexHull(vertices)
    inner = vertices.mean(axis=0)
    tets = vertices[hull.simplices]  # (f, 3, 3)
    volumes = np.abs(np.einsum("ij,ij->i", tets[:, 0] - inner,
                               np.cross(tets[:, 1] - inner, tets[:, 2] - inner))) / 6.0
    centres = (tets.sum(axis=1) + inner) / 4.0
    return volumes @ centres / volumes.sum()


def frustum_face_contacts(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(points (3, 3), inward normals (3, 3)): the centroids of the frustum's three side faces
    and their inward unit normals."""
    points, normals = [], []
    for i in range(3):
        j = (i + 1) % 3
        face = vertices[[i, j, 3 + j, 3 + i]]
        centre = face.mean(axis=0)
        normal = np.cross(face[1] - face[0], face[3] - face[0])
        normal /= np.linalg.norm(normal)
        if np.dot(normal, centre) > 0:  # outward -> inward
            normal = -normal
        points.append(centre)
        normals.append(normal)
    return np.array(points), np.array(normals)


def coulomb_grasps(force: float = FORCE) -> list[CoulombGrasp]:
    """The benchmark's grasps (fingers pressing with ``force`` newtons each, the box tripod's
    single finger with twice that, so the normal forces balance)."""
    box = box_vertices()
    a, b, _ = BOX_HALF
    pinch_points = np.array([[a, 0.0, 0.0], [-a, 0.0, 0.0]])
    pinch_normals = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    pair = np.full(2, force)
    mid = np.radians(22.5)  # midway between two cone edges of both contacts (m = 8)
    tripod_points = np.array([[a, b / 2, 0.0], [a, -b / 2, 0.0], [-a, 0.0, 0.0]])
    tripod_normals = np.array([[-1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    frustum = frustum_vertices()
    f_points, f_normals = frustum_face_contacts(frustum)
    triple = np.full(3, force)
    return [
        CoulombGrasp("pinch_edge", "box, 2 fingers on opposite faces, force 4 N along +y "
                  "(a cone edge direction)", "box", box, pinch_points, pinch_normals, pair,
                  np.array([0.0, 4.0, 0.0, 0.0, 0.0, 0.0])),
        CoulombGrasp("pinch_mid", "box, 2 fingers on opposite faces, force 4 N at 22.5 deg "
                  "from +z towards -y (midway between cone edges)", "box", box, pinch_points,
                  pinch_normals, pair,
                  np.array([0.0, -4.0 * np.sin(mid), 4.0 * np.cos(mid), 0.0, 0.0, 0.0])),
        CoulombGrasp("pinch_twist", "box, 2 fingers on opposite faces, torque 0.12 N m about z "
                  "(across the pinch axis)", "box", box, pinch_points, pinch_normals, pair,
                  np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.12])),
        CoulombGrasp("tripod_box", "box, 2 fingers on +x face, 1 (twice the force) on -x face, "
                  "force 3 N along +z and torque 0.05 N m about x", "box", box,
                  tripod_points, tripod_normals, np.array([force, force, 2.0 * force]),
                  np.array([0.0, 0.0, 3.0, 0.05, 0.0, 0.0])),
        CoulombGrasp("frustum_squeeze", "triangular frustum (faces 14 deg off vertical), 3 "
                  "fingers at the side faces' centres, no disturbance: the squeeze itself "
                  "pushes it out", "frustum", frustum, f_points, f_normals, triple,
                  np.zeros(6)),
        CoulombGrasp("frustum_twist", "the frustum tripod, torque 0.05 N m about the vertical "
                  "axis", "frustum", frustum, f_points, f_normals, triple,
                  np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.05])),
    ]


def resist_mu(grasp: CoulombGrasp, num_edges: int = 8) -> float:
    """mu*: the smallest friction coefficient at which the grasp's contacts, with exactly
    its normal forces, resist its disturbance (the linear program of the module docstring);
    ``inf`` when none does."""
    k, m = len(grasp.points), num_edges
    normal = wrench_matrix(grasp.points, grasp.normals, friction=0.0, num_edges=m)
    edges = wrench_matrix(grasp.points, grasp.normals, friction=1.0, num_edges=m)
    tangential = edges - normal  # (k m, 6)
    wn = normal[::m]  # (k, 6): one row per contact
    rhs = -np.asarray(grasp.wrench, dtype=float) - grasp.forces @ wn
    # variables: nu (k m) >= 0, then mu >= 0
    a_eq = np.zeros((6 + k, k * m + 1))
    a_eq[:6, :k * m] = tangential.T
    for i in range(k):
        a_eq[6 + i, i * m:(i + 1) * m] = 1.0
        a_eq[6 + i, -1] = -grasp.forces[i]
    b_eq = np.concatenate([rhs, np.zeros(k)])
    cost = np.zeros(k * m + 1)
    cost[-1] = 1.0
    res = linprog(cost, A_eq=a_eq, b_eq=b_eq, bounds=(0, None), method="highs")
    if res.status == 2:  # infeasible
        return float("inf")
    if res.status != 0:
        raise RuntimeError(f"HiGHS failed on {grasp.name}: {res.message}")
    return float(res.x[-1])


def closure_mu(grasp: CoulombGrasp, num_edges: int = 8, upper: float = 10.0,
               tol: float = 1e-9) -> float:
    """mu*_FC: the smallest mu at which the contacts are in force closure (Ferrari-Canny
    Q > 0 with ``num_edges`` edges), by bisection to ``tol``; ``inf`` when not even at
    ``upper``."""
    if num_edges % 2:
        raise ValueError(f"num_edges must be even (Q > 0 monotone in mu), got {num_edges}")

    def closed(mu: float) -> bool:
        return ferrari_canny(grasp.points, grasp.normals, friction=mu, num_edges=num_edges,
                             torque_scale=1.0 / grasp.r_max) > 0.0

    if not closed(upper):
        return float("inf")
    low, high = 0.0, upper
    while high - low > tol:
        mid = 0.5 * (low + high)
        low, high = (low, mid) if closed(mid) else (mid, high)
    return high
