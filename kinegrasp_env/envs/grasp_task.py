"""The robot's side of KineGrasp-v0, for every robot of the catalog (``robot="kuka_sdh"``,
the default, ``robot="panda"``, a user's robot).

Everything robot-specific is derived from the robot's description
(:mod:`kinegrasp_env.robot.description`):

- **grasps**: the robot's shipped grasp sets (``assets/grasps/<robot>/<object>.json``; for
  the Panda the antipodal planner's output, ``kinegrasp plan --robot panda --count 4``:
  cube, drill and spray_flask, 4 grasps each) or a ``grasp_file`` of grasps of the robot;
- **self-motion**: :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion` (7 arm joints:
  the palm held, the elbow angle of the description's ``arm_angle_links`` moved); for an arm
  of 6 joints (or fewer) its IK branches as the elbow coordinate
  (:class:`~kinegrasp_env.robot.branch_motion.BranchMotion`: with B branches, branch k
  covers psi in [-pi + 2 pi k / B, -pi + 2 pi (k + 1) / B));
- **reward draws**: an engine of the robot by name
  (:func:`~kinegrasp_env.montecarlo.evaluate.make_engine`): ``fast``
  (:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`, the reference closing
  batched over the draws), ``pybullet``
  (:class:`~kinegrasp_env.montecarlo.evaluate.RobotReferenceEngine`: pybullet closest
  points on the URDF's collision geometry) or ``physics``; the robot's contact model, joint
  noise on the arm joints (or a noise model's draws of every source it has:
  :mod:`~kinegrasp_env.montecarlo.noise_rows`, the rows ``kinegrasp evaluate --robot
  --noise-spec`` draws with the same seed), the hand at its pre-shape;
- **score** (:data:`SCORES`, the names of ``kinegrasp rank --criterion``): ``pfc`` (the
  draws' P(force closure)), ``hold_static`` (the fraction the static hold check holds:
  :mod:`~kinegrasp_env.montecarlo.hold_check`), ``hold`` (the fraction the quick holding
  test holds in pybullet or MuJoCo: :func:`~kinegrasp_env.montecarlo.hold_engine.
  quick_hold_engine`) or ``hold_margin`` (the mean of that test's margins, how far each draw
  got through it: :func:`~kinegrasp_env.physics.protocol.hold_margin`; a graded reward,
  whose physics closings also give the step's P(FC); joint and hand noise, and tens of
  milliseconds a draw, where the kinematic engines take microseconds to milliseconds);
- **observation** (:mod:`~kinegrasp_env.envs.observation`): ``2 * arm_dof + hand_dof + 23``
  entries (44 for the default robot, 38 for the Panda);
- **pictures**: the whole URDF (arm and hand, its visual geometry) and the object in a
  pybullet world of their own (:class:`~kinegrasp_env.envs.render.SceneViewer`).

A step's n draws are the first n rows of a run of a seed the env draws from its generator
(the rows ``kinegrasp evaluate --robot NAME`` draws with that seed), so the same seed gives
the same reward.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.envs.observation import OBS_EXTRA, ArmObserver
from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES
from kinegrasp_env.montecarlo.evaluate import ENGINES, RobotEngine, make_engine
from kinegrasp_env.montecarlo.noise_rows import check_robot_noise, model_rows
from kinegrasp_env.physics.simulators import SIMULATORS, check_simulator
from kinegrasp_env.robot.branch_motion import elbow_motion
from kinegrasp_env.robot.catalog import load_robot
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.grasps import (
    Grasp,
    NoGraspSetError,
    load_grasps,
    plan_command,
    shipped_grasps,
    shipped_objects,
)
from kinegrasp_env.world.objects import load_object

#: Reward draws per step by default, every robot (what they cost per step with each engine:
#: ``python benchmarks/bench_env.py``).
N_DRAWS = 64
#: What the reward scores (module docstring): the criteria of ``kinegrasp rank`` that a
#: step's draws give.
SCORES = ("pfc", "hold_static", "hold", "hold_margin")
#: The scores that run the quick holding test on every draw.
HOLD_TEST_SCORES = ("hold", "hold_margin")
#: Each score's estimate among a step's statistics (:func:`step_stats`).
SCORE_KEYS = {"pfc": "p_fc", "hold_static": "p_hold", "hold": "p_hold",
              "hold_margin": "hold_margin"}


def step_stats(outcome: np.ndarray, quality: np.ndarray, held: np.ndarray | None,
               seed: int, margin: np.ndarray | None = None, score: str = "pfc") -> dict:
    """A step's reward terms from its n draws: ``p_fc`` and its Wilson interval, ``q_mean``
    (over the force-closure draws; 0 without one), ``outcomes`` (counts by name), ``draws``,
    ``draw_seed``, for a hold score (``held`` (n,), else None) ``p_hold`` and its interval,
    with the holding test's margins (``margin`` (n,), else None) their mean ``hold_margin``,
    and ``score_value``: the estimate of ``score`` (:data:`SCORE_KEYS`).

    Args:
        outcome: (n,) indices into :data:`~kinegrasp_env.montecarlo.draws.OUTCOMES`;
        quality: (n,) Q; seed: the draws' seed.
    """
    fc = outcome == FORCE_CLOSURE
    counts = np.bincount(outcome, minlength=len(OUTCOMES))
    stats = {"p_fc": float(fc.mean()), "p_fc_ci": wilson_interval(int(fc.sum()), fc.size),
             "q_mean": float(quality[fc].mean()) if fc.any() else 0.0,
             "draws": int(outcome.size), "draw_seed": seed,
             "outcomes": {name: int(c) for name, c in zip(OUTCOMES, counts, strict=True)}}
    if held is not None:
        stats.update(p_hold=float(held.mean()),
                     p_hold_ci=wilson_interval(int(held.sum()), held.size))
    if margin is not None:
        stats["hold_margin"] = float(np.mean(margin))
    stats["score_value"] = stats[SCORE_KEYS[score]]
    return stats


def check_grasps_robot(grasps: list[Grasp], robot: str, source) -> None:
    """ValueError (one line) when a grasp of ``source`` is a grasp of another robot."""
    other = next((g for g in grasps if g.robot != robot), None)
    if other is not None:
        raise ValueError(f"{source} holds grasps of robot {other.robot!r}; make the env with "
                         f"robot={other.robot!r} (this one is {robot!r})")


def file_grasps(grasp_file: str) -> list[Grasp]:
    """The grasps of a grasp file; ValueError (one line) for a file of none."""
    grasps = load_grasps(grasp_file)
    if not grasps:
        raise ValueError(f"{grasp_file} holds no grasp")
    return grasps


def grasp_file_robot(grasp_file: str) -> str:
    """The robot of a grasp file's grasps (its first grasp's; :func:`robot_tasks` checks that
    every grasp is of the env's robot)."""
    return file_grasps(grasp_file)[0].robot


