"""Refresh the shipped grasp files' nominal contacts after a change of the auto-close.

Run: ``python scripts/refresh_nominal_contacts.py [objects ...] [--robot NAME]``. For each
built-in object the robot has grasps of (default robot: ``kuka_sdh``), every grasp of
``assets/grasps/<robot>/<object>.json`` is closed again by the reference
engine at its q0 (no noise) and its stored contacts (points, normals) and nominal Q are
replaced by what it finds there; q0, the palm pose, the ids and the metadata stay as they
are. It refuses (and writes nothing) where the grasp is no longer in force closure or its
touching links changed: that would be a different grasp, for ``scripts/make_grasp_sets.py``
to plan again.

The contacts are the root of the exact gap to 1e-9 m (the polish), reached from wherever the
conservative steps left the finger: a change of those steps moves them by ~1e-10-1e-9 m (the
per-link speed bounds moved points by at most 2e-9 m, Q by 1.8e-7 relative).
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace

import numpy as np

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
from kinegrasp_env.world.grasps import Grasp, shipped_grasp_file, shipped_grasps, shipped_objects


def refreshed(name: str, robot: str = DEFAULT_ROBOT) -> tuple[list[Grasp], float, float]:
    """The object's shipped grasps of ``robot`` with contacts and Q from the reference engine
    at q0, the largest point move (metres) and the largest relative change of Q."""
    grasps = shipped_grasps(name, robot)
    engine = make_engine("pybullet", robot, name)
    try:
        draws = engine.run(np.stack([g.q0 for g in grasps]))
    finally:
        engine.close()
    out, moved, q_change = [], 0.0, 0.0
    for i, grasp in enumerate(grasps):
        k = int(draws.n_contacts[i])
        if draws.outcome[i] != FORCE_CLOSURE or k != len(grasp.points) or not (
                np.array_equal(draws.finger[i, :k], grasp.fingers)
                and np.array_equal(draws.link[i, :k], grasp.links)):
            raise SystemExit(f"{name} grasp {grasp.id}: no longer the same force-closure "
                             "contacts at q0; plan the set again (scripts/make_grasp_sets.py)")
        points, normals = draws.points[i, :k].copy(), draws.normals[i, :k].copy()
        moved = max(moved, float(np.abs(points - grasp.points).max()))
        q_change = max(q_change, abs(draws.quality[i] - grasp.q_nominal) / grasp.q_nominal)
        out.append(replace(grasp, points=points, normals=normals,
                           q_nominal=float(draws.quality[i])))
    return out, moved, q_change


def rewrite(path, grasps: list[Grasp]) -> None:
    """Put the grasps' contacts and Q into the grasp file at ``path``, every other field and
    the file's layout as they are (the file is rewritten atomically)."""
    data = json.loads(path.read_text())
    for entry, grasp in zip(data["grasps"], grasps, strict=True):
        entry["q_nominal"] = grasp.q_nominal
        for contact, point, normal in zip(entry["contacts"], grasp.points, grasp.normals,
                                          strict=True):
            contact["point"], contact["normal"] = point.tolist(), normal.tolist()
    write_atomic(path, json.dumps(data, indent=1))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("objects", nargs="*")
    parser.add_argument("--robot", default=DEFAULT_ROBOT)
    args = parser.parse_args()
    for name in args.objects or shipped_objects(args.robot):
        grasps, moved, q_change = refreshed(name, args.robot)
        rewrite(shipped_grasp_file(name, args.robot), grasps)
        print(f"{name}: {len(grasps)} grasps, points moved by at most {moved:.1e} m, "
              f"Q by at most {q_change:.1e} relative")


if __name__ == "__main__":
    main()
