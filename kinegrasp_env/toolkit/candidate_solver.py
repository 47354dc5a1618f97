"""Palm-pose candidates of any catalog robot, solved as the description robots' planner
solves its own palm poses (:mod:`kinegrasp_env.toolkit.grasp_planner`):

1. **IK**: :func:`~kinegrasp_env.robot.palm_ik.reach_robot_palm_pose` for the palm pose in
   the world frame (the object at its catalog pose), from the description's ``home`` with the
   planner's restarts and iterations
   (:class:`~kinegrasp_env.toolkit.plan_checks.PlannerSettings`), its random
   restarts seeded for each candidate (a candidate's configuration does not depend on the
   others); then, when the candidate gives ``elbow``, the self-motion to that arm angle
   (:class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`), on a further IK branch where
   the first one's self-motion leaves the joint limits before it.
2. **Clearance**: every robot link but the fingers keeps the planner's ``min_clearance``
   from the object (:func:`~kinegrasp_env.toolkit.plan_checks.clearance`).
3. **Closing**: the robot's reference engine
   (:class:`~kinegrasp_env.montecarlo.evaluate.RobotReferenceEngine`, no noise) with
   its contact model. ``start_collision`` rejects the candidate; a closing not in force
   closure (``no_force_closure`` or ``missed``) gives a grasp (Q = 0) whose
   ``meta["nominal_force_closure"]`` is False.

The planner's own sampling filters (antipodal pairs, a downward approach) are not applied: a
given palm pose is taken as it is.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES, START_COLLISION
from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
from kinegrasp_env.montecarlo.nominal import OUTCOME_DETAILS, grasp_from_draw
from kinegrasp_env.robot.catalog import as_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.robot.palm_ik import reach_robot_palm_pose
from kinegrasp_env.robot.palm_pose import PalmCandidate
from kinegrasp_env.toolkit.plan_checks import PlannerSettings, arm_meta, clearance, self_motion
from kinegrasp_env.world.grasps import Grasp


class CandidateSolver:
    """Solve palm-pose candidates of one catalog robot on one catalog object.

    Args:
        robot: a catalog robot's name or its description.
        object_name: the catalog object (built-in or imported).
        settings: the planner's settings (IK restarts and iterations, ``min_clearance``).
        friction: the closing's friction coefficient.
    """

    def __init__(self, robot: str | RobotDescription, object_name: str,
                 settings: PlannerSettings | None = None, friction: float = 0.5) -> None:
        self.description = as_description(robot)
        self.settings = settings or PlannerSettings()
        self.engine = RobotReferenceEngine(self.description, object_name, friction=friction)
        self.kin = Kinematics(self.description.model)
        self.motion = self_motion(self.description, self.kin)

    def close(self) -> None:
        self.engine.close()

    def __enter__(self) -> CandidateSolver:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def configuration(self, candidate: PalmCandidate) -> tuple[np.ndarray | None, str]:
        """(q (dof,): arm joints then the candidate's pre-shape, "") whose palm is at the
        candidate's pose (object frame, the object at its catalog pose), or (None, why)."""
        return reach_robot_palm_pose(self.kin, self.description,
                                     self.engine.obj.pose @ candidate.pose, candidate.hand,
                                     candidate.elbow, motion=self.motion,
                                     restarts=self.settings.ik_restarts,
                                     iterations=self.settings.ik_iterations)

    def solve(self, candidate: PalmCandidate, object_name: str) -> Grasp | tuple[str, str]:
        """The candidate's grasp, or (reason, detail) of its rejection: ``unreachable``,
        ``arm_collision`` or ``start_collision`` (a closing that misses is a grasp, Q = 0)."""
        q0, why = self.configuration(candidate)
        if q0 is None:
            return "unreachable", why
        gap = clearance(self.engine, q0)
        if gap < self.settings.min_clearance:
            where = (f"{1e3 * gap:.1f} mm from" if gap >= 0 else
                     f"{-1e3 * gap:.1f} mm deep in")
            return "arm_collision", (f"a robot link other than the fingers is {where} the "
                                     f"object (the planner keeps "
                                     f"{1e3 * self.settings.min_clearance:g} mm clear)")
        draws = self.engine.run(q0[None])
        outcome = int(draws.outcome[0])
        if outcome == START_COLLISION:
            name = OUTCOMES[outcome]
            return name, OUTCOME_DETAILS.get(name, name)
        meta = {"source": "palm_pose", "nominal_force_closure": outcome == FORCE_CLOSURE,
                "nominal_outcome": OUTCOMES[outcome],
                "contact_model": self.description.contact_model, **arm_meta(self.motion, q0)}
        return grasp_from_draw(draws, object_name, q0,
                               self.kin.pose(q0[None], self.description.palm_link)[0],
                               grasp_id=candidate.id, meta=meta, robot=self.description.name)
