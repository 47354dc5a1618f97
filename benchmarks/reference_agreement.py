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

from description_agreement import grasp_row, markdown, summarize
from results_file import add_options, publish, settings

from kinegrasp_env.montecarlo.engines import make_engine as own_engine
from kinegrasp_env.montecarlo.robot_engines import make_engine
from kinegrasp_env.world.grasps import shipped_grasps

DOC = Path(__file__).resolve().parents[1] / "docs" / "guides" / "robot.md"
START, END = "<!-- reference-agreement:start -->", "<!-- reference-agreement:end -->"
SIGMA = 0.0133
#: The two closings' names in the figures: the description robots' reference, the default
#: robot's own.
NAMES = ("description", "own")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "drill", "mug", "spray_flask"])
    parser.add_argument("--draws", type=int, default=500)
    add_options(parser, __file__)
    args = parser.parse_args()
    grasps = {obj: shipped_grasps(obj) for obj in args.objects}
    corrected = 0.05 / sum(len(g) for g in grasps.values())
    rows = []
    for obj, kept in grasps.items():
        with make_engine("pybullet", "kuka_sdh", obj) as description:
            own = own_engine("pybullet", obj)
            description.run(kept[0].q0[None]), own.run(kept[0].q0[None])  # warmed
            for index, grasp in enumerate(kept):
                rows.append(grasp_row(obj, index, grasp.q0, description, own, args.draws,
                                      corrected, NAMES))
                print(f"{obj} {index}: same {rows[-1]['same']:.4f}, contacts "
                      f"{rows[-1]['contact_offset_median'] or 0:.1e} m apart (median)",
                      flush=True)
            own.close()
    result = {"sigma": SIGMA, "grasps": rows, "summary": summarize(rows, NAMES),
              "settings": settings(args)}
    publish(__file__, result, args, markdown(result, NAMES), DOC, (START, END))


if __name__ == "__main__":
    main()
