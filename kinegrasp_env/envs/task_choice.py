"""The task of an episode, chosen at reset from the reset options and the env's RNG: the grasp
(given, or one of the env's tasks) and the noise (a noise model, or joint noise of a sigma and
distribution drawn from the env's ranges), and the noise entries of the env's ``info``.

Reset options (all optional): ``object``; the grasp as ONE of ``grasp`` (an index into the
env's grasps of the object: the shipped set, or ``grasp_file``; given with ``object`` where
the env has several objects), ``q0`` (a nominal
configuration: the robot's actuated vector; the default robot's 14 radians, 7 arm joints
then 7 hand DOF, docs/conventions.md) or ``palm_pose`` (one palm-pose entry in the object
frame, the schema of palm-pose candidate files: ``position`` + ``quaternion`` [x, y, z, w] or a 4x4
``pose``, with ``spread`` or a 7-value ``hand`` (another robot: its pre-shape as its
description names it), optional ``elbow``; solved by every robot's palm-pose IK,
:func:`~kinegrasp_env.robot.palm_ik.reach_robot_palm_pose`); ``sigma`` and ``noise`` (or
``noise_model``); ``psi`` (an elbow angle to start at). ``q0`` and ``palm_pose`` need
``object``, which may then be any built-in or imported object (not only the env's
``objects``); the nominal contacts and Q are computed at reset by closing the hand once at
q0 with the env's engine, and a hand that does not close on the object (``start_collision``
or ``missed``: a task needs >= 2 contacts with every finger on the object;
``no_force_closure`` is a task with nominal Q = 0), an unreachable palm pose, a q0 of the
wrong length, not finite or outside the joint limits are ValueErrors
(:mod:`kinegrasp_env.envs.tasks`). Such a task's ``info["grasp"]`` is ``"q0"`` or the palm
pose's ``id`` (default ``"palm_pose"``); the observation is as for a shipped grasp.

The env's RNG draws, in this order and only where the options leave them open: the object,
the grasp index, the sigma, the noise distribution.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from kinegrasp_env.envs.arguments import reset_sigma
from kinegrasp_env.envs.grasp_task import RobotTask
from kinegrasp_env.envs.tasks import given_robot_grasp, grasp_option
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.noise_spec import noise_model_from, spec_of
from kinegrasp_env.world.grasps import Grasp

__all__ = ["joint_sigma", "noise_info", "pick_grasp", "pick_noise", "shipped_grasp"]


def joint_sigma(noise: JointNoise | NoiseModel, arm: int) -> float:
    """The joint sigma ``info`` shows (radians): the largest over the ``arm`` arm joints."""
    return float(noise.sigma_vector(arm).max())


def noise_info(noise: JointNoise | NoiseModel, arm: int) -> dict:
    """The noise entries of ``info`` for an arm of ``arm`` joints: sigma and noise type of
    the joints, and a model's spec."""
    info = {"sigma": joint_sigma(noise, arm), "noise": noise.kind}
    if isinstance(noise, NoiseModel):
        info["noise_model"] = spec_of(noise)
    return info


def pick_grasp(options: dict, rng: np.random.Generator, tasks: dict[str, list[Grasp]],
               object_names: tuple[str, ...], robot_task: RobotTask) -> Grasp:
    """The episode's grasp: a ``q0`` or ``palm_pose`` option's (closed once at reset by the
    robot's task), else one of ``tasks`` (:func:`shipped_grasp`).

    Args:
        options: the reset options.
        rng: the env's ``np_random``.
        tasks: the env's grasps per object name; ``object_names`` their sorted names.
        robot_task: the env's robot's task.
    """
    key = grasp_option(options)
    if key in ("q0", "palm_pose"):
        return given_robot_grasp(options, key, robot_task)
    return shipped_grasp(options, rng, tasks, object_names)


def shipped_grasp(options: dict, rng: np.random.Generator, tasks: dict[str, list[Grasp]],
                  object_names: tuple[str, ...]) -> Grasp:
    """A grasp of the env's tasks: the ``object`` and ``grasp`` options, or drawn with ``rng``
    (the object uniformly from ``object_names``, then the grasp uniformly from its list)."""
    name = options.get("object")
    if name is None and options.get("grasp") is not None and len(object_names) > 1:
        raise ValueError(f"the reset option grasp is an index into one object's grasps: "
                         f"give the object too (this env has {', '.join(object_names)})")
    if name is None:
        name = object_names[rng.integers(len(object_names))]
    elif name not in tasks:
        raise ValueError(f"unknown object {name!r}; this env has "
                         f"{', '.join(object_names)}")
    grasps = tasks[name]
    index = options.get("grasp")
    if index is None:
        index = int(rng.integers(len(grasps)))
    elif isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise ValueError(f"reset option grasp must be an integer index into {name}'s "
                         f"{len(grasps)} grasps, got {index!r}")
    elif not 0 <= index < len(grasps):
        raise ValueError(f"grasp index {index} out of range: {name} has {len(grasps)} "
                         f"(0..{len(grasps) - 1})")
    return grasps[int(index)]


def pick_noise(options: dict, rng: np.random.Generator, sigma_range: tuple[float, float],
               noise_types: tuple[str, ...], noise_model: NoiseModel | None,
               check_noise: Callable[[NoiseModel], None]) -> JointNoise | NoiseModel:
    """The task's noise: the ``noise_model`` option or the env's ``noise_model``, else joint
    noise of the ``sigma`` and ``noise`` options (drawn with ``rng`` from the env's ranges
    where not given: sigma uniformly in ``sigma_range`` (radians), the distribution uniformly
    from ``noise_types``).

    Args:
        check_noise: raises a ValueError for a noise model the env's robot cannot draw.
    """
    model = options.get("noise_model", noise_model)
    if model is not None:
        if options.get("sigma") is not None or options.get("noise") is not None:
            raise ValueError("give a noise_model (the env's or the reset option) or the reset "
                             "options sigma/noise, not both")
        model = noise_model_from(model)
        check_noise(model)
        return model
    sigma = options.get("sigma")
    if sigma is None:
        sigma = float(rng.uniform(*sigma_range))
    else:
        sigma = reset_sigma(sigma)
    kind = options.get("noise")
    if kind is None:
        kind = noise_types[rng.integers(len(noise_types))]
    return JointNoise(float(sigma), kind)
