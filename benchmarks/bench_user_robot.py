"""A robot added as a user adds it: its fast engine against its reference engine, per draw.

The robot comes from a description file (``--description``; default: the xArm 6 with its
gripper from pybullet_data, its description written here as a user writes it: six arm joints,
a revolute linkage gripper driven through mimic joints), added to a catalog of the run's own
(a temporary ``KINEGRASP_HOME``: the user's catalog is not touched). ``--count`` grasps of
``--object`` are planned (seed ``--seed``), then both engines close the same ``--draws``
noisy draws of each (sigma ``--sigma``) on one process, each engine warmed first; each
engine's time is the best of ``--repeat`` runs of all the draws (the machine's other load
only adds to a run).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from results_file import add_options, settings, write_result
from robot_speed import draws_of


def xarm_description(folder: Path) -> Path:
    """The xArm 6 description (the robot guide's) written into ``folder``."""
    import pybullet_data

    urdf = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_with_gripper.urdf"
    path = folder / "xarm6.yaml"
    path.write_text(yaml.safe_dump({
        "name": "xarm6", "urdf": str(urdf),
        "arm_joints": [f"joint{i}" for i in range(1, 7)],
        "palm_link": "xarm_gripper_base_link", "hand_joints": ["drive_joint"],
        "close": {"drive_joint": 1}, "open": {"drive_joint": 0.0},
        "finger_links": ["left_finger", "right_finger"], "contact_model": "soft"}))
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--description", type=Path, help="a robot description (YAML)")
    parser.add_argument("--object", default="cube")
    parser.add_argument("--count", type=int, default=2, help="grasps planned")
    parser.add_argument("--draws", type=int, default=300, help="draws per grasp")
    parser.add_argument("--sigma", type=float, default=0.0133)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--repeat", type=int, default=3, help="timed runs per engine (best)")
    add_options(parser, __file__)
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error(f"--repeat must be >= 1, got {args.repeat}")
    with tempfile.TemporaryDirectory() as home:
        os.environ["KINEGRASP_HOME"] = home
        from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
        from kinegrasp_env.montecarlo.evaluate import make_engine
        from kinegrasp_env.robot.catalog import add_robot
        from kinegrasp_env.toolkit.grasp_planner import plan_grasps

        path = args.description or xarm_description(Path(home))
        description, _ = add_robot(path)
        grasps = plan_grasps(description.name, args.object, count=args.count,
                             seed=args.seed)
        arm = description.arm_dof
        qs = [draws_of(g.q0, arm, args.sigma, args.draws, [args.seed, i])
              for i, g in enumerate(grasps)]
        rows = []
        for name in ("fast", "pybullet"):
            engine = make_engine(name, description.name, args.object)
            try:
                engine.run(qs[0][:16])  # loads the compiled kernels and tables
                seconds = np.inf
                for _ in range(args.repeat):
                    start = time.perf_counter()
                    results = [engine.run(q) for q in qs]
                    seconds = min(seconds, time.perf_counter() - start)
            finally:
                engine.close()
            rows.append({"engine": name, "draws": len(qs) * args.draws,
                         "s_per_draw": seconds / (len(qs) * args.draws),
                         "force_closure": str([int((r.outcome == FORCE_CLOSURE).sum())
                                               for r in results])})
            print(f"{description.name} {args.object}, {name:8s}: "
                  f"{rows[-1]['s_per_draw'] * 1e3:.3f} ms per draw "
                  f"({rows[-1]['draws']} draws of {len(qs)} grasps), force closure "
                  f"{rows[-1]['force_closure']}")
    ratio = rows[1]["s_per_draw"] / rows[0]["s_per_draw"]
    print(f"fast / pybullet per draw: {ratio:.1f}x")
    if not args.no_json:
        write_result(__file__, {"robot": description.name, "arm_dof": arm,
                                "fast_over_pybullet_per_draw": ratio,
                                "per_draw": rows, "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
