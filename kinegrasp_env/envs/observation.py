"""The envs' observation of a configuration, any robot: the task (nominal configuration,
noise), where the palm is against the object, the elbow, and how the joint noise spreads the
palm there.

Layout (``2 arm + hand + 23`` numbers, unclipped): q0's arm joints / pi, q0's hand joints /
pi, the joint sigma / 0.05 rad, the noise type one-hot (3), the palm position in the object
frame / 0.3 m (3), the palm orientation in the object frame (the first two columns of R: 6),
sin and cos of the elbow angle psi, the current arm joints / pi, the palm pose's standard
deviation per unit joint noise (6: sqrt of diag J J^T, object frame), 10 x the nominal Q, and
the episode's elapsed fraction.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from kinegrasp_env.robot.kinematics import Kinematics, elbow_angle
from kinegrasp_env.sampling.noise import DISTRIBUTIONS
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import load_object

__all__ = ["OBS_EXTRA", "ArmObserver"]

#: Observation entries besides the arm (twice) and hand joints.
OBS_EXTRA = 23


class ArmObserver:
    """Observations (module docstring) of one robot.

    Args:
        kin: the robot's kinematics; palm_link: its palm.
        arm: arm joints (the first ``arm`` entries of a configuration).
        angle_links: the shoulder, elbow and wrist links whose centres give the elbow angle,
            or None: then ``elbow_angle`` gives it.
        elbow_angle: (n,) elbow coordinates of configurations (n, dof) (with ``angle_links``
            None: an arm's IK-branch coordinate,
            :class:`~kinegrasp_env.robot.branch_motion.BranchMotion`).
    """

    def __init__(self, kin: Kinematics, palm_link: str, arm: int,
                 angle_links: tuple[str, str, str] | None,
                 elbow_angle: Callable[[np.ndarray], np.ndarray] | None = None) -> None:
        if angle_links is None and elbow_angle is None:
            raise ValueError("an observer needs the elbow's angle_links or an elbow_angle")
        self.kin, self.palm_link, self.arm = kin, palm_link, arm
        self.angle_links = None if angle_links is None else tuple(angle_links)
        self.elbow_angle = elbow_angle
        self.links = list(dict.fromkeys([*kin.jacobian_links(palm_link),
                                         *(self.angle_links or ())]))

    def observe(self, grasp: Grasp, q: np.ndarray, noise, fraction: float,
                psi: float | None = None) -> tuple[np.ndarray, float]:
        """(observation (2 arm + hand + 23,) float64 unclipped, elbow angle psi of q,
        radians) of configuration q (dof,) for ``grasp`` under ``noise`` (a joint noise or
        noise model), ``fraction`` of the episode elapsed; ``psi``: the elbow coordinate to
        show instead of q's (an IK-branch coordinate the agent moves within a branch)."""
        obj = load_object(grasp.object)
        poses = self.kin.forward(np.asarray(q, dtype=float)[None], self.links)
        palm = poses[self.palm_link][0]
        rot_obj = obj.pose[:3, :3]
        rel_pos = rot_obj.T @ (palm[:3, 3] - obj.pose[:3, 3])
        rel_rot = rot_obj.T @ palm[:3, :3]
        jac = self.kin.jacobian_at(poses, self.palm_link)[0][:, :self.arm]
        jac = np.vstack([rot_obj.T @ jac[:3], rot_obj.T @ jac[3:]])
        spread = np.sqrt(np.diag(jac @ jac.T))
        if psi is not None:
            psi = float(psi)
        elif self.angle_links is None:
            psi = float(self.elbow_angle(np.asarray(q, dtype=float)[None])[0])
        else:
            s, e, w = (poses[link][0, :3, 3] for link in self.angle_links)
            psi = float(elbow_angle(s, e, w))
        sigma = float(noise.sigma_vector(self.arm).max())
        onehot = np.array([noise.kind == k for k in DISTRIBUTIONS], dtype=float)
        obs = np.concatenate([
            grasp.q0[:self.arm] / np.pi, grasp.q0[self.arm:] / np.pi, [sigma / 0.05], onehot,
            rel_pos / 0.3, rel_rot[:, :2].T.ravel(), [np.sin(psi), np.cos(psi)],
            q[:self.arm] / np.pi, spread, [10.0 * grasp.q_nominal], [fraction]])
        return obs, psi
