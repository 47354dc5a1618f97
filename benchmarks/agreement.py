"""Agreement of the two engines' contacts, and of both with pybullet's own collision queries.

Run: ``python benchmarks/agreement.py [--grasps 3] [--draws 60] [--seed 0]
[--objects cube mug] [--sigmas 0.0133 0.0266]`` (about 1 s per 30 draws of a row triple,
most of it the reference engine), or on any object, imported ones included, with the grasps
of a grasp file (``kinegrasp plan``'s output): ``python benchmarks/agreement.py --grasp-file
FILE [--grasps 5]`` (the file's object; ``--objects`` may not be given with it).

For every object and noise level sigma (radians, on the 7 arm joints), the first ``--grasps``
shipped grasps (or grasps of ``--grasp-file``) get ``--draws`` noisy configurations each, and
each row compares two computations of those same draws:

(a) ``fast vs pybullet``: the fast engine (distance grid, batched closing) against the
    reference engine (pybullet far-field gaps, per-draw closing). This proves that the batched
    closing stops the fingers where the per-draw one does and so finds the same contacts. It
    does not prove that those contacts are right: near contact both engines use the same exact
    capsule-object geometry (``closing.segment_distance``, ``closing.hand_geometry``) and the
    same scoring (``RobotEngine.scored``), so fingers stopped at the same place get the same
    contacts by construction.
(b) ``<engine> vs bullet``: each engine against the pybullet-only contacts of
    :mod:`kinegrasp_env.montecarlo.bullet_contacts`, on that engine's own closed configuration
    (``DrawBatch.hand``): the arm+hand URDF posed by pybullet's forward kinematics, each finger
    capsule queried against the object's convex parts with ``getClosestPoints``, a link
    touching within the engines' contact tolerance (0.2 mm), pybullet's closest point and
    normal, then Q. It shares no kinematics, distance or contact code with the engines, so it
    proves that the exact near-contact geometry both share agrees with an independent
    collision library. What it measures is pybullet's own precision (GJK round-off, up to
    ~2e-5 m; normals at edges to ~0.1 degree), borderline links (a second link of a finger
    inside the tolerance whose pybullet distance lands outside it, or the converse) and
    contacts whose closest point is not unique: a finger along a face touches along a line, a
    finger on a seam of two convex parts (the mug's facets) touches both, and pybullet may
    pick another point of the line or the other facet's normal. Those make "point max",
    "normal" and Q differ by millimetres, degrees and tens of per cent; "offset" and
    "off.nrm" do not depend on the choice: they hold the engine's own contact to pybullet's
    geometry (see ``BulletContactReference.check_contacts``).
    The "~1 mm edge error" once measured for pybullet's convex hulls is not an edge error:
    it is pybullet's default 1 mm collision margin, which ``changeDynamics(collisionMargin=0)``
    does not remove from the links of a multi-link body (the reference engine's object is
    one, :class:`kinegrasp_env.world.sim.ObjectWorld`): every part but the first reports
    distances 1e-3 m short. Here each part is a body of its own and the margin is gone.

Columns: draws with the same outcome (the four outcomes; the pybullet-only reference decides
start collisions itself, from every hand link at the pre-grasp configuration); of the draws
where both closed the hand, those whose touching (finger, link) lists differ and those whose
closed hands differ by more than ``agreement.STOP_TOL`` (counted as disagreements, never
dropped); over the rest (paired draws): the largest and median distance between paired
contact points (metres), the largest angle between paired normals (degrees), in (b) the
largest offset of the engine's contact points from a closest pair in pybullet's geometry
(metres) and the largest angle between the engine's normal and pybullet's direction from
the link to that point (degrees); the largest relative and absolute Q difference over paired
draws in force closure on both sides (their number in brackets), and the absolute one
without the draws where a normal's tangent basis is tied (``agreement.TIE_TOL``: a 1e-12
change of such a normal can turn the linearized friction cone and change Q by ~1%).

The Panda's rows (``--robots``: ``kuka_sdh`` and ``panda`` by default; ``--panda-objects``,
default cube and drill, their first ``--grasps`` shipped Panda grasps, ``--draws`` each, per
sigma) come from :mod:`robot_agreement`: fast vs reference, reference vs bullet and fast vs
bullet, "bullet" being pybullet's own closest point and normal of each touching link at the
reference's final state; columns: same outcome, paired contacts, the median, 90% quantile and
largest point distance (metres), the 90% quantile and largest normal angle (degrees), and
each side's force-closure count per grasp.

Every row (the same counts and differences, plus the same-outcome fraction) also goes to
``benchmarks/results/agreement.json`` (``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

import numpy as np
from marked_section import write_between
from results_file import ROOT, add_options, settings, write_result
from robot_agreement import robot_agreement

from kinegrasp_env.montecarlo.agreement import Agreement, compare
from kinegrasp_env.montecarlo.bullet_contacts import MAX_CONTACTS, BulletContactReference
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import chunk_stream
from kinegrasp_env.world.grasps import Grasp, load_grasps, shipped_grasps
from kinegrasp_env.world.objects import OBJECT_NAMES

COLUMNS = (f"{'object':11s} {'sigma':>6s} {'comparison':18s} {'same outcome':>11s} "
           f"{'lists diff':>10s} {'stops diff':>10s} {'point max':>9s} {'point med':>9s} "
           f"{'normal':>7s} {'offset':>7s} {'off.nrm':>7s} {'Q rel':>8s} {'Q abs':>8s} "
           f"{'Q untied':>8s} (FC pairs)")


def configurations(grasps: list[Grasp], sigma: float, draws: int, seed: int) -> np.ndarray:
    """(len(grasps) * draws, 14): each grasp with ``draws`` noisy arm configurations (the
    first ``draws`` rows of chunk g's stream of the seed for grasp g)."""
    out = []
    for i, g in enumerate(grasps):
        q = np.repeat(np.asarray(g.q0, dtype=float)[None], draws, axis=0)
        q[:, :7] += JointNoise(sigma).sample(draws, 7, chunk_stream(seed, i))
        out.append(q)
    return np.concatenate(out)


def compare_object(name: str, sigma: float, grasps: list[Grasp], draws: int,
                   seed: int) -> dict[str, Agreement]:
    """The three comparisons of one object (built-in or imported) and noise level on the
    draws of ``grasps`` (grasps of that object)."""
    q = configurations(grasps, sigma, draws, seed)
    # the default robot's engines with the reference's contact slots (one per finger's
    # proximal and distal link, as pybullet's contacts here have them)
    reference = make_engine("pybullet", DEFAULT_ROBOT, name, max_contacts=MAX_CONTACTS)
    fast = make_engine("fast", DEFAULT_ROBOT, name, max_contacts=MAX_CONTACTS)
    bullet = BulletContactReference(name)
    try:
        ref, fst = reference.run(q), fast.run(q)
        return {"fast vs pybullet": compare(fst, ref),
                "pybullet vs bullet": compare(ref, bullet.run(q, ref.hand),
                                              bullet.check_contacts(q, ref)),
                "fast vs bullet": compare(fst, bullet.run(q, fst.hand),
                                          bullet.check_contacts(q, fst))}
    finally:
        reference.close()
        fast.close()
        bullet.close()


def row(name: str, sigma: float, label: str, a: Agreement) -> str:
    return (f"{name:11s} {sigma:6.4f} {label:18s} {a.same_outcome:5d}/{a.draws:<5d} "
            f"{a.list_mismatch:4d}/{a.closed:<5d} {a.stop_mismatch:4d}/{a.closed:<5d} "
            f"{a.point_max:9.2e} {a.point_median:9.2e} {a.normal_max:7.3f} "
            f"{a.offset_max:7.1e} {a.offset_normal_max:7.3f} {a.q_max:8.1e} "
            f"{a.q_abs_max:8.1e} {a.q_abs_max_untied:8.1e} ({a.q_pairs})")


def grasp_sets(parser: argparse.ArgumentParser, args) -> dict[str, list[Grasp]]:
    """The first ``--grasps`` grasps of each object: of ``--grasp-file``, else the shipped
    sets of ``--objects`` (built-in objects by default); bad input ends through
    ``parser.error`` (one line, exit status 2)."""
    if args.grasps < 1:
        parser.error(f"--grasps must be >= 1, got {args.grasps}")
    try:
        if args.grasp_file is None:
            return {name: shipped_grasps(name)[:args.grasps]
                    for name in args.objects or OBJECT_NAMES}
        if args.objects:
            parser.error("--objects and --grasp-file exclude each other (the file names "
                         "its object)")
        grasps = load_grasps(args.grasp_file)[:args.grasps]
    except ValueError as exc:  # unknown object, no shipped set, bad grasp file
        parser.error(str(exc))
    if not grasps or len({g.object for g in grasps}) != 1:
        parser.error(f"{args.grasp_file}: expected grasps of one object, got "
                     f"{sorted({g.object for g in grasps})}")
    return {grasps[0].object: grasps}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--grasps", type=int, default=3,
                        help="grasps per object (the first of its set or of --grasp-file)")
    parser.add_argument("--draws", type=int, default=60, help="draws per grasp and sigma")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--objects", nargs="+", help="objects whose shipped grasps to use "
                        f"(default: {' '.join(OBJECT_NAMES)})")
    parser.add_argument("--grasp-file", help="a grasp file (e.g. `kinegrasp plan`'s output "
                        "for an imported object): its object, its first --grasps grasps")
    parser.add_argument("--sigmas", nargs="+", type=float, default=[0.0133, 0.0266])
    parser.add_argument("--robots", nargs="+", default=["kuka_sdh", "panda"],
                        choices=["kuka_sdh", "panda"], help="the robots whose rows to run")
    parser.add_argument("--panda-objects", nargs="+", default=["cube", "drill"],
                        help="objects of the Panda rows (their shipped Panda grasps)")
    parser.add_argument("--guide", type=Path, default=ROOT / "docs" / "guides" / "robot.md",
                        help="the page whose Panda agreement table to rewrite")
    parser.add_argument("--no-guide", action="store_true", help="leave the page as it is")
    add_options(parser, __file__)
    args = parser.parse_args()
    sets = grasp_sets(parser, args) if "kuka_sdh" in args.robots else {}
    start = time.perf_counter()
    rows = []
    if sets:
        print(COLUMNS)
    for name, grasps in sets.items():
        for sigma in args.sigmas:
            for label, agreement in compare_object(name, sigma, grasps, args.draws,
                                                   args.seed).items():
                print(row(name, sigma, label, agreement), flush=True)
                rows.append({"object": name, "sigma": sigma, "comparison": label,
                             "grasps": len(grasps),
                             "same_outcome_fraction": agreement.same_outcome / agreement.draws,
                             **dataclasses.asdict(agreement)})
    counts = "/".join(sorted({str(len(g)) for g in sets.values()}))
    if sets:
        print(f"({counts} grasps x {args.draws} draws per row, seed {args.seed})")
    robot_rows = panda_rows(args) if "panda" in args.robots else []
    if robot_rows and not args.no_guide:
        write_between(args.guide, START, END, markdown(robot_rows, args))
    seconds = time.perf_counter() - start
    print(f"({seconds:.0f} s)")
    if not args.no_json:
        write_result(__file__, {"wall_s": seconds, "rows": rows, "robot_rows": robot_rows,
                                "settings": settings(args)}, args.json_out)


