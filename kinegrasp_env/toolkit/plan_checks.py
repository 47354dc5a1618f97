"""What every grasp planner shares: its settings (:class:`PlannerSettings`), the arm's
clearance from the object (:func:`clearance`), the check of a candidate's nominal closing
(:func:`planned_closing`), what became of its palm poses (:class:`PlanTally`) and what a
planned grasp records of its arm (:func:`arm_meta`)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.closing.generic_reference import QUERY_DISTANCE
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, DrawBatch
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.palm_ik import IK_ITERATIONS, IK_RESTARTS
from kinegrasp_env.wording import plural

__all__ = ["ATTEMPTS_PER_GRASP", "PlanTally", "PlannerSettings", "arm_meta", "attempts_for",
           "clearance", "planned_closing", "self_motion"]

#: Palm poses a planner tries per grasp asked for, by default (at least the settings' own).
ATTEMPTS_PER_GRASP = 50


@dataclass(frozen=True)
class PlannerSettings:
    """Planner settings (angles in radians, lengths in metres)."""

    surface_samples: int = 400
    max_normal_angle: float = 0.25
    width_margin: float = 0.005
    max_depth: float = 0.025
    min_downward: float = 0.5
    min_clearance: float = 0.005
    attempts: int = 200
    ik_restarts: int = IK_RESTARTS
    ik_iterations: int = IK_ITERATIONS


#: Why a planner dropped a palm pose, in the order a pose meets the checks.
DROPPED = ("facing up", "out of reach", "arm too close", "not in force closure",
           "in the table")


@dataclass
class PlanTally:
    """What became of a plan's palm poses: ``drawn`` of them, ``dropped`` by reason (a
    :data:`DROPPED` reason -> count), ``kept`` as grasps; poses left when enough grasps were
    found (or the time budget was spent) are in none of them."""

    drawn: int = 0
    dropped: Counter = field(default_factory=Counter)
    kept: int = 0

    def summary(self) -> str:
        """One line: ``200 palm poses: 180 out of reach, 20 not in force closure``; poses
        left unchecked (enough grasps found, or the time budget spent) counted as not tried."""
        counts = [f"{self.dropped[r]} {r}" for r in DROPPED if self.dropped[r]]
        counts += [f"{self.kept} kept"] if self.kept else []
        untried = self.drawn - sum(self.dropped.values()) - self.kept
        counts += [f"{untried} not tried"] if untried else []
        return plural(self.drawn, "palm pose") + (": " + ", ".join(counts) if counts else "")


def attempts_for(count: int) -> int:
    """The palm poses to try for ``count`` grasps by default: :data:`ATTEMPTS_PER_GRASP`
    each, at least :class:`PlannerSettings`' ``attempts``."""
    return max(PlannerSettings.attempts, ATTEMPTS_PER_GRASP * int(count))


def clearance(engine: RobotReferenceEngine, q: np.ndarray) -> float:
    """Smallest distance (metres) from the object of the robot's links other than the
    fingers at configuration q (dof,) (pybullet; capped at the query distance)."""
    world = engine.world
    world.set_configuration(q)
    fingers = {world.link_index[link] for link in engine.description.finger_links}
    rows = [r for r in world.closest(QUERY_DISTANCE) if r[3] not in fingers]
    return min((world.distance(r) for r in rows), default=QUERY_DISTANCE)


def self_motion(description: RobotDescription, kin=None):
    """The description's :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion` (on
    ``kin``, its kinematics, when given) for a 7-joint arm with an elbow angle, else None."""
    if not description.has_self_motion:
        return None
    from kinegrasp_env.robot.null_motion import ArmSelfMotion

    return ArmSelfMotion(description, kin)


def arm_meta(motion, q: np.ndarray) -> dict:
    """What a grasp at configuration q (dof,) records of its arm: ``elbow_angle`` (radians)
    by ``motion`` (:func:`self_motion`: the arm's, None for an arm without an elbow angle),
    its grasp file's ``elbow``, which moves a palm pose's IK solution back to this
    configuration; nothing for an arm without one."""
    if motion is None:
        return {}
    return {"elbow_angle": float(motion.elbow_angle(q[None])[0])}


def planned_closing(engine: RobotReferenceEngine, q0: np.ndarray,
                    settings: PlannerSettings, tally: PlanTally | None = None
                    ) -> DrawBatch | None:
    """The nominal closing (one draw) of configuration q0 (dof,) when the planners keep it:
    every robot link but the fingers ``settings.min_clearance`` from the object
    (:func:`clearance`), in force closure, the closed hand out of the object's support
    table; else None, the reason counted in ``tally``. The engine's world is left with the
    hand closed."""
    reason = None
    draws = None
    if clearance(engine, q0) < settings.min_clearance:
        reason = "arm too close"
    else:
        draws = engine.run(q0[None])
        if draws.outcome[0] != FORCE_CLOSURE:
            reason = "not in force closure"
        elif engine.world.in_table():
            reason = "in the table"
    if tally is not None:
        if reason is None:
            tally.kept += 1
        else:
            tally.dropped[reason] += 1
    return None if reason is not None else draws
