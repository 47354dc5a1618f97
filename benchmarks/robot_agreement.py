"""Agreement of a catalog robot's two engines (``kuka_sdh`` by default; ``agreement.py`` runs
the Panda's) on the same draws, and of both with pybullet's own closest points.

For each draw the reference engine (pybullet closest points, :class:`~kinegrasp_env.
montecarlo.evaluate.RobotReferenceEngine`) closes the hand; at its final state each
touching link's pybullet closest pair gives *pybullet's own* contact: its point on the object
and its normal (``-contactNormalOnB``), scored with the robot's contact model. The fast
engine (:class:`~kinegrasp_env.montecarlo.batched_engine.RobotFastEngine`) closes the same draws.
Three comparisons: fast vs reference (what the batched closing changes), reference vs bullet
and fast vs bullet (what the contact rules change: the patch centre moves a point on a face,
the face's normal replaces pybullet's).

Run on its own for any catalog robot (the engines its evaluate, rank and env run; for the
default robot the env's two engines):
``python benchmarks/robot_agreement.py [--robot kuka_sdh] [--objects cube mug] [--grasps 3]
[--draws 100] [--sigmas 0.0133 0.0266] [--seed 1]``: one row per object, sigma and
comparison, then the share of draws with the same outcome over all fast-vs-reference rows.
The figures also go to ``benchmarks/results/robot_agreement.json`` (``--json-out PATH``,
``--no-json``).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.closing.close_rules import CONTACT_TOL
from kinegrasp_env.montecarlo.description_engine import score
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import make_engine
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.world.grasps import Grasp


def bullet_contacts(world, result):
    """A copy of a closing whose contacts are pybullet's own (point, normal) at the world's
    current (final) state."""
    import dataclasses

    contacts = []
    rot = world.obj.pose[:3, :3]
    for c in result.contacts:
        link = world.description.fingers[c.finger].links[c.link]
        row = min(world.closest(CONTACT_TOL, link), key=world.distance)
        point = world.obj.to_object(np.array(row[6])[None])[0]
        normal = -np.array(row[7]) @ rot
        contacts.append(dataclasses.replace(c, point=point,
                                            normal=normal / np.linalg.norm(normal)))
    return dataclasses.replace(result, contacts=contacts)


def compare(a, b, grasps: int, draws: int) -> dict:
    """Figures of two per-draw results of the same draws (``DrawBatch``): outcomes, paired
    contacts (same count, matched by finger and link), force-closure counts per grasp."""
    same = int((a.outcome == b.outcome).sum())
    points, angles = [], []
    for i in np.flatnonzero((a.n_contacts == b.n_contacts) & (a.n_contacts > 0)):
        k = a.n_contacts[i]
        oa = np.lexsort((a.link[i, :k], a.finger[i, :k]))
        ob = np.lexsort((b.link[i, :k], b.finger[i, :k]))
        if not np.array_equal(a.finger[i, oa], b.finger[i, ob]):
            continue
        points += list(np.linalg.norm(a.points[i, oa] - b.points[i, ob], axis=1))
        cos = np.clip(np.einsum("ij,ij->i", a.normals[i, oa], b.normals[i, ob]), -1.0, 1.0)
        angles += list(np.degrees(np.arccos(cos)))
    points, angles = np.array(points), np.array(angles)
    fc = [[int((x.outcome[g * draws:(g + 1) * draws] == FORCE_CLOSURE).sum())
           for g in range(grasps)] for x in (a, b)]
    return {"draws": int(a.outcome.size), "same_outcome": same, "contacts": int(points.size),
            "point_median": float(np.median(points)), "point_q90": float(np.quantile(points, 0.9)),
            "point_max": float(points.max()), "normal_q90_deg": float(np.quantile(angles, 0.9)),
            "normal_max_deg": float(angles.max()), "fc_first": fc[0], "fc_second": fc[1]}


def robot_agreement(robot: str, object_name: str, grasps: list[Grasp], sigma: float,
                    draws: int, seed: int) -> dict[str, dict]:
    """The three comparisons of ``robot``'s engines on ``draws`` noisy configurations of each
    grasp (grasp g's noise from the Generator of [seed, g])."""
    fast, reference = make_engine("fast", robot, object_name), make_engine("pybullet", robot,
                                                                          object_name)
    try:
        arm = fast.description.arm_dof
        q = []
        for g, grasp in enumerate(grasps):
            rows = np.repeat(np.asarray(grasp.q0)[None], draws, axis=0)
            rows[:, :arm] += JointNoise(sigma).sample(draws, arm, np.random.default_rng(
                [seed, g]))
            q.append(rows)
        q = np.concatenate(q)
        a = fast.run(q)
        closings, own = [], []
        for row in reference.check(q):
            result = reference.world.auto_close(row)
            closings.append(result)
            own.append(bullet_contacts(reference.world, result))
        b = score(closings, reference.max_contacts, reference.quality)
        c = score(own, reference.max_contacts, reference.quality)
        n = len(grasps)
        return {"fast vs reference": compare(a, b, n, draws),
                "reference vs bullet": compare(b, c, n, draws),
                "fast vs bullet": compare(a, c, n, draws)}
    finally:
        reference.close()


def main() -> None:
    import argparse

    from results_file import add_options, settings, write_result

    from kinegrasp_env.robot.catalog import robot_names
    from kinegrasp_env.world.grasps import shipped_grasps, shipped_objects

    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--robot", default="kuka_sdh", help="a catalog robot")
    parser.add_argument("--objects", nargs="+", help="objects with shipped grasps of the robot "
                        "(default: all of them)")
    parser.add_argument("--grasps", type=int, default=3, help="the first grasps of each set")
    parser.add_argument("--draws", type=int, default=100, help="draws per grasp")
    parser.add_argument("--sigmas", nargs="+", type=float, default=[0.0133, 0.0266])
    parser.add_argument("--seed", type=int, default=1)
    add_options(parser, __file__)
    args = parser.parse_args()
    if args.robot not in robot_names():
        parser.error(f"unknown robot {args.robot!r}; known robots: {', '.join(robot_names())}")
    objects = args.objects or list(shipped_objects(args.robot))
    missing = [name for name in objects if name not in shipped_objects(args.robot)]
    if missing:
        parser.error(f"robot {args.robot!r} has no shipped grasps of {missing[0]!r}")
    for name, value in (("--grasps", args.grasps), ("--draws", args.draws)):
        if value < 1:
            parser.error(f"{name} must be >= 1, got {value}")
    rows = []
    for name in objects:
        grasps = shipped_grasps(name, args.robot)[:args.grasps]
        for sigma in args.sigmas:
            for label, r in robot_agreement(args.robot, name, grasps, sigma, args.draws,
                                            args.seed).items():
                print(f"{name:12s} {sigma:6.4f} {label:20s} {r['same_outcome']:5d}/"
                      f"{r['draws']:<5d} point max {r['point_max']:9.2e} m, normal max "
                      f"{r['normal_max_deg']:7.3f} deg", flush=True)
                rows.append({"object": name, "sigma": sigma, "comparison": label,
                             "grasps": len(grasps), **r})
    paired = [r for r in rows if r["comparison"] == "fast vs reference"]
    same, total = sum(r["same_outcome"] for r in paired), sum(r["draws"] for r in paired)
    print(f"fast vs reference: the same outcome on {same} of {total} draws")
    if not args.no_json:
        write_result(__file__, {"robot": args.robot, "same_outcome": same, "draws": total,
                                "rows": rows, "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
