"""The two reference closings of the default robot, on the same draws: the description
robots' (:class:`~kinegrasp_env.closing.generic_reference.RobotWorld`: ``kuka_sdh.yaml`` run
as any description, pybullet's closest points far from the object, the exact pair of a
capsule link near it) against the default robot's own (:func:`~kinegrasp_env.closing.
reference.auto_close`: its hand alone in pybullet, its finger capsules placed by its own
kinematics, the exact pair near contact), the shipped grasps of the four objects, joint
noise of sigma 0.0133 rad, ``--draws`` each.

Per grasp, as ``description_agreement.py`` reports it: the share of draws with the same
outcome, the classes of the differing draws (``verdict``, ``links``, ``reach``, ``start``:
explained there), P(FC) of both with the paired difference's 95% t-interval (Bonferroni
over the grasps), the distance between the contacts of draws where the same links touch,
and the time a draw of each.

    python benchmarks/reference_agreement.py [--draws 500] [--objects cube drill ...]

The figures go to ``benchmarks/results/reference_agreement.json`` and the table to
``docs/guides/robot.md`` (``--no-json``: neither).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from description_agreement import SIGMA, compare, markdown, summarize
from results_file import add_options, publish, settings

from kinegrasp_env.montecarlo.engines import make_engine as own_engine
from kinegrasp_env.montecarlo.robot_engines import make_engine

DOC = Path(__file__).resolve().parents[1] / "docs" / "guides" / "robot.md"
START, END = "<!-- reference-agreement:start -->", "<!-- reference-agreement:end -->"
#: The two closings' names in the figures: the description robots' reference, the default
#: robot's own.
NAMES = ("description", "own")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "drill", "mug", "spray_flask"])
    parser.add_argument("--draws", type=int, default=500)
    add_options(parser, __file__)
    args = parser.parse_args()
    rows = compare(args.objects, lambda obj: (make_engine("pybullet", "kuka_sdh", obj),
                                               own_engine("pybullet", obj)), args.draws, NAMES)
    result = {"sigma": SIGMA, "grasps": rows, "summary": summarize(rows, NAMES),
              "settings": settings(args)}
    publish(__file__, result, args, markdown(result, NAMES), DOC, (START, END))


if __name__ == "__main__":
    main()
