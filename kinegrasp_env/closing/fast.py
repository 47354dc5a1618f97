"""Batched GraspIt auto-close against an object's distance grid (the fast engine).

The same rule as :mod:`kinegrasp_env.closing.reference` (same constants, same state machine
per finger: conservative steps of at least ``STEP``, bisection to ``CONTACT_TOL``, a proximal
contact freezes the proximal joint, a distal contact ends the finger), run for all fingers of all
draws at once: the three fingers of a draw never interact, so every (draw, finger) pair is
an independent closing problem and one iteration advances all of them with array operations
(``closing="vectorized"``, :mod:`kinegrasp_env.closing.close_vectorized`). By default
(``closing="compiled"``) each problem's whole loop runs in one numba call instead
(:mod:`kinegrasp_env.closing.close_kernel`, bit-identical; the array form pays a fixed cost per
iteration that dominates small batches).
Distances come from the object's :class:`~kinegrasp_env.world.sdf.DistanceGrid` instead of
pybullet, and within ``GRID_EXACT_BAND`` of contact from the exact capsule-object distance, as in
the reference engine; the finger links are the URDF's capsules, the palm and knuckles its
cylinders (sampled on their surface, to ``CYLINDER_SPACING``).

Contacts are computed as in the reference engine, exactly, from the touching capsule's axis
(:func:`kinegrasp_env.closing.hand_geometry.capsule_contacts`).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.capsule_gap import capsule_gaps, grid_arrays, screened_hits
from kinegrasp_env.closing.close_kernel import (
    PAIR_SIZE,
    close_all,
    closing_rules,
    geometry_args,
    grid_args,
)
from kinegrasp_env.closing.close_vectorized import close_problems
from kinegrasp_env.closing.finger_axes import finger_axes
from kinegrasp_env.closing.hand_geometry import Shape, hand_shapes, pair_contacts
from kinegrasp_env.closing.reference import START_TOL, closing_speeds
from kinegrasp_env.closing.segment_distance import closest_to_segments
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.model import FINGERS, HAND_JOINTS, kuka_sdh
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sdf import DistanceGrid

#: Spacing of the sample points on the palm and knuckle cylinders (metres), of the
#: coarse pass that decides whether the fine one is needed, and of the screen that decides
#: whether the coarse one is (each pass's samples lie within its spacing of any surface
#: point, and the distance is 1-Lipschitz: a pass can only send on what a finer one could
#: flag).
CYLINDER_SPACING = 2e-3
COARSE_SPACING = 1.2e-2
SCREEN_SPACING = 3e-2
#: Capsule gaps within +-this (metres) are computed exactly: above the grid's largest
#: measured error (0.35 mm), so every decision near contact is the exact one.
GRID_EXACT_BAND = 1e-3
#: Implementations of the closing loop.
CLOSINGS = ("compiled", "vectorized")


@dataclass
class BatchClose:
    """Auto-close results of n draws.

    Attributes:
        start_collision: (n,) bool.
        missed: (n, 3) bool per finger.
        found: (n, 3, 2) bool: a contact on (finger, link).
        points, normals: (n, 3, 2, 3) contacts in the object frame (valid where found).
        flexion: (n, 3, 2) closed (proximal, distal) flexion of each finger, radians (NaN
            for start collisions: the hand did not close).
        iterations: closing iterations used.
    """

    start_collision: np.ndarray
    missed: np.ndarray
    found: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    flexion: np.ndarray
    iterations: int = 0


class FastHand:
    """Batched auto-close of the hand against one object.

    Args:
        obj: the object (placed at ``obj.pose``).
        grid: its distance grid.
        closing: ``compiled`` (the whole closing loop in one compiled call,
            :mod:`kinegrasp_env.closing.close_kernel`) or ``vectorized`` (one array-operation
            iteration at a time); the same results.

    Attributes:
        cylinders: the palm and knuckle cylinders (:class:`~kinegrasp_env.closing.
            hand_geometry.Shape`); capsules: per finger its (proximal, distal) capsules.
        flexion_columns: the six flexion joints' columns of a configuration (14,) (per
            finger proximal, distal).
    """

    def __init__(self, obj: GraspObject, grid: DistanceGrid, closing: str = "compiled"
                 ) -> None:
        if closing not in CLOSINGS:
            raise ValueError(f"unknown closing {closing!r}; choose from {', '.join(CLOSINGS)}")
        self.obj = obj
        self.grid = grid
        self.closing = closing
        self.model = kuka_sdh()
        self.kin = Kinematics(self.model)
        shapes = {s.link: s for s in hand_shapes()}
        self.capsules = [[shapes[f[2]], shapes[f[3]]] for f in FINGERS]
        self.cylinders = [s for s in hand_shapes() if s.kind == "cylinder"]
        self.samples = [(s.surface_samples(SCREEN_SPACING), s.surface_samples(COARSE_SPACING),
                         s.surface_samples(CYLINDER_SPACING)) for s in self.cylinders]
        # the same, stacked for the compiled check: samples, where cylinder s's samples at
        # spacing t start (starts[s, t]; its finest end at starts[s, 3]), and the three
        # thresholds (see cylinder_collision)
        stacked = [block for blocks in self.samples for block in blocks]
        offsets = np.cumsum([0] + [len(block) for block in stacked])
        starts = np.array([offsets[3 * s:3 * s + 4] for s in range(len(self.cylinders))],
                          dtype=np.int64)
        self._screen = (np.ascontiguousarray(np.vstack(stacked), dtype=float), starts,
                        np.array([COARSE_SPACING - START_TOL + SCREEN_SPACING,
                                  COARSE_SPACING - START_TOL, -START_TOL]))
        self.axis_p = [self.model.joint(f[0]).axis for f in FINGERS]
        self.axis_d = [self.model.joint(f[1]).axis for f in FINGERS]
        self.distal_origin = [self.model.joint(f[1]).origin for f in FINGERS]
        self.axis_ends = [tuple(np.array(shape.axis_points()) for shape in pair)
                          for pair in self.capsules]
        self.upper = np.array([[self.model.joint(f[0]).upper, self.model.joint(f[1]).upper]
                               for f in FINGERS])
        self.speed = closing_speeds()
        self.flexion_columns = self.model.index([j for f in FINGERS for j in f[:2]])
        if closing == "compiled":
            # the kernel's fixed arguments: grid, object, rules, then (after the per-call
            # frames and flexions) the finger constants stacked over fingers
            self._kernel_head = (grid_args(grid, GRID_EXACT_BAND), geometry_args(obj),
                                 closing_rules())
            self._kernel_fingers = (
                np.array(self.axis_p, dtype=float), np.array(self.axis_d, dtype=float),
                np.array(self.distal_origin, dtype=float),
                np.array([ends[0] for ends in self.axis_ends], dtype=float),
                np.array([ends[1] for ends in self.axis_ends], dtype=float),
                np.array([[c.radius for c in pair] for pair in self.capsules]), self.upper,
                np.tile(np.array(self.speed, dtype=float), (len(FINGERS), 1)))

    def with_refine_steps(self, steps: int) -> FastHand:
        """This hand (a shallow copy) with its compiled closing refining each grid gap by
        ``steps`` golden-section steps instead of
        :data:`~kinegrasp_env.closing.capsule_gap.REFINE`: what the refinement costs and
        changes (``benchmarks/bench_refine.py``). Only for ``closing="compiled"``."""
        if self.closing != "compiled":
            raise ValueError(f"refine steps apply to the compiled closing, not {self.closing!r}")
        if isinstance(steps, bool) or int(steps) != steps or steps < 1:
            raise ValueError(f"refine steps must be an integer >= 1, got {steps!r}")
        twin = copy.copy(self)
        twin._kernel_head = (grid_args(self.grid, GRID_EXACT_BAND, int(steps)),
                             *self._kernel_head[1:])
        return twin

    # ------------------------------------------------------------------ geometry
    def frames(self, q: np.ndarray, links: list[str],
                to_object: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Object-frame poses (n, 4, 4) of links (by name) at configurations q (n, 14);
        ``to_object`` (n, 4, 4) maps each draw's world poses to the object frame (default: the
        inverse of the object's pose): link name -> poses, what :meth:`cylinder_collision`
        takes."""
        world = self.kin.forward(q, links)
        left = self.obj.pose_inverse if to_object is None else to_object
        return {name: left @ pose for name, pose in world.items()}

    def grid_or_exact_gaps(self, a: np.ndarray, b: np.ndarray, radius: float | np.ndarray
                           ) -> np.ndarray:
        """Gaps (m,) of capsules with axis ends a, b (m, 3) and radius (a float, or (m,)
        metres): exact within ``GRID_EXACT_BAND`` of contact, from the grid elsewhere."""
        radius = np.broadcast_to(np.asarray(radius, dtype=float), (len(a),))
        gap, _ = capsule_gaps(self.grid, a, b, radius)
        near = np.flatnonzero(np.abs(gap) <= GRID_EXACT_BAND)
        if near.size:
            gap[near] = closest_to_segments(self.obj, a[near], b[near])[2] - radius[near]
        return gap

    def _capsule_collision(self, frames: dict[str, np.ndarray]) -> np.ndarray:
        """(n,) True where a finger link's capsule penetrates more than START_TOL (the six
        capsules' gaps in one call)."""
        shapes = [shape for pair in self.capsules for shape in pair]
        ends = [capsule_axis(frames[shape.link], shape) for shape in shapes]
        n = len(ends[0][0])
        radius = np.repeat([shape.radius for shape in shapes], n)
        gap = self.grid_or_exact_gaps(np.concatenate([e[0] for e in ends]),
                                      np.concatenate([e[1] for e in ends]), radius)
        return (gap.reshape(len(shapes), n) < -START_TOL).any(axis=0)

    def cylinder_collision(self, frames: dict[str, np.ndarray]) -> np.ndarray:
        """(n,) True where a palm or knuckle cylinder (``self.cylinders``) penetrates more
        than START_TOL, from :meth:`frames` of (at least) the cylinders' links.

        Every coarse sample lies within SCREEN_SPACING of a screen sample, every surface
        point within COARSE_SPACING of a coarse one (distances are 1-Lipschitz): the fine
        check runs only where the coarse one can fire, the coarse one where the screen can; the
        three passes per draw run in one compiled loop."""
        n = next(iter(frames.values())).shape[0]
        hit = np.zeros(n, dtype=bool)
        poses = np.stack([frames[shape.link] for shape in self.cylinders])
        screened_hits(*grid_arrays(self.grid), np.ascontiguousarray(poses[..., :3, :3]),
                      np.ascontiguousarray(poses[..., :3, 3]), *self._screen, hit)
        return hit

    def link_axes(self, joint_frames: np.ndarray, finger: int, prox: np.ndarray,
                  dist: np.ndarray) -> np.ndarray:
        """Axis ends (m, 4, 3) [proximal a, b, distal a, b] for flexions prox, dist (m,)."""
        ends_p, ends_d = self.axis_ends[finger]
        return finger_axes(joint_frames, self.axis_p[finger], prox, self.distal_origin[finger],
                           self.axis_d[finger], dist, ends_p, ends_d)

    # ------------------------------------------------------------------ closing
    def close(self, q: np.ndarray, to_object: np.ndarray | None = None) -> BatchClose:
        """Auto-close at configurations q (n, 14) (arm joints, then the hand pre-shape);
        ``to_object`` (n, 4, 4): per draw, the map from world to object frame (where a hand
        or object pose error puts the hand relative to the object; default: the inverse of
        the object's pose)."""
        q = np.atleast_2d(np.asarray(q, dtype=float))
        n = q.shape[0]
        finger_links = [link for f in FINGERS for link in f[2:]]
        frames = self.frames(q, [s.link for s in self.cylinders] + finger_links, to_object)
        start = self.cylinder_collision(frames) | self._capsule_collision(frames)
        out = BatchClose(start, np.zeros((n, 3), bool), np.zeros((n, 3, 2), bool),
                         np.full((n, 3, 2, 3), np.nan), np.full((n, 3, 2, 3), np.nan),
                         np.full((n, 3, 2), np.nan))
        draws = np.flatnonzero(~start)
        if draws.size == 0:
            return out
        # joint frames of the proximal joints (flexion zero): fixed while closing
        q_zero = q[draws].copy()
        q_zero[:, self.flexion_columns] = 0.0
        zero = self.frames(q_zero, [f[2] for f in FINGERS],
                            None if to_object is None else to_object[draws])
        hand = q[draws, 7:]
        joint_frames = np.ascontiguousarray(np.stack([zero[f[2]] for f in FINGERS], axis=1))
        prox0 = np.ascontiguousarray(hand[:, [HAND_JOINTS.index(f[0]) for f in FINGERS]])
        dist0 = np.ascontiguousarray(hand[:, [HAND_JOINTS.index(f[1]) for f in FINGERS]])
        if self.closing == "compiled":
            self._close_compiled(draws, joint_frames, prox0, dist0, out)
        else:
            self._close_vectorized(draws, joint_frames, prox0, dist0, out)
        return out

    def _close_compiled(self, draws: np.ndarray, joint_frames: np.ndarray, prox0: np.ndarray,
                        dist0: np.ndarray, out: BatchClose) -> None:
        """The closing loop in one compiled call, then the contacts of the closest pairs:
        draws (m,) the rows of ``out`` closed, joint_frames (m, 3, 4, 4), prox0 / dist0
        (m, 3) as :func:`~kinegrasp_env.closing.close_vectorized.close_problems` takes."""
        m = draws.size
        found = np.zeros((m, 3, 2), dtype=bool)
        pairs = np.zeros((m, 3, 2, PAIR_SIZE))
        missed = np.zeros((m, 3), dtype=bool)
        flex = np.zeros((m, 3, 2))
        out.iterations = close_all(*self._kernel_head, joint_frames, prox0, dist0,
                                        *self._kernel_fingers, found, pairs, missed, flex)
        out.missed[draws] = missed
        out.flexion[draws] = flex
        out.found[draws] = found
        hit = pairs[found]
        if len(hit):
            point, normal = pair_contacts(self.obj, hit[:, 1:4], hit[:, 4:7], hit[:, 0],
                                          hit[:, 7].astype(np.int64))
            rows, fingers, links = np.nonzero(found)
            out.points[draws[rows], fingers, links] = point
            out.normals[draws[rows], fingers, links] = normal

    def _close_vectorized(self, draws: np.ndarray, joint_frames: np.ndarray,
                          prox0: np.ndarray, dist0: np.ndarray, out: BatchClose) -> None:
        """The closing loop one array-operation iteration at a time
        (:func:`~kinegrasp_env.closing.close_vectorized.close_problems`), its results
        written to the rows draws (m,) of ``out``."""
        closed = close_problems(self, joint_frames, prox0, dist0)
        out.missed[draws] = closed.missed
        out.flexion[draws] = closed.flexion
        out.found[draws] = closed.found
        out.points[draws] = closed.points
        out.normals[draws] = closed.normals
        out.iterations = closed.iterations


def capsule_axis(frames: np.ndarray, shape: Shape) -> tuple[np.ndarray, np.ndarray]:
    """The end points (m, 3) and (m, 3) of a capsule's axis (``shape``, in its link's frame)
    placed by link frames (m, 4, 4) (:meth:`FastHand.frames`)."""
    a_local, b_local = shape.axis_points()
    rot, trans = frames[:, :3, :3], frames[:, :3, 3]
    return rot @ a_local + trans, rot @ b_local + trans
