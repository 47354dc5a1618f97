"""``kinegrasp validate`` of a description robot's grasps (a robot other than the default
``kuka_sdh``): the same noisy draws through a kinematic engine of the robot
(:mod:`~kinegrasp_env.montecarlo.robot_evaluate`: ``pybullet``, the reference, or ``fast``)
and the holding test of its own hand in pybullet
(:class:`~kinegrasp_env.physics.robot_hold.RobotHold`) or MuJoCo
(:class:`~kinegrasp_env.physics.mujoco_robot_hold.MujocoRobotHold`); results in the default robot's
per-draw form (:class:`~kinegrasp_env.toolkit.validation.GraspDraws`), summarized and
written by the same code.

The draws are those of ``kinegrasp evaluate --robot`` with the same seed and sigma
(:func:`~kinegrasp_env.montecarlo.robot_evaluate.evaluate_robot_grasp`: joint noise on the
description's arm joints, the hand at its pre-shape). The fingers' normal forces are stored
one column per finger of the description.
"""

from __future__ import annotations

import hashlib
from dataclasses import fields
from pathlib import Path

from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
from kinegrasp_env.montecarlo.robot_evaluate import make_engine, robot_configurations
from kinegrasp_env.physics.hand_motors import motor_efforts
from kinegrasp_env.physics.protocol import HOLD_OUTCOMES, PHASES
from kinegrasp_env.physics.pybullet_world import WorldSettings
from kinegrasp_env.physics.robot_hold import RobotMotorSettings
from kinegrasp_env.physics.simulators import DESCRIPTION_ROBOT_SIMULATORS, check_simulator
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.toolkit.validation import GraspDraws, ValidationSettings, run_validation
from kinegrasp_env.world.grasps import Grasp


def motors_summary(robot: str, torque_scale: float = 1.0) -> list[dict]:
    """The motors a robot's holding test runs with: per closing joint its effort (times
    ``torque_scale``), unit, source (``urdf`` or ``description``) and closing speed."""
    return [m.to_json() for m in motor_efforts(load_robot(robot), torque_scale)]


def check_robot_settings(robot: str, settings: ValidationSettings) -> None:
    """ValueError (one line) for settings a description robot's holding test cannot
    honour, or a robot whose motors lack an effort limit."""
    if settings.simulator not in DESCRIPTION_ROBOT_SIMULATORS:
        raise ValueError(f"--simulator {settings.simulator}: only "
                         f"{' and '.join(DESCRIPTION_ROBOT_SIMULATORS)} hold description "
                         f"robots (robot {robot!r})")
    check_simulator(settings.simulator)
    description = load_robot(robot)
    motor_efforts(description)
    if settings.simulator == "mujoco":
        from kinegrasp_env.physics.mujoco_robot_hold import description_hand

        description_hand(description)  # its meshes are ones MuJoCo reads


def robot_key(grasp: Grasp, settings: ValidationSettings) -> str:
    """A hash of everything a description robot's grasp draws depend on (cf.
    :func:`~kinegrasp_env.toolkit.validation.settings_key`): the robot's description and URDF
    too."""
    description = load_robot(grasp.robot)
    kept = [(f.name, getattr(settings, f.name)) for f in fields(settings) if f.name != "samples"]
    files = [hashlib.sha256(Path(p).read_bytes()).hexdigest() for p in
             (description.path, description.urdf)]
    text = repr((grasp.robot, files, grasp.object, grasp.q0.tobytes().hex(), kept,
                 WorldSettings(), RobotMotorSettings(), settings.protocol, PHASES,
                 HOLD_OUTCOMES))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# a worker's engines, built on first use: (kinematic, physics) per (robot, object, settings)
_ENGINES: dict[tuple, tuple[RobotEngine, RobotHoldEngine]] = {}


def robot_engines(grasp: Grasp, settings: ValidationSettings
                  ) -> tuple[RobotEngine, RobotHoldEngine]:
    key = (grasp.robot, grasp.object, settings.kinematic, settings.friction,
           settings.num_edges, settings.protocol, settings.simulator)
    if key not in _ENGINES:
        options = {"friction": settings.friction, "num_edges": settings.num_edges}
        _ENGINES[key] = (make_engine(settings.kinematic, grasp.robot, grasp.object, **options),
                         RobotHoldEngine(grasp.robot, grasp.object, protocol=settings.protocol,
                                         simulator=settings.simulator, **options))
    return _ENGINES[key]


def robot_draws(task: tuple[int, Grasp, ValidationSettings, int]) -> GraspDraws:
    """Run one grasp ``(index, grasp, settings, start)`` of a description robot: its draws
    start..samples-1 through the kinematic engine and the holding test."""
    index, grasp, settings, start = task
    kinematic, physics = robot_engines(grasp, settings)
    q = robot_configurations(grasp, kinematic, sigma=settings.sigma, n=settings.samples,
                             seed=settings.seed)[start:]
    kin = kinematic.run(q)
    phys, hold = physics.run_hold(q)
    return GraspDraws(grasp.object, index, grasp.id, kin.outcome, kin.quality, phys.outcome,
                      phys.quality, hold)


def run_robot_validation(grasps: list[tuple[int, Grasp]], settings: ValidationSettings,
                         out_dir: str | Path, progress: bool = False,
                         processes: int = 1) -> list[GraspDraws]:
    """:func:`~kinegrasp_env.toolkit.validation.run_validation` of one description robot's
    grasps (every grasp of that robot), one grasp per task on ``processes`` worker
    processes (each grasp's draws the same whichever process runs it)."""
    robots = {g.robot for _, g in grasps}
    if len(robots) != 1:
        raise ValueError(f"the grasps are of several robots: {', '.join(sorted(robots))}")
    check_robot_settings(robots.pop(), settings)
    return run_validation(grasps, settings, out_dir, processes, progress,
                          task=robot_draws, key=robot_key)
