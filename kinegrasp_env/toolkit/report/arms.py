"""The arm at a few noisy draws on a report's 3-D scene: the draws' configurations
(:func:`first_arms`: a run's first draws, rebuilt from its seed's streams), the skeleton of
the chain from the robot's base to its palm (:func:`arm_skeletons`, the project's forward
kinematics) and the traces that draw them, coloured by outcome. Metres, world frame."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.montecarlo.draws import OUTCOMES
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.toolkit.report.scene import OUTCOME_COLOURS, skeleton_trace
from kinegrasp_env.world.grasps import Grasp


@dataclass(frozen=True)
class NoisyArms:
    """The arm at a few noisy draws of a grasp.

    Attributes:
        q: (k, dof) the draws' configurations; outcome: (k,) their outcomes (indices into
            :data:`~kinegrasp_env.montecarlo.draws.OUTCOMES`), or None where they were
            not kept (a ranking's draws).
    """

    q: np.ndarray
    outcome: np.ndarray | None


def first_arms(description: RobotDescription, grasp: Grasp, evaluation, sigma, seed: int,
               noise: str, shown: int) -> NoisyArms:
    """The arm at a run's first ``shown`` draws of joint noise (``sigma``, radians; the rows
    its integer seed's chunked streams draw first, whatever the processes:
    :func:`~kinegrasp_env.montecarlo.chunks.chunk_configurations`) with their
    outcomes in ``evaluation`` (:class:`~kinegrasp_env.montecarlo.evaluate.
    GraspEvaluation` with its draws; None: outcomes not known)."""
    from kinegrasp_env.montecarlo.chunks import chunk_configurations

    q = chunk_configurations(np.asarray(grasp.q0, dtype=float), description.arm_dof, sigma,
                             noise, seed, 0, shown)
    return NoisyArms(q, None if evaluation is None else evaluation.draws.outcome[:shown])


def arm_skeletons(description: RobotDescription, q: np.ndarray) -> np.ndarray:
    """(n, L, 3) the origins of the links from the base to the palm (the base, the child of
    each arm joint, the palm) at configurations q (n, dof), world frame, metres."""
    from kinegrasp_env.robot.kinematics import Kinematics

    kinematics = Kinematics(description.model)
    chain = kinematics.chain(description.palm_link)
    links = list(dict.fromkeys([chain[0].parent, *(j.child for j in chain)]))
    poses = kinematics.forward(np.atleast_2d(q), links)
    return np.stack([poses[link][:, :3, 3] for link in links], axis=1)


def noisy_traces(description: RobotDescription, arms: NoisyArms) -> list[dict]:
    """The skeletons of the noisy draws, one trace per outcome present, or one grey trace
    where the outcomes are not known (hidden until toggled)."""
    lines = arm_skeletons(description, arms.q)
    if arms.outcome is None:
        return [skeleton_trace(lines, f"noisy arms ({len(lines)})", "#7f7f7f", 2,
                               visible="legendonly")]
    return [skeleton_trace(lines[rows], f"noisy arms: {name.replace('_', ' ')} "
                           f"({len(rows)})", OUTCOME_COLOURS[name], 2, visible="legendonly")
            for k, name in enumerate(OUTCOMES)
            if len(rows := np.flatnonzero(arms.outcome == k))]
