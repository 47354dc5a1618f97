"""``kinegrasp rank`` of any robot's grasps: the candidates checked, and the
evaluator that :mod:`kinegrasp_env.cli.ranking` ranks them with (fixed-n, resumable, or
adaptive), its draws in chunks on the command's executor
(:mod:`~kinegrasp_env.montecarlo.chunks`: the same draws whatever the processes or
backend), each candidate on the same rows of the seed's chunked streams (common noise),
with the hold scores where asked."""

from __future__ import annotations

import dataclasses
import sys

from kinegrasp_env.cli.common import check_spec_noise, reported
from kinegrasp_env.cli.evaluation import check_hold_simulator, check_robot_engine


def check_candidates(args, grasps: list, robot: str, noise) -> None:
    """A robot's candidates (each a grasp of ``robot``, of any catalog objects),
    and the options and the noise (``--noise-spec``'s model, or joint noise) its ranking
    takes; CLIError lines otherwise."""
    from kinegrasp_env.montecarlo.evaluate import check_robot
    from kinegrasp_env.toolkit.ranking import HOLD_TEST_CRITERIA

    test = args.criterion in HOLD_TEST_CRITERIA
    if test:
        from kinegrasp_env.montecarlo.draw_holds import check_hold_noise

        with reported(ValueError):
            check_hold_noise(noise, robot, f"--criterion {args.criterion} (the holding test)")
    check_hold_simulator(args, test, "--criterion hold or hold_margin")
    check_robot_engine(args.engine, robot)
    with reported(ValueError):
        for g in grasps:
            check_robot(g, robot, "--robot")
    if args.noise_spec:
        check_spec_noise(args, noise, robot, args.engine,
                         bool(args.static_hold) or args.criterion == "hold_static")



class RankingDraws:
    """``rank``'s evaluator of any robot's candidates (see
    :data:`kinegrasp_env.toolkit.ranking.Evaluator`): chunks ``first .. first + count`` of
    ``layout`` of candidate ``index`` closed on ``executor``; each draw's outcome and the
    hold scores are added to ``side[index]`` (a
    :class:`~kinegrasp_env.toolkit.ranking.CandidateResult`).

    Args:
        grasps: the candidates; robot: the catalog robot; sigma, noise, seed: the joint noise.
        engine, friction: the engine's name and the contacts' mu.
        static_hold: run the static hold check on every draw; hold_test: the quick holding
            test in ``hold_simulator`` on every draw (in this process).
        layout: the chunk sizes of one candidate's draws.
        model: the ``--noise-spec`` model (every source; replaces sigma and noise), or None.
        criterion: the ranking's criterion (a hold criterion: an adaptive run's paired
            successes are its score's holds).
    """

    def __init__(self, grasps: list, robot: str, *, sigma, noise: str, seed: int,
                 engine: str, friction: float, static_hold: bool, hold_test: bool,
                 layout: list[int], executor, side: dict, model=None,
                 hold_simulator: str = "pybullet", criterion: str = "pfc") -> None:
        import json

        from kinegrasp_env.sampling.noise_spec import spec_of

        self.model = None if model is None else json.dumps(spec_of(model))
        self.noise_model = model
        self.grasps, self.robot, self.layout = grasps, robot, layout
        self.sigma, self.noise, self.seed = sigma, noise, seed
        self.engine, self.friction, self.static_hold = engine, friction, static_hold
        self.executor, self.side = executor, side
        self.hold_test, self.hold_simulator = hold_test, hold_simulator
        self.criterion = criterion
        self.testers: dict[str, object] = {}  # the quick holding test's engine per object

    def chunk(self, index: int):
        """Candidate ``index``'s run as a :class:`~kinegrasp_env.montecarlo.chunks.
        RobotChunk` (its first row)."""
        import numpy as np

        from kinegrasp_env.montecarlo.chunks import RobotChunk

        g = self.grasps[index]
        return RobotChunk(self.robot, g.object, self.engine,
                          tuple(np.asarray(g.q0, dtype=float)), self.sigma, self.noise,
                          self.seed, 0, 0, self.friction, self.static_hold, self.model)

    def __call__(self, index: int, first: int, count: int, outcomes: bool = False):
        """(successes, trials, moments) of chunks ``first .. first + count`` of candidate
        ``index``; with ``outcomes`` each draw's success too (force closure, or the draws the
        hold criterion's score held: :func:`~kinegrasp_env.toolkit.adaptive_ranking.
        certified_successes`)."""
        from kinegrasp_env.montecarlo.chunks import chunked_draws
        from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, OUTCOMES
        from kinegrasp_env.sampling.stats import StreamingMoments
        from kinegrasp_env.toolkit.adaptive_ranking import certified_successes
        from kinegrasp_env.toolkit.ranking import CandidateResult

        offset, n = sum(self.layout[:first]), sum(self.layout[first:first + count])
        start = dataclasses.replace(self.chunk(index), offset=offset)
        draws = chunked_draws(start, n, self.executor, chunk=max(self.layout))
        fc = draws.outcome == FORCE_CLOSURE
        tally = self.side.setdefault(index, CandidateResult(index))
        tally.add_outcomes({name: int((draws.outcome == i).sum())
                            for i, name in enumerate(OUTCOMES)})
        held = {}
        if self.static_hold:
            held["static"] = draws.holds
        if self.hold_test:
            held["test"], margins = self._held(index, start, n)
            tally.add_margins(margins)
        for score, verdicts in held.items():
            tally.add_holds(score, int(verdicts.sum()), n)
        moments = StreamingMoments(1).update(draws.quality[fc])
        if outcomes:
            return certified_successes(self.criterion, fc, held, moments)
        return int(fc.sum()), n, moments

    def _held(self, index: int, start, n: int):
        """((n,) bool, (n,) float): of the draws of rows ``start.offset .. + n`` of candidate
        ``index``, those the quick holding test holds, and how far each got through it
        (:func:`~kinegrasp_env.physics.protocol.hold_margin`)."""

        from kinegrasp_env.montecarlo.chunks import chunk_rows
        from kinegrasp_env.montecarlo.hold_engine import quick_hold_engine
        from kinegrasp_env.physics.protocol import HELD

        name = self.grasps[index].object
        if name not in self.testers:
            self.testers[name] = quick_hold_engine(self.robot, name, self.friction,
                                                   self.hold_simulator)
        tester = self.testers[name]
        q = chunk_rows(dataclasses.replace(start, size=n), tester.description,  # as closed
                       tester.obj.center_of_mass, self.noise_model)[0]
        hold = tester.run_hold(q)[1]
        held = hold.outcome == HELD
        print(f"rank: candidate {self.grasps[index].id}: holding test {int(held.sum())}/{n} "
              "held", file=sys.stderr)
        return held, hold.margin(tester.protocol)

    def nominal(self, index: int) -> float:
        """Candidate ``index``'s nominal Q: its closing at q0 (no noise) by the engine."""
        from kinegrasp_env.montecarlo.chunks import nominal_closing_quality

        return nominal_closing_quality(self.chunk(index), self.executor)

    def close(self) -> None:
        from kinegrasp_env.montecarlo.chunks import close_engines

        for tester in self.testers.values():
            tester.close()
        close_engines()
