"""KineGrasp-v0 and KineGraspSelect-v0: choose the elbow angle that makes a grasp robust.

A task is a grasp (object, nominal arm+hand configuration q0, hence a palm pose and nominal
contacts) and a noise: joint noise of a sigma and distribution drawn at reset, or a fixed
:class:`~kinegrasp_env.sampling.noise_model.NoiseModel` of every source of error (the
``noise_model`` argument or reset option: a model, a spec mapping or a spec file; the
observation is the same, showing the model's joint noise). The agent moves the arm along its
self-motion manifold (the palm pose, so the nominal contacts, stay fixed); the reward is
P(force closure) estimated from ``n_draws`` internal Monte Carlo draws at the current
configuration, plus ``q_weight`` times the mean Ferrari-Canny Q, minus ``limit_penalty`` when
the requested motion would leave the joint limits (the arm then stays at the last reachable
point).

Reset options (all optional): the task's object, grasp (an index into the env's grasps, a
``q0`` or a ``palm_pose``, closed once at reset) and noise, and the elbow angle ``psi`` to
start at; :mod:`kinegrasp_env.envs.task_choice` documents each one.

Observation (float32, 44 entries, every one scaled to roughly [-1, 1]):

====== ===================================================== =========================
index  entry                                                 scale
====== ===================================================== =========================
0-6    nominal arm joints q0[:7]                              / pi
7-13   hand pre-shape q0[7:]                                  / pi
14     joint noise sigma (the largest, if per joint)            / 0.05 rad
15-17  joint noise type one-hot (gaussian, uniform, triangular)  1
18-20  palm position relative to the object frame             / 0.3 m
21-26  palm orientation in the object frame (first two columns of R)  1
27-28  current elbow angle psi: sin, cos                      1
29-35  current arm joints                                     / pi
36-41  palm-pose std per unit joint noise, object frame:      / 1 (metres or radians
       sqrt(diag(J J^T)) for x, y, z, rx, ry, rz              per radian)
42     nominal Q of the grasp                                 x 10
43     fraction of the episode's steps used                   1
====== ===================================================== =========================

Action: float32 Box(-1, 1, (2,)): [change of psi in units of ``step_size`` radians,
done signal (> 0 ends the episode)]; an action of another shape, not finite or outside
[-1, 1] is a ValueError (one line naming the expected shape and range). KineGraspSelect-v0
has one step and a 1-D action: the
elbow angle psi itself, a in [-1, 1] -> psi = pi a; or, with ``action_bins=K``, Discrete(K):
k -> psi = -pi + 2 pi k / K (a categorical policy can prefer both ends of the reachable
range at once, which a Gaussian one centred between them cannot).

Robots: ``robot``, any robot of the catalog (default: the robot of ``grasp_file``'s grasps,
else ``kuka_sdh``, the paper's robot, whose
44-entry observation is tabled above; ``robot="panda"``, a user's robot): its shipped or
given grasps, its self-motion (a 6-joint arm: its IK branches as the elbow coordinate), its
engine's draws (``engine``, fast by default), an observation sized by its arm and hand, and
pictures of its whole URDF with the object (:mod:`kinegrasp_env.envs.grasp_task`); a noise
model's draws of every source; ``reward="batch"``; and a reward that scores holding
(``score``: the static hold check's or the quick holding test's P(hold) instead of P(FC)).

Every bad argument, reset option or action is a ValueError of one line naming the value.
"""

from __future__ import annotations

import math
from typing import ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from kinegrasp_env.envs.arguments import box_action, env_arguments, reset_options, reset_psi
from kinegrasp_env.envs.batch_reward import (
    BatchReward,
    batch_noise,
    batch_size_error,
    check_batch_size,
    covered_configurations,
    grasp_seed,
    sigma_levels,
)
from kinegrasp_env.envs.grasp_task import RobotTask, grasp_file_robot, robot_tasks
from kinegrasp_env.envs.render import human_window_available
from kinegrasp_env.envs.task_choice import noise_info, pick_grasp, pick_noise
from kinegrasp_env.montecarlo.palm_batch import PalmJacobian
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.robot.kinematics import Kinematics
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.sampling.noise_spec import noise_model_from
from kinegrasp_env.sampling.reweight import BatchTooSmall
from kinegrasp_env.world.grasps import Grasp

