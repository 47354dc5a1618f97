"""Moving the elbow along the self-motion (``ArmIK.set_elbow_angle``): what every env step,
elbow curve and planned elbow pays.

Run: ``python benchmarks/bench_self_motion.py [--repeats 200]``. Times one configuration moved
by 0.3 rad (the env's largest step; one continuation step), and all 48 shipped grasps moved by
0.25 rad and by 1.5 rad (6 continuation steps), with the compiled kernels loaded first; checks
the results with the numpy kinematics (palm pose kept, elbow angle reached). Before the Newton
loop was compiled (``kinegrasp_env/robot/self_motion.py``) the env's case took 3.2 ms.
The figures (seconds, errors) also go to ``benchmarks/results/bench_self_motion.json``
(``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from results_file import add_options, settings, write_result

from kinegrasp_env.robot.default_robot import PALM_LINK, kuka_sdh
from kinegrasp_env.robot.ik import ArmIK
from kinegrasp_env.robot.kinematics import Kinematics, pose_error
from kinegrasp_env.world.grasps import shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES


def timed(ik: ArmIK, q: np.ndarray, psi: np.ndarray, repeats: int) -> tuple[float, tuple]:
    """Median seconds of ``repeats`` calls, and the last result."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        out = ik.set_elbow_angle(q, psi)
        times.append(time.perf_counter() - start)
    return float(np.median(times)), out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=200)
    add_options(parser, __file__)
    args = parser.parse_args()
    kin = Kinematics(kuka_sdh())
    ik = ArmIK(kin)
    q0 = np.array([g.q0 for name in OBJECT_NAMES for g in shipped_grasps(name)])
    psi0 = ik.elbow_angle(q0)
    ik.set_elbow_angle(q0[:1], psi0[:1] + 0.3)  # load the compiled kernels
    cases = (("1 configuration, +0.3 rad", q0[:1], psi0[:1] + 0.3, args.repeats),
             (f"{len(q0)} configurations, +0.25 rad", q0, psi0 + 0.25, max(5, args.repeats // 10)),
             (f"{len(q0)} configurations, +1.5 rad", q0, psi0 + 1.5, max(5, args.repeats // 20)))
    rows = []
    for label, q, psi, repeats in cases:
        seconds, (moved, ok) = timed(ik, q, psi, repeats)
        palm = np.abs(pose_error(kin.pose(moved[ok], PALM_LINK), kin.pose(q[ok], PALM_LINK)))
        reached = np.abs(np.angle(np.exp(1j * (ik.elbow_angle(moved[ok]) - psi[ok]))))
        print(f"{label:34s}: {seconds * 1e3:8.3f} ms median ({seconds / len(q) * 1e6:7.1f} us "
              f"per configuration); reached {ok.sum()}/{len(q)}, palm error "
              f"{palm.max() if ok.any() else 0.0:.1e}, elbow angle error "
              f"{reached.max() if ok.any() else 0.0:.1e}")
        rows.append({"case": label, "repeats": repeats, "median_s": seconds,
                     "s_per_configuration": seconds / len(q), "reached": int(ok.sum()),
                     "configurations": len(q),
                     "palm_error_max": float(palm.max()) if ok.any() else 0.0,
                     "elbow_angle_error_max_rad": float(reached.max()) if ok.any() else 0.0})
    if not args.no_json:
        write_result(__file__, {"cases": rows, "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
