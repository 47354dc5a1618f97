"""One grasp's draws of ``kinegrasp validate``, for any robot: the same noisy draws through
a kinematic engine of the robot (:mod:`~kinegrasp_env.montecarlo.evaluate`: ``pybullet``, the
reference, or ``fast``) and the holding test of its own hand in pybullet
(:class:`~kinegrasp_env.physics.robot_hold.RobotHold`) or MuJoCo
(:class:`~kinegrasp_env.physics.mujoco_robot_hold.MujocoRobotHold`), the hand closed by the
motors of its description; results in the per-draw form
:class:`~kinegrasp_env.toolkit.validation.GraspDraws`, summarized and written by the same
code (:func:`~kinegrasp_env.toolkit.validation.run_validation`), and the checks of a
robot's settings before any work.

The draws are those of ``kinegrasp evaluate --robot`` with the same seed and sigma
(:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`: joint noise on the
description's arm joints, the hand at its pre-shape). The fingers' normal forces are stored
one column per finger of the description.
"""

from __future__ import annotations

import hashlib
from dataclasses import fields
from pathlib import Path

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.evaluate import make_engine, robot_configurations
from kinegrasp_env.montecarlo.hold_engine import hold_engine
from kinegrasp_env.physics.hand_motors import motor_efforts
from kinegrasp_env.physics.protocol import HOLD_OUTCOMES, PHASES
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.physics.robot_hold import RobotMotorSettings
from kinegrasp_env.physics.simulators import PHYSICS_MODEL, SIMULATORS, check_simulator
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.sampling.noise_model import DRAW_LAYOUT
from kinegrasp_env.toolkit.validation_records import GraspDraws, ValidationSettings
from kinegrasp_env.world.grasps import Grasp
from kinegrasp_env.world.objects import object_version


def motors_summary(robot: str, torque_scale: float = 1.0) -> list[dict]:
    """The motors a robot's holding test runs with: per closing joint its effort (times
    ``torque_scale``), unit, source (``urdf`` or ``description``) and closing speed."""
    return [m.to_json() for m in motor_efforts(load_robot(robot), torque_scale)]


def check_settings(robot: str, settings: ValidationSettings) -> None:
    """ValueError (one line) for settings a robot's holding test cannot honour, or a robot
    whose motors lack an effort limit."""
    check_simulator(settings.simulator)
    description = load_robot(robot)
    motor_efforts(description)
    if settings.simulator == "mujoco":
        from kinegrasp_env.physics.mujoco_robot_hold import description_hand

        description_hand(description)  # its meshes are ones MuJoCo reads


def settings_key(grasp: Grasp, settings: ValidationSettings) -> str:
    """A hash of everything a robot's grasp draws depend on: the settings (less the number
    of draws), the robot's description and URDF, the object's version, the grasp, the
    physics, motor and lift settings, the class that holds the hand in the run's simulator
    and the physics model (:data:`~kinegrasp_env.physics.simulators.PHYSICS_MODEL`),
    the protocol and the draws' layout in the seed's streams: the name of its cache file (a
    cached run of more draws serves a smaller one: the draws of n samples are the first n
    of any larger number)."""
    description = load_robot(grasp.robot)
    kept = [(f.name, getattr(settings, f.name)) for f in fields(settings) if f.name != "samples"]
    files = [hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in
             (description.path, description.urdf)]
    text = repr((grasp.robot, files, grasp.object, object_version(grasp.object),
                 grasp.q0.tobytes().hex(), kept,
                 WorldSettings(), RobotMotorSettings(),
                 SIMULATORS[settings.simulator], PHYSICS_MODEL, settings.protocol,
                 PHASES, HOLD_OUTCOMES, DRAW_LAYOUT))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# a worker's engines, built on first use: (kinematic, physics) per (robot, object, settings)
_ENGINES: dict[tuple, tuple[RobotEngine, RobotEngine]] = {}


def worker_engines(grasp: Grasp, settings: ValidationSettings
                  ) -> tuple[RobotEngine, RobotEngine]:
    """(kinematic engine, holding test's engine: its ``run_hold``) of a grasp's robot and
    object under ``settings``, built once per worker."""
    key = (grasp.robot, grasp.object, settings.kinematic, settings.friction,
           settings.num_edges, settings.protocol, settings.simulator,
           object_version(grasp.object))
    if key not in _ENGINES:
        options = {"friction": settings.friction, "num_edges": settings.num_edges}
        _ENGINES[key] = (make_engine(settings.kinematic, grasp.robot, grasp.object, **options),
                         hold_engine(grasp.robot, grasp.object, protocol=settings.protocol,
                                     simulator=settings.simulator, **options))
    return _ENGINES[key]


def grasp_draws(task: tuple[int, Grasp, ValidationSettings, int]) -> GraspDraws:
    """Run one grasp ``(index, grasp, settings, start)``: its draws
    start..samples-1 through the kinematic engine and the holding test."""
    index, grasp, settings, start = task
    kinematic, physics = worker_engines(grasp, settings)
    q = robot_configurations(grasp, kinematic, sigma=settings.sigma,
                             n=settings.samples - start, seed=settings.seed, offset=start)
    kin = kinematic.run(q)
    phys, hold = physics.run_hold(q)
    return GraspDraws(grasp.object, index, grasp.id, kin.outcome, kin.quality, phys.outcome,
                      phys.quality, hold)
