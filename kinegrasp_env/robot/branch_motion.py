"""A non-redundant arm's configurations at one palm pose, laid out as a coordinate the way a
7-joint arm's self-motion is: its IK branches (:func:`~kinegrasp_env.robot.ik_branches.
ik_branches`) on the circle of an angle psi.

A 6-joint arm reaches a palm pose in finitely many configurations, so the envs' and the
planner's elbow angle becomes a branch coordinate: with B branches (in
:func:`~kinegrasp_env.robot.ik_branches.ik_branches`' order), branch k covers psi in
[-pi + 2 pi k / B, -pi + 2 pi (k + 1) / B) and a configuration on it has the bin's centre as
its coordinate. Moving psi across a bin's edge switches branch; every psi is reached. The
branches of a palm pose are found once (``starts`` seeded IK starts) and kept; a
configuration on a branch the search missed is added as the last one.
"""

from __future__ import annotations

import math

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.ik_branches import (
    BRANCH_SEED,
    DEFAULT_STARTS,
    MERGE_TOL,
    ik_branches,
    joint_difference,
)
from kinegrasp_env.robot.kinematics import Kinematics

__all__ = ["SAME_POSE", "BranchMotion", "elbow_motion"]

#: Two palm poses are one (their branches shared) when no entry of the (4, 4) poses differs
#: by more than this (metres, or rotation entries): the branches' IK converges to ~1e-7.
SAME_POSE = 1e-5
#: A coordinate within this fraction of a bin below its lower edge is on the edge.
EDGE_TOL = 1e-9


class BranchMotion:
    """The IK branches of an arm as an elbow coordinate (module docstring).

    Args:
        description: the robot (any arm; meant for one that is not redundant).
        kin: its kinematics (default: built from ``description.model``).
        starts, seed: the IK branch search's random starts and their seed.

    Attributes:
        angle_links: None (the coordinate is not an angle of the arm's links).
    """

    angle_links = None

    def __init__(self, description: RobotDescription, kin: Kinematics | None = None, *,
                 starts: int = DEFAULT_STARTS, seed: int = BRANCH_SEED) -> None:
        self.description = description
        self.kin = kin or Kinematics(description.model)
        self.starts, self.seed = int(starts), int(seed)
        self.arm = description.arm_dof
        self._branches: list[tuple[np.ndarray, np.ndarray]] = []  # (palm pose, branches)

    def branches(self, q: np.ndarray) -> np.ndarray:
        """(B, arm) the arm joints of the branches of configuration q's (dof,) palm pose,
        q's own among them."""
        q = np.asarray(q, dtype=float)
        pose = self.kin.pose(q[None], self.description.palm_link)[0]
        k = next((i for i, (known, _) in enumerate(self._branches)
                  if np.abs(known - pose).max() <= SAME_POSE), None)
        if k is None:
            found = np.array([b.q for b in ik_branches(
                self.description, pose, starts=self.starts, seed=self.seed, kin=self.kin)],
                dtype=float).reshape(-1, self.arm)
            self._branches.append((pose, found))
            k = len(self._branches) - 1
        found = self._branches[k][1]
        if found.shape[0] == 0 or joint_difference(self.description, found,
                                                   q[:self.arm]).min() > MERGE_TOL:
            found = np.vstack([found, q[None, :self.arm]])
            self._branches[k] = (self._branches[k][0], found)
        return found

    def branch_of(self, q: np.ndarray) -> tuple[int, int]:
        """(index of the branch nearest q (dof,), number of branches B)."""
        branches = self.branches(q)
        near = joint_difference(self.description, branches, np.asarray(q)[:self.arm])
        return int(np.argmin(near)), branches.shape[0]

    def elbow_angle(self, q: np.ndarray) -> np.ndarray:
        """(n,) the coordinate psi (radians) of configurations q (n, dof): the centre of
        their branch's bin."""
        out = []
        for row in np.atleast_2d(np.asarray(q, dtype=float)):
            k, count = self.branch_of(row)
            out.append(-math.pi + 2.0 * math.pi * (k + 0.5) / count)
        return np.array(out)

    def set_elbow_angle(self, q: np.ndarray, psi: float) -> tuple[np.ndarray, bool]:
        """(q on the branch whose bin holds ``psi`` (radians, wrapped to [-pi, pi)), True):
        the arm joints replaced, the hand kept; every coordinate is reached."""
        q = np.asarray(q, dtype=float)
        branches = self.branches(q)
        wrapped = (float(psi) + math.pi) % (2.0 * math.pi)
        # a bin's lower edge is its own (an edge computed as -pi + 2 pi k / B may round
        # below it)
        k = min(int(wrapped / (2.0 * math.pi) * branches.shape[0] + EDGE_TOL),
                branches.shape[0] - 1)
        moved = q.copy()
        moved[:self.arm] = branches[k]
        return moved, True


def elbow_motion(description: RobotDescription, kin: Kinematics | None = None):
    """The elbow coordinate of a robot's arm: a 7-joint arm's self-motion
    (:class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`; ValueError without
    ``arm_angle_links``), any other arm's IK branches (:class:`BranchMotion`)."""
    from kinegrasp_env.robot.null_motion import ArmSelfMotion

    if description.arm_dof == 7:
        return ArmSelfMotion(description, kin)
    return BranchMotion(description, kin)