OBS_LIMIT = 10.0


class KineGraspEnv(gym.Env):
    """Move the elbow along the self-motion to make a grasp robust to joint noise.

    Args:
        objects: objects to draw tasks from, built-in or imported (default: every built-in
            one, or with ``grasp_file`` every object of the file). An imported object has no
            shipped grasp set: give it with ``grasp_file`` (e.g. ``kinegrasp plan``'s output),
            or give its task at reset (``options={"object": name, "q0": [...]}`` or
            ``"palm_pose"``: see the module docstring), which works with any object.
        grasp_file: a grasp file to draw tasks from instead of the shipped sets.
        sigma_range: (low, high) of the noise sigma drawn at reset (radians).
        noise_types: noise distributions drawn at reset.
        n_draws: Monte Carlo draws per reward (an integer >= 1; default 64).
        q_weight: weight of the mean Q in the reward.
        limit_penalty: subtracted when an action would leave the joint limits.
        max_steps: steps before truncation.
        step_size: radians of psi per unit action.
        render_mode: None, ``rgb_array`` ((240, 320, 3) uint8 pictures of the whole robot at
            its current configuration and the object, from pybullet's CPU renderer in a
            world of the env's own; any robot of the catalog) or ``human`` (a pybullet GUI
            window). Where no
            display can show a window (Linux without a reachable ``$DISPLAY``), ``human``
            warns once (:class:`~kinegrasp_env.envs.render.NoDisplayWarning`) and renders
            nothing (``render()`` returns None, as in human mode) instead of letting
            pybullet end the process.
        split: ``train`` (grasp indices i % 4 != 3), ``test`` (i % 4 == 3, held out) or None
            (all grasps).
        engine: the engine of the reward's draws, by name
            (:func:`~kinegrasp_env.montecarlo.evaluate.make_engine`): ``fast`` (the
            default: the reference closing batched over the draws, many times the steps per
            second: ``benchmarks/bench_env.py``), ``pybullet`` (the reference: pybullet
            closest points, draw by draw) or ``physics`` (pybullet dynamics). Both kinematic
            engines take the same draws for the same seed; on the Panda's env rewards of 16
            draws their P(FC) differed by one draw in 1 of 240 steps (seeds 0-23;
            ``tests/test_env_robot.py``).
        reward: ``draws`` (each step: ``n_draws`` fresh Monte Carlo draws) or ``batch`` (any
            robot, with zero-mean Gaussian joint noise, a noise model's included, with
            Gaussian palm noise beside it or without: one batch of ``batch_size``
            closings per grasp, kept across episodes, re-weighted to each step's
            configuration and sigma, :mod:`~kinegrasp_env.envs.batch_reward`; other noise,
            a step whose configuration starts in collision or whose effective sample size
            is below ``n_draws`` takes draws;
            ``info["reward_method"]`` says which).
        batch_size: the closings of a ``batch`` reward's grasp batch: an integer, at least
            one per target it covers beside its defensive share (50 for a 7-joint arm at
            five noise levels; a smaller one is refused here, naming the least).
        noise_model: every task's noise instead of the drawn joint noise: a
            :class:`~kinegrasp_env.sampling.noise_model.NoiseModel`, a spec mapping or a spec
            file (YAML/JSON); the observation shows its joint sigma and distribution.
        robot: a catalog robot (default: the robot of ``grasp_file``'s grasps, else
            ``kuka_sdh``); an unknown name is a ValueError listing the known ones. Another
            robot: see the module docstring.
        score: what the reward scores: ``pfc`` (P(force closure)), ``hold_static`` (the
            static hold check's P(hold) on the same draws), ``hold`` (the quick holding
            test's, in ``hold_simulator``: slow; joint and hand noise only) or
            ``hold_margin`` (the mean of that test's margins: how far each draw got through
            it, in [0, 1]; ``info["hold_margin"]`` with either)
            (:data:`~kinegrasp_env.envs.grasp_task.SCORES`); ``info["score"]`` names it,
            ``info["p_hold"]`` holds a hold score's estimate.
        hold_simulator: the quick holding test's simulator, ``pybullet`` (default) or
            ``mujoco``.
    """

    metadata: ClassVar[dict] = {"render_modes": ["rgb_array", "human"], "render_fps": 4}

    def __init__(self, objects: tuple[str, ...] | None = None, grasp_file: str | None = None,
                 sigma_range: tuple[float, float] = (0.0033, 0.0333),
                 noise_types: tuple[str, ...] = ("gaussian",), n_draws: int | None = None,
                 q_weight: float = 0.0, limit_penalty: float = 0.1, max_steps: int = 10,
                 step_size: float = 0.3, render_mode: str | None = None,
                 split: str | None = None, engine: str | None = None,
                 noise_model: NoiseModel | dict | str | None = None,
                 robot: str | None = None, reward: str = "draws",
                 batch_size: int = 4096, score: str = "pfc",
                 hold_simulator: str = "pybullet") -> None:
        super().__init__()
        if robot is None:  # the grasp file's robot, as the commands take it, else the default
            robot = DEFAULT_ROBOT if grasp_file is None else grasp_file_robot(grasp_file)
        args = env_arguments(
            robot=robot, n_draws=n_draws, engine=engine, score=score, render_mode=render_mode,
            render_modes=self.metadata["render_modes"], reward=reward,
            hold_simulator=hold_simulator, batch_size=batch_size, max_steps=max_steps,
            sigma_range=sigma_range, noise_types=noise_types, q_weight=q_weight,
            limit_penalty=limit_penalty, step_size=step_size, split=split, objects=objects)
        self.robot = args.robot
        self.tasks = robot_tasks(args.robot, args.objects, grasp_file)
        if args.split is not None:
            keep = (lambda i: i % 4 == 3) if args.split == "test" else (lambda i: i % 4 != 3)
            self.tasks = {name: [g for i, g in enumerate(gs) if keep(i)]
                          for name, gs in self.tasks.items()}
        self.object_names = tuple(sorted(self.tasks))
        self.sigma_range = args.sigma_range
        self.noise_types = args.noise_types
        self.n_draws = args.n_draws
        self.q_weight = args.q_weight
        self.limit_penalty = args.limit_penalty
        self.max_steps = args.max_steps
        self.step_size = args.step_size
        self.render_mode = args.render_mode
        self._window = self.render_mode == "human" and human_window_available()
        self._robot = RobotTask(args.robot, args.engine, args.score, args.hold_simulator)
        self.score = args.score
        self.observation_space = spaces.Box(-OBS_LIMIT, OBS_LIMIT, (self._robot.obs_size,),
                                            np.float32)
        self.action_space = self._action_space()
        self.engine = args.engine
        self.reward_method, self.batch_size = args.reward, args.batch_size
        self._batch: BatchReward | None = None
        #: the episode's noise as the batch re-weights it (:func:`~kinegrasp_env.envs.
        #: batch_reward.batch_noise`; None: the steps take draws), set at each reset
        self._batch_noise: tuple[np.ndarray, np.ndarray] | None = None
        self._batches: dict[tuple, BatchReward] = {}  # per grasp, kept across episodes
        self._jacobian = None
        if args.reward == "batch":
            check_batch_size(args.batch_size, self._robot.description.has_self_motion,
                             args.sigma_range)
            self._jacobian = PalmJacobian(self._robot.description)
        self.noise_model = None if noise_model is None else noise_model_from(noise_model)
        if self.noise_model is not None:
            self._robot.check_noise(self.noise_model)
        self._viewer = None
        self.grasp: Grasp | None = None
        #: the episode ended (terminated or truncated): step() needs a reset() first
        self.ended = False
        self.q = None
        self._psi = 0.0  # elbow angle of self.q (radians), set by every observation
        #: an arm without self-motion: the IK-branch coordinate moved to (radians, wrapped),
        #: which the observation shows (the branch's bin holds it); else None
        self._branch_psi: float | None = None
        self.steps = 0

    def _action_space(self) -> spaces.Box:
        return spaces.Box(-1.0, 1.0, (2,), np.float32)

    # ------------------------------------------------------------------ helpers
    @property
    def kinematics(self) -> Kinematics:
        """The batched kinematics of the arm and hand (FK, Jacobians)."""
        return self._robot.kin

    @property
    def self_motion(self):
        """The arm's elbow coordinate: a 7-joint arm's
        :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion`, a 6-joint arm's IK branches
        (:class:`~kinegrasp_env.robot.branch_motion.BranchMotion`); elbow angles in
        radians."""
        return self._robot.motion

    def elbow_angle(self, q: np.ndarray) -> float:
        """The elbow angle psi (radians) of configuration q (dof,) of the env's robot: along
        a 7-joint arm's self-motion, or a 6-joint arm's branch coordinate (the centre of its
        IK branch's bin), as :meth:`configuration_at` takes it."""
        return float(self._robot.motion.elbow_angle(np.asarray(q, dtype=float)[None])[0])

    def configuration_at(self, psi: float,
                         start: np.ndarray | None = None) -> tuple[np.ndarray, bool]:
        """The arm moved along its self-motion to elbow angle ``psi`` (radians).

        Args:
            psi: target elbow angle, radians.
            start: (dof,) configuration whose palm pose is kept (default: the current one).

        Returns:
            (q (dof,), reached): the configuration, and whether it reached ``psi`` within the
            joint limits (when not, the arm stops at the last continuation step within
            them, up to one step, 0.3 rad of psi, short of the limit, where depending on
            ``psi``). The env's state is unchanged.
        """
        q = self.q if start is None else np.asarray(start, dtype=float)
        return self._robot.motion.set_elbow_angle(q, psi)

    def _pick_task(self, options: dict) -> tuple[Grasp, JointNoise | NoiseModel]:
        """The episode's grasp and noise, drawn with the env's RNG where the options leave
        them open (:mod:`kinegrasp_env.envs.task_choice`)."""
        grasp = pick_grasp(options, self.np_random, self.tasks, self.object_names, self._robot)
        return grasp, pick_noise(options, self.np_random, self.sigma_range, self.noise_types,
                                 self.noise_model, self._robot.check_noise)

    def _observation(self) -> np.ndarray:
        obs, self._psi = self._robot.observer.observe(self.grasp, self.q, self.noise,
                                      self.steps / self.max_steps, self._branch_psi)
        return np.clip(obs, -OBS_LIMIT, OBS_LIMIT).astype(np.float32)

    def _estimate(self) -> dict:
        """The episode's batch re-weighted to the current configuration (``reward="batch"``),
        else Monte Carlo draws at it, seeded from the env's RNG (also at sigma 0: no
        deviation to re-weight, the one draw's outcome is the answer)."""
        if self._batch is not None and not self._starts_in_collision():
            found = self._batch.estimate(self.q, self._batch_noise, self.n_draws)
            if found is not None:
                return found
        seed = int(self.np_random.integers(2**31 - 1))
        return {**self._robot.estimate(self.grasp, self.q, self.noise, seed, self.n_draws),
                "reward_method": "draws"}

    def _starts_in_collision(self) -> bool:
        """Whether the current configuration starts in collision (an arm link in the object
        or the table at another elbow angle or IK branch: the engine's start-collision test,
        ``starts_in_collision``): the batch, closed with the arm where the grasp's own
        configuration puts it, does not stand for it."""
        engine = self._robot.closing_engine(self.grasp.object)
        return bool(engine.starts_in_collision(self.q[None])[0])

    def _episode_batch(self) -> BatchReward | None:
        """The grasp's batch (``reward="batch"`` with Gaussian noise:
        :func:`~kinegrasp_env.envs.batch_reward.batch_noise`), built at the grasp's first
        episode and kept; else None."""
        if self._batch_noise is None or max(self.sigma_range) <= 0:  # no level to draw at
            return None
        grasp = self.grasp
        key = (grasp.object, str(grasp.id), tuple(np.round(grasp.palm_pose, 9).ravel()))
        if key not in self._batches:
            q0 = np.asarray(grasp.q0, dtype=float)
            try:
                self._batches[key] = BatchReward.build(
                    self.engine, grasp.object, q0, self._covered_configurations(q0),
                    sigma_levels(*self.sigma_range), self.batch_size, grasp_seed(key),
                    self._jacobian, robot=self.robot)
            except BatchTooSmall as exc:  # a 6-joint arm's branches: known only here
                raise batch_size_error(self.batch_size, f"{grasp.object} grasp {grasp.id}",
                                       exc) from None
        return self._batches[key]

    def _covered_configurations(self, q0: np.ndarray) -> list[np.ndarray]:
        """The configurations (each (dof,): q0's palm pose) a grasp's batch covers besides
        q0 (dof,): :func:`~kinegrasp_env.envs.batch_reward.covered_configurations`."""
        return covered_configurations(q0, self._robot.motion)

    def _move_to(self, psi: float) -> bool:
        self.q, reached = self.configuration_at(psi)
        if self._branches:
            self._branch_psi = (psi + math.pi) % (2.0 * math.pi) - math.pi
        return reached

    @property
    def _branches(self) -> bool:
        """Whether the arm's elbow coordinate is its IK branches (no self-motion)."""
        return self._robot.motion.angle_links is None

    def _reward(self, within_limits: bool) -> tuple[float, dict]:
        info = self._estimate()
        penalty = 0.0 if within_limits else self.limit_penalty
        reward = info["score_value"] + self.q_weight * info["q_mean"] - penalty
        info.update({"score": self.score, "reward_score": info.pop("score_value"),
                     "reward_q": self.q_weight * info["q_mean"],
                     "reward_limit_penalty": -penalty, "within_limits": within_limits,
                     "elbow_angle": self._psi,
                     "object": self.grasp.object, "grasp": self.grasp.id,
                     **noise_info(self.noise, self._robot.arm)})
        return float(reward), info

    # ------------------------------------------------------------------ gymnasium API
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        options = reset_options(options)
        self.grasp, self.noise = self._pick_task(options)
        self.q = self.grasp.q0.copy()
        self.steps = 0
        self.ended = False
        self._branch_psi = None
        if options.get("psi") is not None:
            self._move_to(reset_psi(options["psi"]))
        psi0 = (self._branch_psi if self._branch_psi is not None
                else self.elbow_angle(self.q))
        self._batch_noise = (batch_noise(self.noise, self._robot.arm)
                             if self.reward_method == "batch" else None)
        self._batch = self._episode_batch()
        info = {"object": self.grasp.object, "grasp": self.grasp.id, "robot": self.robot,
                **noise_info(self.noise, self._robot.arm), "elbow_angle": psi0}
        return self._observation(), info

    def check_running(self) -> None:
        """RuntimeError unless an episode is running: before the first reset(), and after an
        episode ended (terminated or truncated: a step would move on from an episode the
        agent was told is over)."""
        if self.grasp is None:
            raise RuntimeError("call reset() before step()")
        if self.ended:
            raise RuntimeError("the episode has ended (terminated or truncated): call reset() "
                               "before step()")

    def step(self, action):
        self.check_running()
        action = box_action(action, (2,), "change of the elbow angle in units of step_size, "
                            "done signal: > 0 ends the episode")
        # the current elbow angle: the one the last observation computed (self._psi)
        within = self._move_to(self._psi + self.step_size * float(action[0]))
        self.steps += 1
        observation = self._observation()  # (sets self._psi to the new configuration's)
        reward, info = self._reward(within)
        terminated = bool(action[1] > 0.0)
        truncated = self.steps >= self.max_steps and not terminated
        self.ended = terminated or truncated
        return observation, reward, terminated, truncated, info

    def render(self):
        if self.render_mode is None or self.grasp is None:
            return None
        if self.render_mode == "human" and not self._window:
            return None  # no display: warned at construction, nothing to show
        from kinegrasp_env.envs.render import render_scene

        image, self._viewer = render_scene(
            self.grasp.object, self.q, self._viewer, gui=self.render_mode == "human",
            robot=self._robot.description)
        return image if self.render_mode == "rgb_array" else None

    def close(self) -> None:
        self._robot.close()
        if self._viewer is not None:
            self._viewer.close()
            self._viewer = None

