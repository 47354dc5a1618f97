"""The re-weighted elbow search (:mod:`kinegrasp_env.toolkit.elbow_reweight`) for a
description robot with a 7-joint arm: one batch of closings over the palm's deviation
(the robot's palm error: the palm link and every link below it moved in the flange frame,
:mod:`~kinegrasp_env.closing.hand_errors`) answers every elbow angle of its self-motion.

The robot's pieces (:class:`~kinegrasp_env.toolkit.elbow_reweight.ReweightRobot`): the
flange's body Jacobian and the self-motion of its description
(:class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`), the reachable angles of
``kinegrasp elbow --robot`` (:func:`~kinegrasp_env.toolkit.robot_elbow.
robot_reachable_configurations`), the batch closed at the grasp's own configuration, and
direct draws as ``elbow --robot --method direct`` draws them (selection: ``seed``; fresh:
:func:`~kinegrasp_env.toolkit.robot_elbow.fresh_seed`). The batch moves the hand alone: the
arm's links are where the grasp's own configuration puts them, which is what joint noise
changes besides the palm (an assumption the fresh direct draws at the chosen angle check).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.montecarlo.palm_batch import close_batch, gaussian_terms
from kinegrasp_env.montecarlo.robot_evaluate import RobotReferenceEngine
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.elbow import FINE_STEP, ElbowPoint, ElbowResult, nominal_index
from kinegrasp_env.toolkit.elbow_certificate import DEFAULT_DELTA, DEFAULT_EPSILON
from kinegrasp_env.toolkit.elbow_reweight import (
    ReweightEvidence,
    ReweightRobot,
    SelfMotionDeviation,
    check_reweight,
    reweighted_search,
)
from kinegrasp_env.toolkit.robot_elbow import (
    AngleScorer,
    angle_point,
    fresh_seed,
    robot_reachable_configurations,
)
from kinegrasp_env.world.grasps import Grasp


def check_robot_reweight(grasp: Grasp, noise, samples: int, epsilon: float, delta: float,
                         batch: int | None) -> RobotDescription:
    """The grasp's robot, or ValueError (one line) for what
    :func:`optimize_robot_elbow_reweighted` refuses before any closing: noise other than
    Gaussian joint noise, an arm without a 7-joint self-motion, and :func:`~kinegrasp_env.
    toolkit.elbow_reweight.check_reweight`'s refusals."""
    if not isinstance(noise, JointNoise):
        raise ValueError("a description robot's re-weighted elbow takes joint noise "
                         "(--sigma, --noise gaussian)")
    check_reweight(grasp, noise, samples, epsilon, delta, batch)
    description = load_robot(grasp.robot)
    if not description.has_self_motion:
        raise ValueError(f"robot {description.name!r} has {description.arm_dof} arm joints"
                         f"{'' if description.arm_angle_links else ' and no elbow angle'}; "
                         "the re-weighted search moves a 7-joint arm along its self-motion")
    return description


def optimize_robot_elbow_reweighted(grasp: Grasp, noise: JointNoise, samples: int,
                                    seed: int = 0, *, engine: str = "fast",
                                    step: float = FINE_STEP,
                                    epsilon: float = DEFAULT_EPSILON,
                                    delta: float = DEFAULT_DELTA, batch: int | None = None,
                                    progress=None, friction: float = 0.5,
                                    executor: Executor | None = None
                                    ) -> tuple[ElbowResult, ReweightEvidence]:
    """The most robust elbow of a description robot's ``grasp`` from one batch of closings
    (arguments: :func:`~kinegrasp_env.toolkit.elbow_reweight.optimize_elbow_reweighted`;
    ``engine`` closes the batches and the direct draws, ``executor`` runs the direct draws
    in chunks).

    Raises:
        ValueError: joint noise that is not Gaussian, an arm without a self-motion of 7
            joints, the checks of :func:`~kinegrasp_env.toolkit.elbow_reweight.
            check_reweight` (before any closing).
    """
    description = check_robot_reweight(grasp, noise, samples, epsilon, delta, batch)
    joint_cov, palm_cov = gaussian_terms(noise)
    with RobotReferenceEngine(description, grasp.object, friction=friction) as reference:
        reach = robot_reachable_configurations(grasp, reference, step)
        scorer = AngleScorer.of(reference, engine, executor)
        try:
            nominal = nominal_index(grasp, reach)
            q0 = reach[nominal][1]

            def direct(psi: float, q: np.ndarray, n: int) -> ElbowPoint:
                fc, p_fc, ci = angle_point(grasp, psi, q, noise, n, seed, scorer)
                return ElbowPoint(psi, q, p_fc, ci, fc)

            robot = ReweightRobot(
                reach, nominal, SelfMotionDeviation(joint_cov, palm_cov, description),
                lambda covs, n, stream: close_batch(q0, grasp.object, covs, n, stream,
                                                    engine=engine, friction=friction,
                                                    robot=description.name),
                direct,
                lambda q: angle_point(grasp, 0.0, q, noise, samples, fresh_seed(seed),
                                      scorer)[0],
                engine)
            return reweighted_search(grasp, noise, samples, seed, robot, step=step,
                                     epsilon=epsilon, delta=delta, batch=batch,
                                     progress=progress)
        finally:
            scorer.close()
