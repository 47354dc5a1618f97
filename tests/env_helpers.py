"""The reward of a step computed again, independently of the env, from what it reports."""

from __future__ import annotations

import pytest

from kinegrasp_env.montecarlo.evaluate import evaluate_grasp
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.world.grasps import Grasp


def check_reward_is_the_evaluation(env, reward: float, info: dict) -> None:
    """The step's reward is P(FC) of ``evaluate_grasp`` at the env's current configuration
    (the task's grasp with q0 = env.q) with the draw seed, draw count and engine the env
    reports (the evaluation's own chunks: a step's n draws are its first n), plus the stated
    penalty and Q terms; and P(FC) is the force-closure share of
    the step's outcome counts. A wrong configuration, seed, draw count, engine or reward
    formula in the env fails it."""
    g = env.grasp
    here = Grasp(g.object, env.q.copy(), g.palm_pose, g.points, g.normals, g.fingers, g.links,
                 g.q_nominal, robot=g.robot)
    noise = ({"sigma": 0.0, "noise_model": env.noise} if isinstance(env.noise, NoiseModel)
             else {"sigma": env.noise.sigma, "noise": env.noise.kind})
    stats = evaluate_grasp(here, **noise, n=env.n_draws, seed=info["draw_seed"],
                           engine=env.engine)
    assert sum(info["outcomes"].values()) == env.n_draws
    assert info["p_fc"] == stats.p_fc == info["outcomes"]["force_closure"] / env.n_draws
    q_term = env.q_weight * stats.q_mean if env.q_weight else 0.0  # q_mean: NaN without FC
    assert reward == pytest.approx(stats.p_fc + q_term + info["reward_limit_penalty"],
                                   abs=1e-12)
