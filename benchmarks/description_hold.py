"""The holding test of the paper's hand run as a description robot against its own.

The description robots' holding test (:mod:`kinegrasp_env.physics.robot_hold`, and its
MuJoCo twin) cuts the hand from the URDF and grips a hand of revolute fingers with balanced
joint torques (:mod:`kinegrasp_env.physics.balanced_grip`); parallel jaws keep every closing
motor at its full effort. Here ``kuka_sdh`` runs through it, with the balanced grip and with
the jaws' rule (the grip layout switched off), beside the SDH's own holding test
(:class:`~kinegrasp_env.montecarlo.physics_engine.PhysicsEngine`: its closing holds the
proximal joint when a link touches and lets the distal creep), all with the quick protocol,
on the same draws: the shipped grasps of ``--objects``, ``--samples`` draws each at every
joint noise of ``--sigmas`` (seed ``--seed``).

For each simulator and object: the draws, how many each test holds, and on how many draws
each description test's verdict is the SDH test's. Written as JSON
(``benchmarks/results/description_hold.json``) and as a table in the robots guide between
``<!-- description-hold:start -->`` and ``<!-- description-hold:end -->``.

    python benchmarks/description_hold.py [--objects cube mug] [--sigmas 0 0.0033]
        [--samples 2] [--simulators pybullet mujoco]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from marked_section import write_between
from quick_hold import configurations
from results_file import add_options, settings, write_result

from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine
from kinegrasp_env.montecarlo.physics_engine import PhysicsEngine
from kinegrasp_env.physics.protocol import HELD, QUICK_PROTOCOL
from kinegrasp_env.physics.robot_hold import QUICK_MOTORS
from kinegrasp_env.world.grasps import shipped_grasps

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "guides" / "robot.md"
START, END = "<!-- description-hold:start -->", "<!-- description-hold:end -->"
TESTS = ("own", "balanced", "jaws")


def held(test: str, obj: str, q: np.ndarray, simulator: str) -> np.ndarray:
    """(n,) whether ``test`` (:data:`TESTS`) holds each configuration q (n, 14)."""
    if test == "own":
        engine = PhysicsEngine(obj, protocol=QUICK_PROTOCOL, simulator=simulator)
        try:
            return engine.run_hold(q)[1].outcome == HELD
        finally:
            engine.close()
    # the description robots' holding test on the SDH (quick_hold_engine gives its own)
    with RobotHoldEngine("kuka_sdh", obj, protocol=QUICK_PROTOCOL, motors=QUICK_MOTORS,
                         simulator=simulator) as engine:
        if test == "jaws":
            engine.simulator.layout = None  # every closing motor at full effort
        return engine.run_hold(q)[1].outcome == HELD


def markdown(rows: list[dict]) -> str:
    lines = ["| simulator | object | draws | held: SDH's own test | held: description, "
             "balanced grip | held: description, jaws' rule | same verdict as the SDH's: "
             "balanced | same verdict: jaws' rule |", "|---" * 8 + "|"]
    for r in rows:
        lines.append(f"| {r['simulator']} | {r['object']} | {r['draws']} | {r['held_own']} | "
                     f"{r['held_balanced']} | {r['held_jaws']} | {r['same_balanced']} | "
                     f"{r['same_jaws']} |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=["cube", "mug"])
    parser.add_argument("--sigmas", type=float, nargs="+", default=[0.0, 0.0033])
    parser.add_argument("--samples", type=int, default=2)
    parser.add_argument("--simulators", nargs="+", default=["pybullet", "mujoco"],
                        choices=["pybullet", "mujoco"])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--page", type=Path, default=PAGE)
    parser.add_argument("--no-page", action="store_true")
    add_options(parser, __file__)
    args = parser.parse_args()
    rows = []
    for simulator in args.simulators:
        for obj in args.objects:
            q = configurations(shipped_grasps(obj), args.sigmas, args.samples, args.seed)
            start = time.perf_counter()
            verdicts = {test: held(test, obj, q, simulator) for test in TESTS}
            rows.append({"simulator": simulator, "object": obj, "draws": int(q.shape[0]),
                         **{f"held_{t}": int(v.sum()) for t, v in verdicts.items()},
                         **{f"same_{t}": int((verdicts[t] == verdicts["own"]).sum())
                            for t in ("balanced", "jaws")}})
            print(f"  {simulator} {obj}: {time.perf_counter() - start:.0f} s", file=sys.stderr)
    text = markdown(rows)
    print(text)
    if not args.no_json:
        write_result(__file__, {"rows": rows, "settings": settings(args)}, args.json_out)
    if not args.no_page:
        write_between(args.page, START, END, text)


if __name__ == "__main__":
    main()
