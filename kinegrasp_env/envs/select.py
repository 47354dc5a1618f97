"""KineGraspSelect-v0: one step, the elbow angle psi itself as the action (see
:mod:`kinegrasp_env.envs.kinegrasp` for the tasks, the observation and the reward)."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from kinegrasp_env.envs.arguments import box_action
from kinegrasp_env.envs.kinegrasp import KineGraspEnv


class KineGraspSelectEnv(KineGraspEnv):
    """One step: pick the elbow angle psi = pi * action[0], receive P(FC) there.

    Args:
        action_bins: if given, the action is Discrete(action_bins): bin k is the elbow angle
            psi = -pi + 2 pi k / action_bins.
        **kwargs: as :class:`KineGraspEnv`.
    """

    def __init__(self, action_bins: int | None = None, **kwargs) -> None:
        if action_bins is not None and (isinstance(action_bins, bool)
                                        or not isinstance(action_bins, (int, np.integer))
                                        or action_bins < 2):
            raise ValueError(f"action_bins must be an integer >= 2, got {action_bins!r}")
        self.action_bins = None if action_bins is None else int(action_bins)
        kwargs.setdefault("max_steps", 1)
        super().__init__(**kwargs)

    def _action_space(self) -> spaces.Space:
        if self.action_bins is not None:
            return spaces.Discrete(self.action_bins)
        return spaces.Box(-1.0, 1.0, (1,), np.float32)

    def action_angle(self, action) -> float:
        """The elbow angle psi (radians) an action asks for."""
        if self.action_bins is not None:
            k = np.asarray(action)
            if k.shape not in ((), (1,)) or not np.issubdtype(k.dtype, np.integer) \
                    or not 0 <= int(k.ravel()[0]) < self.action_bins:
                raise ValueError(f"action {action!r} outside Discrete({self.action_bins}): the "
                                 f"action must be an integer in 0..{self.action_bins - 1} (bin "
                                 f"k is the elbow angle -pi + 2 pi k / {self.action_bins})")
            return -math.pi + 2.0 * math.pi * int(k.ravel()[0]) / self.action_bins
        action = box_action(action, (1,), "the elbow angle psi = pi * action[0]")
        return math.pi * float(action[0])

    def step(self, action):
        self.check_running()
        within = self._move_to(self.action_angle(action))
        self.steps += 1
        observation = self._observation()  # (sets self._psi, which the reward's info reports)
        reward, info = self._reward(within)
        self.ended = True  # one step an episode
        return observation, reward, True, False, info