ROBOT_COLUMNS = (f"{'robot':6s} {'object':11s} {'sigma':>6s} {'comparison':20s} "
                 f"{'same outcome':>12s} {'contacts':>8s} {'point med':>9s} {'point q90':>9s} "
                 f"{'point max':>9s} {'nrm q90':>8s} {'nrm max':>8s}  FC per grasp (first / "
                 "second)")


def panda_rows(args) -> list[dict]:
    """The Panda's rows (:func:`robot_agreement.robot_agreement`): the first ``--grasps``
    shipped Panda grasps of each of ``--panda-objects``, ``--draws`` draws each, per sigma."""
    print(ROBOT_COLUMNS)
    out = []
    for name in args.panda_objects:
        grasps = shipped_grasps(name, "panda")[:args.grasps]
        for sigma in args.sigmas:
            for label, r in robot_agreement("panda", name, grasps, sigma, args.draws,
                                            args.seed).items():
                print(f"{'panda':6s} {name:11s} {sigma:6.4f} {label:20s} "
                      f"{r['same_outcome']:6d}/{r['draws']:<5d} {r['contacts']:8d} "
                      f"{r['point_median']:9.2e} {r['point_q90']:9.2e} {r['point_max']:9.2e} "
                      f"{r['normal_q90_deg']:8.3f} {r['normal_max_deg']:8.3f}  "
                      f"{r['fc_first']} / {r['fc_second']}", flush=True)
                out.append({"robot": "panda", "object": name, "sigma": sigma,
                            "comparison": label, "grasps": len(grasps), **r})
    print(f"({args.grasps} Panda grasps x {args.draws} draws per row; normals in degrees; "
          "bullet: pybullet's own closest point and normal at the reference's final state)")
    return out



START, END = "<!-- panda-agreement:start -->", "<!-- panda-agreement:end -->"


def markdown(rows: list[dict], args) -> str:
    """The Panda rows as the guide's table."""
    lines = ["| object | sigma (rad) | comparison | same outcome | paired contacts | point "
             "median (m) | point 90% (m) | point max (m) | normal 90% (deg) | normal max "
             "(deg) | force closure per grasp |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['object']} | {r['sigma']:.4f} | {r['comparison']} | "
                     f"{r['same_outcome']}/{r['draws']} | {r['contacts']} | "
                     f"{r['point_median']:.1e} | {r['point_q90']:.1e} | {r['point_max']:.1e} | "
                     f"{r['normal_q90_deg']:.3f} | {r['normal_max_deg']:.3f} | "
                     f"{r['fc_first']} vs {r['fc_second']} |")
    lines.append("")
    lines.append(f"(`python benchmarks/agreement.py --robots panda`: the first {args.grasps} "
                 f"shipped Panda grasps of each object, {args.draws} draws each per sigma, "
                 f"seed {args.seed}; bullet: pybullet's own closest point and normal of each "
                 "touching link at the reference's final state.)")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
