"""The re-weighted elbow search (:mod:`kinegrasp_env.toolkit.elbow_reweight`) of any robot:
one batch of closings over the palm's deviation (the robot's palm error:
the palm link and every link below it moved in the flange frame,
:mod:`~kinegrasp_env.closing.hand_errors`) answers every elbow angle of a 7-joint arm's
self-motion (:func:`optimize_robot_elbow_reweighted`), or every IK branch of a 6-joint arm
(:func:`optimize_robot_branches_reweighted`: each branch's Jacobian gives the deviation its
own Gaussian; no motion joins the branches, so the curve has no slope and the best branch is
the best of the batch's estimates).

The robot's pieces (:class:`~kinegrasp_env.toolkit.elbow_reweight.ReweightRobot`): the
flange's body Jacobian and the self-motion of its description
(:class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`), the reachable angles of
``kinegrasp elbow`` (:func:`~kinegrasp_env.toolkit.elbow_search.
robot_reachable_configurations`), the batch closed at the grasp's own configuration, and
direct draws as ``elbow --method direct`` draws them (selection: ``seed``; fresh:
:func:`~kinegrasp_env.toolkit.elbow_search.fresh_point`). The batch moves the hand alone: the
arm's links are where the grasp's own configuration puts them, which is what joint noise
changes besides the palm (an assumption the fresh direct draws at the chosen angle check).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.evaluate import RobotReferenceEngine
from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.montecarlo.palm_batch import check_batch_engine, close_batch, gaussian_terms
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.ik_branches import DEFAULT_STARTS
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
from kinegrasp_env.toolkit.elbow_search import (
    AngleScorer,
    BranchResult,
    angle_point,
    branch_variants,
    fresh_point,
    robot_reachable_configurations,
)
from kinegrasp_env.toolkit.plan_checks import clearance
from kinegrasp_env.toolkit.search_checks import check_branch_arm, check_search
from kinegrasp_env.world.grasps import Grasp


def check_robot_reweight(grasp: Grasp, noise, samples: int, epsilon: float, delta: float,
                         batch: int | None, seed: int = 0, engine: str = "fast"
                         ) -> RobotDescription:
    """The grasp's robot, or ValueError (one line) for what
    :func:`optimize_robot_elbow_reweighted` and :func:`optimize_robot_branches_reweighted`
    refuse before any closing: the search's inputs (:func:`~kinegrasp_env.toolkit.
    search_checks.check_search`), noise other than Gaussian joint noise (of the arm's
    joints), an engine that cannot close palm deviations (:func:`~kinegrasp_env.montecarlo.
    palm_batch.check_batch_engine`), an arm that is neither a 7-joint one with a
    self-motion nor a 6-joint one, and :func:`~kinegrasp_env.toolkit.elbow_reweight.
    check_reweight`'s refusals."""
    description = check_search(grasp, noise, samples, seed, epsilon, delta)
    if not isinstance(noise, JointNoise):
        raise ValueError("the re-weighted elbow search takes Gaussian joint noise (a "
                         "JointNoise; a noise model's runs take the direct method)")
    check_batch_engine(engine)
    check_reweight(grasp, noise, samples, epsilon, delta, batch, description.arm_dof)
    if not (description.has_self_motion or description.arm_dof == 6):
        raise ValueError(f"robot {description.name!r} has {description.arm_dof} arm joints"
                         f"{'' if description.arm_angle_links else ' and no elbow angle'}; "
                         "the re-weighted search moves a 7-joint arm along its self-motion "
                         "or compares a 6-joint arm's IK branches")
    return description


def optimize_robot_elbow_reweighted(grasp: Grasp, noise: JointNoise, samples: int,
                                    seed: int = 0, *, engine: str = "fast",
                                    step: float = FINE_STEP,
                                    epsilon: float = DEFAULT_EPSILON,
                                    delta: float = DEFAULT_DELTA, batch: int | None = None,
                                    progress=None, friction: float = 0.5,
                                    executor: Executor | None = None,
                                    reach: list[tuple[float, np.ndarray]] | None = None
                                    ) -> tuple[ElbowResult, ReweightEvidence]:
    """The most robust elbow of ``grasp`` (its ``robot`` names the robot) from one batch of
    closings (the steps: :mod:`~kinegrasp_env.toolkit.elbow_reweight`).

    Args:
        grasp: the grasp; its palm pose and nominal contacts stay fixed.
        noise: Gaussian joint noise on the arm joints.
        samples: the accuracy asked for: each angle's effective sample size at least this,
            else direct draws for the shortfall; fresh direct draws per scored angle.
        seed: run seed (the batches' streams; the direct draws' selection and fresh rows).
        engine: closes the batches and the direct draws (``fast``, ``pybullet``).
        step: fine-grid spacing of psi, radians.
        epsilon, delta: the certificate's margin and error level.
        batch: closings per batch (default ``BATCH_FACTOR`` x samples).
        progress: optional ``progress(stage)`` callback with a stage name.
        friction: the contacts' mu (the batches' and the direct draws').
        executor: runs the direct draws in chunks (the same draws).
        reach: :func:`~kinegrasp_env.toolkit.elbow_search.robot_reachable_configurations`,
            when already computed.

    Raises:
        ValueError: joint noise that is not Gaussian, an arm without a self-motion of 7
            joints, the checks of :func:`~kinegrasp_env.toolkit.elbow_reweight.
            check_reweight` (before any closing).
    """
    description = check_robot_reweight(grasp, noise, samples, epsilon, delta, batch, seed,
                                       engine)
    if not description.has_self_motion:
        raise ValueError(f"robot {description.name!r} has no self-motion: its IK branches "
                         "are optimize_robot_branches_reweighted's")
    with RobotReferenceEngine(description, grasp.object, friction=friction) as reference:
        if reach is None:
            reach = robot_reachable_configurations(grasp, reference, step)
        return _search(grasp, noise, samples, seed, reference, reach,
                       nominal_index(grasp, reach), engine=engine, step=step, epsilon=epsilon,
                       delta=delta, batch=batch, progress=progress, friction=friction,
                       executor=executor)


def _search(grasp: Grasp, noise: JointNoise, samples: int, seed: int,
            reference: RobotReferenceEngine, reach: list, nominal: int, *, engine: str,
            step: float, epsilon: float, delta: float, batch: int | None, progress,
            friction: float, executor: Executor | None
            ) -> tuple[ElbowResult, ReweightEvidence]:
    """:func:`~kinegrasp_env.toolkit.elbow_reweight.reweighted_search` of a description
    robot's configurations ``reach`` ((psi, q) pairs; ``nominal``: the grasp's own): the
    batch closed at the grasp's own configuration by ``engine``, the direct and fresh draws
    by the angle scorer of ``reference``."""
    description = reference.description
    joint_cov, palm_cov = gaussian_terms(noise, description.arm_dof)
    scorer = AngleScorer.of(reference, engine, executor)
    try:
        q0 = reach[nominal][1]

        def direct(psi: float, q: np.ndarray, n: int) -> ElbowPoint:
            return angle_point(grasp, psi, q, noise, n, seed, scorer)

        robot = ReweightRobot(
            reach, nominal, SelfMotionDeviation(joint_cov, palm_cov, description),
            lambda covs, n, stream: close_batch(q0, grasp.object, covs, n, stream,
                                                engine=engine, friction=friction,
                                                robot=description.name),
            direct,
            lambda q: fresh_point(grasp, q, noise, samples, seed, scorer),
            engine)
        return reweighted_search(grasp, noise, samples, seed, robot, step=step,
                                 epsilon=epsilon, delta=delta, batch=batch, progress=progress)
    finally:
        scorer.close()


def optimize_robot_branches_reweighted(grasp: Grasp, noise: JointNoise, samples: int,
                                       seed: int = 0, *, engine: str = "fast",
                                       starts: int = DEFAULT_STARTS,
                                       epsilon: float = DEFAULT_EPSILON,
                                       delta: float = DEFAULT_DELTA, batch: int | None = None,
                                       progress=None, friction: float = 0.5,
                                       executor: Executor | None = None
                                       ) -> tuple[BranchResult, ReweightEvidence]:
    """The most robust IK branch of a 6-joint arm's ``grasp`` from one batch of closings:
    the branches of :func:`~kinegrasp_env.toolkit.elbow_search.optimize_robot_branches`
    (``starts`` IK starts from one fixed seed), each re-weighted from one batch drawn from
    the mixture of their Gaussians and closed at the grasp's own configuration (a branch
    whose effective sample size falls below ``samples`` topped up with direct draws; a
    branch whose arm meets the object or the table at the palm pose left out); the
    best and the grasp's own branch scored on fresh direct draws; the certificate from a
    second batch (the steps of :func:`~kinegrasp_env.toolkit.elbow_reweight.
    reweighted_search`; the other arguments as :func:`optimize_robot_elbow_reweighted`).

    Raises:
        ValueError: :func:`check_robot_reweight`'s refusals, an arm that is not a 6-joint
            one (before any closing).
    """
    description = check_robot_reweight(grasp, noise, samples, epsilon, delta, batch, seed,
                                       engine)
    check_branch_arm(description)
    with RobotReferenceEngine(description, grasp.object, friction=friction) as reference:
        branches, nominal = branch_variants(grasp, reference, int(starts))
        hand = np.asarray(grasp.q0, dtype=float)[description.arm_dof:]
        reach = [(float(i), np.concatenate([b.q, hand])) for i, b in enumerate(branches)]
        # a branch whose arm meets the object or the table is left out, as the self-motion's
        # colliding angles are: the batch, closed with the arm of the grasp's own branch,
        # cannot see its collisions
        reach = [(i, q) for i, q in reach if i == nominal or clearance(reference, q) > 0.0]
        own = next(k for k, (i, _) in enumerate(reach) if i == nominal)
        result, evidence = _search(grasp, noise, samples, seed, reference, reach, own,
                                   engine=engine, step=0.0, epsilon=epsilon, delta=delta,
                                   batch=batch, progress=progress, friction=friction,
                                   executor=executor)
    best = round(result.best_psi)
    return BranchResult(result, branches, nominal, best), evidence