def robot_tasks(robot: str, objects, grasp_file: str | None) -> dict[str, list[Grasp]]:
    """object -> grasps of ``robot``: from ``grasp_file`` or the shipped sets.

    Raises:
        ValueError: no grasps for an object, grasps of another robot.
    """
    if grasp_file is not None:
        grasps = file_grasps(grasp_file)
        check_grasps_robot(grasps, robot, grasp_file)
        names = tuple(objects) if objects else tuple(sorted({g.object for g in grasps}))
        tasks = {name: [g for g in grasps if g.object == name] for name in names}
        empty = [name for name, gs in tasks.items() if not gs]
        if empty:
            raise ValueError(f"{grasp_file} has no grasp of {empty[0]!r}")
        return tasks
    names = tuple(objects) if objects else shipped_objects(robot)
    if not names:
        raise ValueError(f"robot {robot!r} has no shipped grasps; give a grasp_file "
                         f"(kinegrasp plan --robot {robot})")
    tasks = {}
    for name in names:
        try:
            tasks[name] = shipped_grasps(name, robot)
        except NoGraspSetError as exc:  # the advice worded for the env
            raise ValueError(
                f"{exc.reason}; plan grasps (`{plan_command(robot, name, out=True)}`) and give "
                f"the env that file: grasp_file='{name}_grasps.json'") from None
    return tasks


