"""What every elbow or IK-branch search (:mod:`~kinegrasp_env.toolkit.elbow_search`,
:mod:`~kinegrasp_env.toolkit.elbow_reweight_search`) refuses before any closing, in one line
naming the bad value: its inputs (:func:`check_search`), and an arm without IK branches to
compare (:func:`check_branch_arm`).
"""

from __future__ import annotations

from kinegrasp_env.counts import check_count
from kinegrasp_env.montecarlo.evaluation_checks import check_engine_grasp
from kinegrasp_env.montecarlo.reference_engine import RobotReferenceEngine
from kinegrasp_env.robot.catalog import as_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import JointNoise, is_integer_seed
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.toolkit.elbow_certificate import check_levels
from kinegrasp_env.world.grasps import Grasp, check_grasp


def check_search(grasp: Grasp, noise, samples, seed, epsilon: float, delta: float,
                 engine: RobotReferenceEngine | None = None) -> RobotDescription:
    """The grasp's robot, or ValueError (one line, naming the value) for what every elbow or
    IK-branch search refuses before any closing: not a grasp, the certificate's levels
    (:func:`~kinegrasp_env.toolkit.elbow_certificate.check_levels`), a number of draws that
    is not a positive integer, a seed that is not an integer >= 0 (the run's rows), noise
    that is neither joint noise nor a noise model, and a given engine that is not a
    reference engine of the grasp's robot and object."""
    check_grasp(grasp)
    check_levels(epsilon, delta)
    check_count(samples, "samples")
    if not is_integer_seed(seed):
        raise ValueError(f"seed must be an integer >= 0 (the run's rows), got {seed!r}")
    if not isinstance(noise, (JointNoise, NoiseModel)):
        raise ValueError(f"noise must be a JointNoise (e.g. JointNoise(0.0133)) or a "
                         f"NoiseModel, got {type(noise).__name__} {noise!r:.40}")
    description = as_description(grasp.robot)
    if engine is not None:
        if type(engine) is not RobotReferenceEngine:
            raise ValueError(f"engine must be a RobotReferenceEngine of the grasp's robot and "
                             f"object, or None, got {type(engine).__name__}")
        check_engine_grasp(grasp, engine)
    return description


def check_branch_arm(description: RobotDescription) -> None:
    """ValueError (one line) unless the robot's arm has 6 joints: the IK branches of a palm
    pose are a 6-joint arm's (a 7-joint arm has a self-motion instead)."""
    if description.arm_dof != 6:
        raise ValueError(f"robot {description.name!r} has {description.arm_dof} arm joints; "
                         "IK branches are a 6-joint arm's (a 7-joint arm's elbow moves along "
                         "its self-motion)")
