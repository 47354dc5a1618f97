"""Batched forward kinematics (all link frames of the KUKA + hand) vs a per-draw pybullet loop.

Run: ``python benchmarks/bench_fk.py [--draws 10000]``. Both compute every link frame of the
same configurations in one run; prints wall times, draws/s and the ratio (target >= 50x).
The figures (seconds, draws/s, ratios, metres) also go to ``benchmarks/results/bench_fk.json``
(``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import pybullet
from pybullet_utils.bullet_client import BulletClient
from results_file import add_options, settings, write_result

from kinegrasp_env.robot.default_robot import kuka_sdh, urdf_path
from kinegrasp_env.robot.kinematics import Kinematics


def pybullet_loop(q: np.ndarray, batched_calls: bool = True
                  ) -> tuple[np.ndarray, float, list[str]]:
    """Per-draw pybullet FK of every link. ``batched_calls``: one resetJointStatesMultiDof and
    one getLinkStates call per draw (the fastest loop); else one call per joint and per link."""
    model = kuka_sdh()
    client = BulletClient(connection_mode=pybullet.DIRECT)
    body = client.loadURDF(str(urdf_path()), useFixedBase=True)
    infos = [client.getJointInfo(body, j) for j in range(client.getNumJoints(body))]
    index = {info[1].decode(): info[0] for info in infos}
    n_links = len(infos)
    expanded = model.expand(q)
    names = list(expanded)
    values = np.stack([expanded[n] for n in names], axis=1)
    joint_ids = [index[n] for n in names]
    out = np.empty((q.shape[0], n_links, 3))
    start = time.perf_counter()
    for i in range(q.shape[0]):
        if batched_calls:
            client.resetJointStatesMultiDof(body, joint_ids, [[v] for v in values[i]])
            states = client.getLinkStates(body, list(range(n_links)), computeForwardKinematics=1)
        else:
            for j, v in zip(joint_ids, values[i], strict=True):
                client.resetJointState(body, j, v)
            states = [client.getLinkState(body, j, computeForwardKinematics=1)
                      for j in range(n_links)]
        out[i] = [s[4] for s in states]
    elapsed = time.perf_counter() - start
    link_names = [info[12].decode() for info in infos]
    client.disconnect()
    return out, elapsed, link_names


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--draws", type=int, default=10_000)
    parser.add_argument("--repeats", type=int, default=5)
    add_options(parser, __file__)
    args = parser.parse_args()
    model = kuka_sdh()
    kin = Kinematics(model)
    q = np.random.default_rng(0).uniform(model.lower, model.upper, (args.draws, model.dof))
    kin.forward(q[:10])  # warm-up
    batched = []
    for _ in range(args.repeats):
        start = time.perf_counter()
        poses = kin.forward(q)
        batched.append(time.perf_counter() - start)
    t_batch = min(batched)
    ref, t_loop, links = pybullet_loop(q)
    _, t_naive, _ = pybullet_loop(q[: max(1, args.draws // 5)], batched_calls=False)
    t_naive *= args.draws / max(1, args.draws // 5)
    ours = np.stack([poses[name][:, :3, 3] for name in links], axis=1)
    err = np.abs(ours - ref).max()
    print(f"draws: {args.draws}, link frames per draw: {len(links) + 1}")
    print(f"batched numpy FK : {t_batch * 1e3:9.1f} ms  ({args.draws / t_batch:12,.0f} draws/s)"
          f"  best of {args.repeats}")
    print(f"pybullet loop (multi-joint reset + getLinkStates): {t_loop * 1e3:9.1f} ms  "
          f"({args.draws / t_loop:12,.0f} draws/s)")
    print(f"pybullet, 1 call per joint/link: {t_naive * 1e3:9.1f} ms (measured on 1/5 of the "
          "draws, scaled)")
    print(f"ratio vs fastest pybullet loop : {t_loop / t_batch:9.1f}x  (target >= 50x)")
    print(f"ratio vs per-call pybullet loop: {t_naive / t_batch:9.1f}x")
    print(f"max |difference| : {err:.2e} m")
    if not args.no_json:
        write_result(__file__, {
            "link_frames_per_draw": len(links) + 1,
            "batched_numpy_s": t_batch, "batched_numpy_draws_per_s": args.draws / t_batch,
            "pybullet_loop_s": t_loop, "pybullet_loop_draws_per_s": args.draws / t_loop,
            "pybullet_per_call_s": t_naive, "pybullet_per_call_scaled_from_draws":
                max(1, args.draws // 5),
            "ratio_vs_pybullet_loop": t_loop / t_batch,
            "ratio_vs_pybullet_per_call": t_naive / t_batch, "max_difference_m": float(err),
            "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
