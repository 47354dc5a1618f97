"""What every engine of a robot shares: the outcome of a closing
(:func:`outcome_of`), the scoring of closings with the robot's contact model (:func:`score`:
per-draw results as a :class:`~kinegrasp_env.montecarlo.draws.DrawBatch`) and the engine's
base (:class:`RobotEngine`: robot, object, quality measure, input check); the engines close
(:class:`~kinegrasp_env.montecarlo.reference_engine.RobotReferenceEngine`,
:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`,
:class:`~kinegrasp_env.montecarlo.physics_engine.RobotPhysicsEngine`).
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from kinegrasp_env.closing.close_batch import RobotCloseBatch
from kinegrasp_env.closing.close_result import RobotCloseResult
from kinegrasp_env.closing.coupled_jaws import jaw_push, jaw_speeds
from kinegrasp_env.counts import check_count
from kinegrasp_env.montecarlo.draws import (
    FORCE_CLOSURE,
    NO_FORCE_CLOSURE,
    START_COLLISION,
    DrawBatch,
    provisional_outcomes,
)
from kinegrasp_env.quality.soft_contacts import (
    FINGER_RADIUS,
    contact_quality_batch,
    soft_torsions,
)
from kinegrasp_env.quality.wrenches import (
    DEFAULT_FRICTION,
    DEFAULT_NUM_EDGES,
    check_parameters,
)
from kinegrasp_env.robot.catalog import as_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.threads import single_blas_thread
from kinegrasp_env.world.objects import load_object


def check_errors(n: int, palm, object_offset, friction, *,
                 static_hold: bool = False) -> dict[str, np.ndarray]:
    """The per-draw errors an engine's ``run`` is given (:meth:`RobotEngine.run`; n draws), as
    float arrays of the right shapes (ValueError otherwise: a bad shape, a non-finite entry, a
    negative mu, or a per-draw mu for an engine running the static hold check, ``static_hold``,
    which holds at the engine's one mu)."""
    if static_hold and friction is not None:
        raise ValueError("the static hold check holds at the engine's friction; a "
                         "per-draw friction is not checked (drop it or the check)")
    out = {}
    for name, value, shape in (("palm", palm, (n, 4, 4)),
                               ("object_offset", object_offset, (n, 4, 4)),
                               ("friction", friction, (n,))):
        if value is None:
            continue
        arr = np.asarray(value, dtype=float)
        if arr.shape != shape:
            raise ValueError(f"{name} must have shape {shape} (one per draw), got {arr.shape}")
        if not np.all(np.isfinite(arr)):
            raise ValueError(f"{name} has NaN or infinite entries")
        out[name] = arr
    if "friction" in out and np.any(out["friction"] < 0):
        raise ValueError(f"friction must be >= 0, got {float(out['friction'].min()):g}")
    return out


def outcome_of(result: RobotCloseResult) -> int:
    """The provisional outcome of one closing (:func:`provisional_outcomes`)."""
    missed = np.array([result.missed], dtype=bool).reshape(1, -1)
    return int(provisional_outcomes(np.array([result.start_collision]), missed,
                                    np.array([len(result.contacts)]))[0])


def score_batch(batch: RobotCloseBatch, max_contacts: int, quality,
                friction: np.ndarray | None = None, hand_joints: int = 0) -> DrawBatch:
    """Per-draw results of closings: each one's outcome (:func:`provisional_outcomes`), its
    contacts (at most ``max_contacts``, in the batch's order) and, for a candidate, Q by
    ``quality(points, normals, mu)`` (force closure where Q > 0): points and normals
    (B, k, 3) of every candidate with k contacts at once, their draws' mu (B,) from
    ``friction`` (n,) (None: the engine's), Q (B,); ``quality`` None leaves the candidates
    unscored (outcome ``no_force_closure``, Q 0) for the caller; ``hand_joints`` columns of
    the closed hand, left for the caller (NaN). Every engine of a description robot scores
    its closings here."""
    n = len(batch)
    out = DrawBatch.empty(n, max_contacts, hand_joints)
    counts = batch.contact_counts
    out.outcome[:] = provisional_outcomes(batch.start_collision, batch.missed, counts)
    out.n_contacts[:] = np.minimum(counts, max_contacts)
    slot = batch.slot
    keep = slot < max_contacts
    row, slot = batch.row[keep], slot[keep]
    out.points[row, slot], out.normals[row, slot] = batch.points[keep], batch.normals[keep]
    out.finger[row, slot], out.link[row, slot] = batch.finger[keep], batch.link[keep]
    if quality is not None:  # else the caller scores the candidates
        score_candidates(out, quality, friction)
    return out


def score_candidates(draws: DrawBatch, quality, friction: np.ndarray | None = None) -> None:
    """Q of every candidate of ``draws`` (outcome ``no_force_closure``) by ``quality(points,
    normals, mu)`` (the candidates with k contacts at once: points and normals (B, k, 3),
    their mu (B,) from ``friction`` (n,), None: the engine's) and force closure where Q > 0,
    in place."""
    candidate = draws.outcome == NO_FORCE_CLOSURE
    for k in np.unique(draws.n_contacts[candidate]):
        rows = np.flatnonzero(candidate & (draws.n_contacts == k))
        draws.quality[rows] = quality(draws.points[rows, :k], draws.normals[rows, :k],
                                      None if friction is None else friction[rows])
    draws.outcome[candidate & (draws.quality > 0)] = FORCE_CLOSURE


def score(results: list[RobotCloseResult], max_contacts: int, quality) -> DrawBatch:
    """:func:`score_batch` of closings given one by one."""
    return score_batch(RobotCloseBatch.of_results(results), max_contacts, quality)


class RobotEngine:
    """What every engine of a description robot shares: the robot, the object, the quality
    measure, the input check and the scoring; a subclass closes (:meth:`close_all`).

    Args:
        robot: a catalog name or a loaded description.
        object_name: catalog object.
        friction, num_edges: friction cone of the quality measure.
        finger_radius: soft contacts' patch radius (metres).
        static_hold: also run the static hold check on every closing that touches
            (:class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck`).
        max_contacts: contacts kept and scored per draw, in the closing's order (default:
            one per finger link, every contact a closing can make).
    """

    name = ""

    def __init__(self, robot: str | RobotDescription, object_name: str, *,
                 friction: float = DEFAULT_FRICTION, num_edges: int = DEFAULT_NUM_EDGES,
                 finger_radius: float = FINGER_RADIUS, static_hold: bool = False,
                 max_contacts: int | None = None) -> None:
        friction, num_edges = check_parameters(friction, num_edges)  # before any closing
        if not (isinstance(finger_radius, (int, float)) and 0 < finger_radius < 1):
            raise ValueError(f"finger_radius must be a length in (0, 1) metres, got "
                             f"{finger_radius!r}")
        if max_contacts is not None:
            check_count(max_contacts, "max_contacts")
        self.description = as_description(robot)
        self.obj = load_object(object_name)
        self.friction, self.num_edges = friction, num_edges
        self.finger_radius = float(finger_radius)
        self.max_contacts = (self.all_contacts() if max_contacts is None
                             else int(max_contacts))
        self.jaw_speeds = jaw_speeds(self.description)
        self.patches = None
        if self.description.contact_model == "patch":
            from kinegrasp_env.montecarlo.patch_contacts import PatchContacts

            self.patches = PatchContacts(self.description, self.obj)
        self.hold_check = None
        if static_hold:
            from kinegrasp_env.montecarlo.hold_check import StaticHoldCheck

            self.hold_check = StaticHoldCheck(self.description, self.obj, friction=friction,
                                              num_edges=num_edges,
                                              finger_radius=finger_radius)

    def options(self) -> dict[str, object]:
        """The settings, beyond robot, object, friction and the static hold check, in which
        this engine differs from the defaults (``make_engine(name, robot, object,
        **options())`` builds it again: what a run in chunks gives its workers)."""
        given = {"num_edges": (self.num_edges, DEFAULT_NUM_EDGES),
                 "finger_radius": (self.finger_radius, FINGER_RADIUS),
                 "max_contacts": (self.max_contacts, self.all_contacts())}
        return {key: value for key, (value, default) in given.items() if value != default}

    def all_contacts(self) -> int:
        """The default ``max_contacts``: one per finger link, every contact a closing can
        make."""
        return len(self.description.finger_links)

    @cached_property
    def in_table(self):
        """The robot's table test on the engine's object
        (:class:`~kinegrasp_env.closing.table_check.RobotTableCheck`: ``in_table(q)``, (n,)
        bool), built on first use: what a simulation of the hand alone (the arm not
        simulated) takes as start collisions."""
        from kinegrasp_env.closing.table_check import RobotTableCheck

        return RobotTableCheck(self.description, self.obj)

    def close(self) -> None:
        """Release what the engine holds (nothing by default)."""

    def __enter__(self) -> RobotEngine:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def check(self, q: np.ndarray) -> np.ndarray:
        """q as a finite (n, dof) float array; ValueError otherwise."""
        dof = self.description.model.dof
        q = np.atleast_2d(np.asarray(q, dtype=float))
        if q.ndim != 2 or q.shape[1] != dof:
            raise ValueError(f"configurations of robot {self.description.name!r} must have "
                             f"shape (n, {dof}), got {q.shape}")
        bad = ~np.isfinite(q)
        if bad.any():
            draw, joint = (int(i) for i in np.argwhere(bad)[0])
            raise ValueError(f"configuration {draw} is not finite: joint {joint} = "
                             f"{q[draw, joint]} ({int(bad.any(axis=1).sum())} of {q.shape[0]} "
                             "configurations have NaN or infinite entries)")
        return q

    def quality(self, points: np.ndarray, normals: np.ndarray,
                friction: np.ndarray | None = None, soft: np.ndarray | None = None
                ) -> np.ndarray:
        """(B,) Q of B contact sets (B, k, 3) with the robot's contact model, each set at its
        own mu ``friction`` (B,) (None: the engine's); the patch model's sets: ``soft`` (B, k)
        marks its soft contacts, the others are point contacts (the patches' corners:
        :meth:`~kinegrasp_env.montecarlo.patch_contacts.PatchContacts.expand`), and without
        ``soft`` every contact is a point contact."""
        model = self.description.quality_model
        if self.patches is not None and soft is None:  # corners alone: point contacts
            model = "point"
        options = {"contact_model": model, "num_edges": self.num_edges,
                   "torque_scale": self.obj.torque_scale, "center": self.obj.center_of_mass,
                   **({"finger_radius": self.finger_radius} if model == "soft" else {})}

        def torsion(mu: float) -> dict:
            if soft is None:
                return {}
            return {"torsion": soft_torsions(soft, mu, self.finger_radius)}

        if friction is None:
            return contact_quality_batch(points, normals, friction=self.friction,
                                         **options, **torsion(self.friction))
        if model == "point":  # the point model takes one mu per set
            return contact_quality_batch(points, normals, friction=friction, **options)
        out = np.empty(len(friction))
        for mu in np.unique(friction):  # the soft model: the sets of one mu at a time
            rows = np.flatnonzero(friction == mu)
            chosen = {k: v[rows] for k, v in torsion(float(mu)).items()}
            out[rows] = contact_quality_batch(points[rows], normals[rows], friction=float(mu),
                                              **options, **chosen)
        return out

    def close_all(self, q: np.ndarray) -> list[RobotCloseResult]:
        """One closing per configuration of q (n, dof) (checked)."""
        raise NotImplementedError

    def close_batch(self, q: np.ndarray, **errors: np.ndarray) -> RobotCloseBatch:
        """The closings of q (n, dof) (checked) as arrays (default: :meth:`close_all`'s);
        ``errors``: per-draw ``palm`` and ``object_offset`` (n, 4, 4), for an engine that
        :attr:`takes_errors`."""
        return RobotCloseBatch.of_results(self.close_all(q, **errors))

    #: Whether :meth:`run` takes palm and object pose errors (the kinematic engines do).
    takes_errors = False

    def run(self, q: np.ndarray, *, palm: np.ndarray | None = None,
            object_offset: np.ndarray | None = None,
            friction: np.ndarray | None = None) -> DrawBatch:
        """Outcomes of configurations q (n, dof) (arm noisy, hand at its pre-shape), with
        the static hold check where the engine was asked for it.

        Per-draw errors (None: exact; :mod:`~kinegrasp_env.closing.hand_errors`):
            palm: (n, 4, 4) the hand's error relative to the flange (flange frame).
            object_offset: (n, 4, 4) the object's true pose in the frame it was believed
                at; the contacts are in the true object's frame.
            friction: (n,) each draw's mu (instead of the engine's).

        Raises:
            ValueError: bad configurations or errors; pose or friction errors for an engine
                that does not take them; a per-draw mu with the static hold check (it holds
                at one mu).
        """
        q = self.check(q)
        errors = check_errors(q.shape[0], palm, object_offset, friction,
                              static_hold=self.hold_check is not None)
        if errors and not self.takes_errors:
            raise ValueError(f"the {self.name} engine takes joint and hand noise only, not "
                             f"{', '.join(errors)} errors")
        mu = errors.pop("friction", None)
        with single_blas_thread():  # tiny matrices: a second BLAS thread only spins
            return self.scored(q, self.close_batch(q, **errors), mu)

    def starts_in_collision(self, q: np.ndarray) -> np.ndarray:
        """(n,) bool: the closing of each configuration q (n, dof), without errors, starts
        in collision (outcome ``start_collision``: a link in the object or its table); an
        engine that can tell without closing says so sooner."""
        return self.run(q).outcome == START_COLLISION

    def scored(self, q: np.ndarray, batch: RobotCloseBatch,
               friction: np.ndarray | None = None) -> DrawBatch:
        """:meth:`run`'s results of the closings ``batch`` of checked configurations q
        (n, dof), each draw at its mu ``friction`` (n,) (None: the engine's): for a caller
        that needs the closings too (their final joint values)."""
        draws = score_batch(batch, self.max_contacts,
                            None if self.patches is not None else self.quality, friction,
                            len(self.description.hand_joints))
        self._closed_hand(q, batch, draws)
        contacts = None
        if self.patches is not None:
            contacts = self._score_patches(q, batch, draws, friction)
        if self.jaw_speeds is not None and len(batch):
            draws.push[:] = jaw_push(self.jaw_speeds, batch.travel, batch.missed,
                                     batch.start_collision)
        if self.hold_check is not None:
            touched = np.flatnonzero((draws.outcome == NO_FORCE_CLOSURE)
                                     | (draws.outcome == FORCE_CLOSURE))
            if touched.size:
                values = {name: v[touched] for name, v in batch.joints.items()}
                points, normals, finger, link, soft = contacts or (
                    draws.points, draws.normals, draws.finger, draws.link, None)
                draws.held[touched] = self.hold_check.held(
                    q[touched], values, points[touched], normals[touched], finger[touched],
                    link[touched], soft=None if soft is None else soft[touched])
        return draws

    def _closed_hand(self, q: np.ndarray, batch: RobotCloseBatch, draws: DrawBatch) -> None:
        """Fill ``draws.hand``: each actuated hand joint of q (n, dof) where the closing
        left it (its final value), a pre-shape joint the closing does not move as it was,
        NaN after a start collision."""
        arm = self.description.arm_dof
        draws.hand[:] = q[:, arm:]
        for j, name in enumerate(self.description.hand_joints):
            if name in batch.joints:
                draws.hand[:, j] = batch.joints[name]
        draws.hand[np.asarray(batch.start_collision, dtype=bool)] = np.nan

    def _score_patches(self, q: np.ndarray, batch: RobotCloseBatch, draws: DrawBatch,
                       friction: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
        """Q and force closure of the candidates of ``draws`` with the patch model; returns
        every draw's contacts expanded to their patches' corners ((n, k C, 3) points and
        normals, (n, k C) finger, link and soft: :meth:`~kinegrasp_env.montecarlo.
        patch_contacts.PatchContacts.expand`)."""
        from kinegrasp_env.montecarlo.patch_contacts import distinct_slots

        expanded = self.patches.expand(q, batch.joints, draws.points, draws.normals,
                                       draws.finger, draws.link)
        points, normals, soft = expanded[0], expanded[1], expanded[4]
        keep = distinct_slots(points, soft, draws.points)
        candidate = draws.outcome == NO_FORCE_CLOSURE
        count, mixed = keep.sum(axis=1), (soft & keep).any(axis=1)
        groups = np.unique(np.column_stack([count, mixed])[candidate], axis=0)
        for size, any_soft in groups.tolist():
            rows = np.flatnonzero(candidate & (count == size) & (mixed == any_soft))
            cols = np.nonzero(keep[rows])[1].reshape(rows.size, size)
            at = rows[:, None], cols
            draws.quality[rows] = self.quality(
                points[at], normals[at], None if friction is None else friction[rows],
                soft[at] if any_soft else None)
        draws.outcome[candidate & (draws.quality > 0)] = FORCE_CLOSURE
        return expanded
