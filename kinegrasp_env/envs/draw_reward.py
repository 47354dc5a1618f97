"""The default robot's reward from Monte Carlo draws at the env's configuration: P(FC), the
mean Q of the force-closure draws and the outcome counts of a step's draws, and with a hold
score (``score``) that score's P(hold) on the same draws (the static hold check their engine
runs, or the quick holding test of :mod:`~kinegrasp_env.montecarlo.draw_holds` on the draws'
configurations).

A step's n draws are the first n rows of a run of a seed the env draws from its generator
(:func:`~kinegrasp_env.montecarlo.evaluate.draw_rows`: an evaluation's draws of that seed),
so the same seed gives the same reward.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE, OUTCOMES, Engine, cached_engine
from kinegrasp_env.montecarlo.evaluate import DEFAULT_CHUNK, draw_rows
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.world.grasps import Grasp

__all__ = ["DrawReward", "step_stats"]


def step_stats(outcome: np.ndarray, quality: np.ndarray, held: np.ndarray | None,
               seed: int) -> dict:
    """A step's reward terms from its n draws (any robot): ``p_fc`` and its Wilson interval,
    ``q_mean`` (over the force-closure draws; 0 without one), ``outcomes`` (counts by name),
    ``draws``, ``draw_seed``, for a hold score (``held`` (n,), else None) ``p_hold`` and its
    interval, and ``score_value``: the score's estimate.

    Args:
        outcome: (n,) indices into :data:`~kinegrasp_env.montecarlo.engines.OUTCOMES`;
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
    stats["score_value"] = stats["p_fc" if held is None else "p_hold"]
    return stats


class DrawReward:
    """The draws' reward terms of the default robot (module docstring).

    Args:
        engine: the engine's name (``fast``, ``pybullet``, ``physics``).
        score: ``pfc``, ``hold_static`` or ``hold``.
        hold_simulator: where the ``hold`` score's holding test runs.
    """

    def __init__(self, engine: str, score: str, hold_simulator: str = "pybullet") -> None:
        self.engine_name, self.score, self.hold_simulator = engine, score, hold_simulator
        self._engines: dict[tuple, Engine] = {}
        self._hold_scores: dict[str, object] = {}

    def engine(self, object_name: str) -> Engine:
        """The engine on ``object_name``, built once (a fresh one after a re-import)."""
        return cached_engine(self._engines, self.engine_name, object_name,
                             static_hold=self.score == "hold_static")

    def hold_score(self, object_name: str):
        """The quick holding test on ``object_name``, built once (the static hold check comes
        with the engine's draws)."""
        from kinegrasp_env.montecarlo.draw_holds import QuickHoldTest

        if object_name not in self._hold_scores:
            self._hold_scores[object_name] = QuickHoldTest(object_name,
                                                           simulator=self.hold_simulator)
        return self._hold_scores[object_name]

    def estimate(self, grasp: Grasp, q: np.ndarray, noise, seed: int, n: int) -> dict:
        """The reward terms of n draws of ``noise`` at configuration q (14,), seed ``seed``:
        ``p_fc`` and its Wilson interval, ``q_mean``, ``outcomes``, ``draws``, ``draw_seed``,
        ``score_value`` (the score's estimate), and for a hold score ``p_hold`` and its
        interval."""
        draws = draw_rows(self.engine(grasp.object), q, noise, seed, n)
        held = None
        if self.score == "hold_static":  # the engine's verdicts on the same draws
            held = draws.holds
        elif self.score != "pfc":  # the quick holding test of the same draws
            held = self.hold_score(grasp.object).chunk_held(q, noise, seed, n,
                                                            chunk=DEFAULT_CHUNK)
        return step_stats(draws.outcome, draws.quality, held, seed)

    def check_noise(self, noise) -> None:
        """ValueError (one line) for a noise model a hold score of the default robot's draws
        cannot take (:func:`~kinegrasp_env.montecarlo.draw_holds.check_hold_scores_noise`)."""
        from kinegrasp_env.montecarlo.draw_holds import check_hold_scores_noise

        check_hold_scores_noise(noise, static=self.score == "hold_static",
                                test=self.score == "hold")

    def close(self) -> None:
        for engine in self._engines.values():
            engine.close()
        self._engines.clear()
        for score in self._hold_scores.values():
            score.close()
        self._hold_scores.clear()