class RobotTask:
    """The robot-specific pieces of the env (module docstring).

    Speed (``python benchmarks/bench_env.py``): see the benchmarks page; per step, the
    self-motion's cost grows with the elbow angle moved, and the draws are much cheaper with
    the fast engine than with the reference.

    Args:
        robot: a catalog robot.
        engine: the reward draws' engine by name: ``fast``, ``pybullet`` or ``physics``
            (:data:`~kinegrasp_env.montecarlo.evaluate.ENGINES`).
        score: what the reward scores (:data:`SCORES`).
        hold_simulator: where the ``hold`` score's holding test runs (``pybullet`` or
            ``mujoco``).

    Raises:
        ValueError: an unknown engine, score or simulator (one line naming it and the known
            ones), or a simulator whose package is not installed.
    """

    def __init__(self, robot: str, engine: str = "fast", score: str = "pfc",
                 hold_simulator: str = "pybullet") -> None:
        if engine not in ENGINES:
            raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
        if score not in SCORES:
            raise ValueError(f"score must be one of {', '.join(SCORES)}, got {score!r}")
        if hold_simulator not in SIMULATORS:
            raise ValueError(f"hold_simulator must be one of "
                             f"{', '.join(SIMULATORS)}, got {hold_simulator!r}")
        if score in HOLD_TEST_SCORES:
            check_simulator(hold_simulator)
        self.engine_name, self.score, self.hold_simulator = engine, score, hold_simulator
        self.description: RobotDescription = load_robot(robot)
        self.arm = self.description.arm_dof
        self.motion = elbow_motion(self.description)
        self.kin = self.motion.kin
        self.obs_size = 2 * self.arm + len(self.description.hand_joints) + OBS_EXTRA
        self._engines: dict[tuple[str, bool], RobotEngine] = {}  # (object, holding test)
        self.observer = ArmObserver(self.kin, self.description.palm_link, self.arm,
                                    self.motion.angle_links, self.motion.elbow_angle)

    def engine(self, object_name: str) -> RobotEngine:
        """The reward's engine of ``object_name`` (built on first use and kept: a pybullet
        world, or the fast engine's distance grid and compiled kernels); for the ``hold``
        score the quick holding test's."""
        test = self.score in HOLD_TEST_SCORES
        key = (object_name, test)
        if key not in self._engines:
            if test:
                from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine

                engine = quick_hold_engine(self.description, object_name,
                                           simulator=self.hold_simulator)
            else:
                engine = make_engine(self.engine_name, self.description, object_name,
                                     static_hold=self.score == "hold_static")
            self._engines[key] = engine
        return self._engines[key]

    def closing_engine(self, object_name: str) -> RobotEngine:
        """The engine ``engine`` names, of ``object_name`` (a task's nominal
        closing): the reward's, unless the score runs the holding test."""
        if self.score not in HOLD_TEST_SCORES:
            return self.engine(object_name)
        key = (object_name, False)
        if key not in self._engines:
            self._engines[key] = make_engine(self.engine_name, self.description, object_name)
        return self._engines[key]

    def close(self) -> None:
        for engine in self._engines.values():
            engine.close()
        self._engines.clear()

    def check_noise(self, noise: JointNoise | NoiseModel) -> None:
        """ValueError (one line) for a noise model this robot's draws or score cannot take
        (:func:`~kinegrasp_env.montecarlo.noise_rows.check_robot_noise`; the ``hold`` score
        takes joint and hand noise: :func:`~kinegrasp_env.montecarlo.draw_holds.
        check_hold_noise`)."""
        if not isinstance(noise, NoiseModel):
            return
        check_robot_noise(noise, self.description, self.arm, self.engine_name,
                          static_hold=self.score == "hold_static")
        if self.score in HOLD_TEST_SCORES:
            from kinegrasp_env.montecarlo.draw_holds import check_hold_noise

            check_hold_noise(noise, self.description.name,
                             f"score {self.score!r} (the holding test)")

    def draw_rows(self, grasp: Grasp, q: np.ndarray, noise: JointNoise | NoiseModel,
                  seed: int, n_draws: int) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """(configurations (n_draws, dof), per-draw errors as an engine's ``run`` takes
        them): q (dof,) with the arm joints' errors of ``noise``: rows 0 .. n_draws of a run of
        ``seed`` (the same rows for every engine, and an evaluation's), the hand at q's
        pre-shape; a noise model's other sources
        (:func:`~kinegrasp_env.montecarlo.noise_rows.model_rows`)."""
        if isinstance(noise, NoiseModel):
            return model_rows(noise, q, self.description, seed, 0, n_draws,
                              load_object(grasp.object).center_of_mass)
        return chunk_configurations(np.asarray(q, float), self.arm, noise.sigma, noise.kind,
                                    seed, 0, n_draws), {}

    def estimate(self, grasp: Grasp, q: np.ndarray, noise: JointNoise | NoiseModel,
                 seed: int, n_draws: int) -> dict:
        """``n_draws`` draws of the task's engine at q (dof,) (:meth:`draw_rows`); the
        reward's statistics: P(FC), its Wilson interval, mean Q over the force-closure
        draws, outcome counts, for a hold score ``p_hold`` and its interval, with the holding
        test the mean margin ``hold_margin``; ``score_value``: the score's estimate."""
        rows, errors = self.draw_rows(grasp, q, noise, seed, n_draws)
        engine = self.engine(grasp.object)
        held = margin = None
        if self.score in HOLD_TEST_SCORES:
            from kinegrasp_env.physics.protocol import HELD

            draws, hold = engine.run_hold(rows)
            held, margin = hold.outcome == HELD, hold.margin(engine.protocol)
        else:
            draws = engine.run(rows, **errors)
            if self.score == "hold_static":
                held = draws.holds
        return step_stats(draws.outcome, draws.quality, held, seed, margin, self.score)
