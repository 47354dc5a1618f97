"""Soft-finger quality against Dex-Net's own function on the same contact sets.

Dex-Net's Ferrari-Canny L1 metric (``PointGraspMetrics3D.ferrari_canny_L1`` with
``soft_fingers``, in ``graspnetAPI/utils/dexnet/grasping/quality.py`` of the ``graspnetAPI``
package on PyPI) is loaded from a copy of that file the user downloads, and run, unchanged:

    pip download graspnetapi==1.2.11 --no-deps -d /tmp/gn && tar xzf /tmp/gn/*.tar.gz -C /tmp/gn
    pip install cvxopt          # the metric solves one QP per hull facet with it
    python benchmarks/dexnet_soft_contacts.py \\
        --dexnet /tmp/gn/graspnetAPI-1.2.11/graspnetAPI/utils/dexnet/grasping/quality.py

The module's imports that the metric does not use (its grasp, object and mesh classes,
IPython) are stood in for by empty modules; ``pyhull``, whose ``ConvexHull(points).vertices``
the metric reads as the hull's facets (lists of point indices), is stood in for by SciPy's
qhull (``ConvexHull(points).simplices``). Everything else is Dex-Net's code.

Contact sets (``--sets`` of each kind, seed ``--seed``): two-finger pinches of a box on
opposite faces and three-finger grasps on three faces, points uniform on the faces (inner
80%), normals the faces' inward normals tilted by up to ``--tilt`` degrees; mu ``--friction``,
``--edges`` cone edges, patch radius ``--radius``, torques scaled by 1 / r_max (r_max: the
box's half-diagonal). Two comparisons:

1. **The same primitive wrenches**: this project's soft-finger primitives
   (:func:`kinegrasp_env.quality.soft_contacts.contact_wrenches`: cone edges and
   (n, s (p - c) x n +- s gamma n), gamma = (2/3) mu r) given to Dex-Net's metric as its
   forces and torques (``soft_fingers`` off: no primitive added), against this project's Q
   of them (:func:`~kinegrasp_env.quality.soft_contacts.contact_quality`). The two compute
   Q differently (here: facet planes of the hull or the certified expansion; there: the
   minimum-norm point of each hull facet by a QP), so they agree to the QP's tolerance.
2. **Each its own soft-finger model**: Dex-Net's (the cone edges plus two pure torques
   +-pi r^2 mu s n per contact, no normal force behind them) against this project's, on the
   same contacts: how often the force-closure verdicts agree and how the Q values compare.

Writes ``benchmarks/results/dexnet_soft_contacts.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import sys
import types
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from results_file import add_options, settings, write_result

from kinegrasp_env.quality.soft_contacts import (
    contact_quality,
    contact_wrenches,
)

#: The box: half-sizes (metres).
HALF = np.array([0.03, 0.02, 0.025])
#: Its faces: (axis, sign) -> inward normal -sign e_axis at coordinate sign * HALF[axis].
PINCH_FACES = ((0, 1), (0, -1))
TRIPOD_FACES = ((0, 1), (0, -1), (1, 1))


def load_dexnet(path: Path):
    """Dex-Net's ``PointGraspMetrics3D`` from its ``quality.py`` at ``path`` (module
    docstring: the unused imports stood in for, pyhull by SciPy's qhull)."""
    from scipy.spatial import ConvexHull

    package = "kg_dexnet_grasping"
    stubs = {package: [], f"{package}.grasp": ["PointGrasp"],
             f"{package}.graspable_object": ["GraspableObject3D"],
             f"{package}.grasp_quality_config": ["GraspQualityConfig"],
             f"{package}.meshpy": ["mesh", "sdf"], "IPython": []}
    for name, attributes in stubs.items():
        module = types.ModuleType(name)
        module.__path__ = []
        for attribute in attributes:
            setattr(module, attribute, type(attribute, (), {}))
        sys.modules.setdefault(name, module)

    class FacetHull:
        """pyhull's ConvexHull as the metric reads it: ``vertices``, the facets' indices."""

        def __init__(self, points):
            self.vertices = ConvexHull(np.asarray(points)).simplices.tolist()

    pyhull = types.ModuleType("pyhull")
    pyhull.convex_hull = types.ModuleType("pyhull.convex_hull")
    pyhull.convex_hull.ConvexHull = FacetHull
    sys.modules["pyhull"], sys.modules["pyhull.convex_hull"] = pyhull, pyhull.convex_hull
    spec = importlib.util.spec_from_file_location(f"{package}.quality", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    import cvxopt

    cvxopt.solvers.options["show_progress"] = False
    return module.PointGraspMetrics3D


class Params(dict):
    """Dex-Net's quality parameters: a dict whose keys are attributes too."""

    __getattr__ = dict.__getitem__


def contact_sets(faces: tuple, count: int, tilt: float, rng: np.random.Generator):
    """``count`` contact sets (points (count, k, 3), inward unit normals (count, k, 3)), one
    contact on each of ``faces``, points uniform on the inner 80% of the face, normals
    tilted by up to ``tilt`` radians in a uniform direction."""
    k = len(faces)
    points, normals = np.zeros((count, k, 3)), np.zeros((count, k, 3))
    for c, (axis, sign) in enumerate(faces):
        points[:, c] = rng.uniform(-0.8, 0.8, (count, 3)) * HALF
        points[:, c, axis] = sign * HALF[axis]
        inward = np.zeros(3)
        inward[axis] = -sign
        others = [a for a in range(3) if a != axis]
        angle = tilt * np.sqrt(rng.uniform(0, 1, count))
        turn = rng.uniform(0, 2 * np.pi, count)
        n = np.tile(inward * 1.0, (count, 1)) * np.cos(angle)[:, None]
        n[:, others[0]] += np.sin(angle) * np.cos(turn)
        n[:, others[1]] += np.sin(angle) * np.sin(turn)
        normals[:, c] = n
    return points, normals


def dexnet_q(metrics, wrenches: np.ndarray, normals: np.ndarray, params: Params,
             soft: bool) -> float:
    """Dex-Net's L1 metric of primitive wrenches (M, 6) (forces, unscaled torques: it scales
    them by ``params.torque_scaling``); ``soft``: it adds its two torsion primitives per
    contact of ``normals`` (k, 3)."""
    forces = wrenches[:, :3].T
    torques = wrenches[:, 3:].T / params.torque_scaling
    return float(metrics.ferrari_canny_L1(forces, torques, normals.T, soft_fingers=soft,
                                          params=params))


def run(metrics, args) -> dict:
    rng = np.random.default_rng(args.seed)
    scale = 1.0 / float(np.linalg.norm(HALF))
    params = Params(friction_coef=args.friction, finger_radius=args.radius,
                    torque_scaling=scale, wrench_norm_thresh=1e-3, wrench_regularizer=1e-10)
    common = {"friction": args.friction, "num_edges": args.edges, "torque_scale": scale}
    out = {}
    for kind, faces in (("pinch", PINCH_FACES), ("tripod", TRIPOD_FACES)):
        points, normals = contact_sets(faces, args.sets, math.radians(args.tilt), rng)
        same_gap, both_fc, verdicts_same, ours_fc, theirs_fc, ratios = [], 0, 0, 0, 0, []
        model_same = 0
        for p, n in zip(points, normals, strict=True):
            ours = contact_quality(p, n, contact_model="soft", finger_radius=args.radius,
                                   **common)
            primitives = contact_wrenches(p, n, contact_model="soft",
                                          finger_radius=args.radius, **common)
            theirs_same = dexnet_q(metrics, primitives, n, params, soft=False)
            verdicts_same += (ours > 0) == (theirs_same > 0)
            if ours > 0 and theirs_same > 0:
                both_fc += 1
                same_gap.append(abs(ours - theirs_same) / ours)
            edges = contact_wrenches(p, n, contact_model="point", **common)
            theirs_own = dexnet_q(metrics, edges, n, params, soft=True)
            ours_fc += ours > 0
            theirs_fc += theirs_own > 0
            model_same += (ours > 0) == (theirs_own > 0)
            if ours > 0 and theirs_own > 0:
                ratios.append(theirs_own / ours)
        gap = np.array(same_gap)
        ratio = np.array(ratios)
        out[kind] = {
            "sets": args.sets,
            "same_primitives_verdicts_agree": verdicts_same,
            "same_primitives_both_fc": both_fc,
            "same_primitives_rel_gap_median": float(np.median(gap)) if gap.size else None,
            "same_primitives_rel_gap_max": float(gap.max()) if gap.size else None,
            "own_models_verdicts_agree": model_same,
            "own_models_fc_ours": ours_fc,
            "own_models_fc_dexnet": theirs_fc,
            "own_models_q_ratio_median": float(np.median(ratio)) if ratio.size else None,
            "own_models_q_ratio_min": float(ratio.min()) if ratio.size else None,
            "own_models_q_ratio_max": float(ratio.max()) if ratio.size else None,
        }
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dexnet", type=Path, required=True,
                        help="Dex-Net's quality.py (graspnetAPI/utils/dexnet/grasping/)")
    parser.add_argument("--sets", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--friction", type=float, default=0.5)
    parser.add_argument("--edges", type=int, default=8)
    parser.add_argument("--radius", type=float, default=0.01)
    parser.add_argument("--tilt", type=float, default=10.0)
    add_options(parser, __file__)
    args = parser.parse_args(argv)
    if not args.dexnet.is_file():
        parser.error(f"--dexnet {args.dexnet}: no such file")
    metrics = load_dexnet(args.dexnet)
    rows = run(metrics, args)
    for kind, row in rows.items():
        print(f"{kind}: same primitives: verdicts agree {row['same_primitives_verdicts_agree']}"
              f"/{row['sets']}, Q relative gap median {row['same_primitives_rel_gap_median']:.2e}"
              f" max {row['same_primitives_rel_gap_max']:.2e} over "
              f"{row['same_primitives_both_fc']} sets in force closure; own models: verdicts "
              f"agree {row['own_models_verdicts_agree']}/{row['sets']} (force closure: ours "
              f"{row['own_models_fc_ours']}, Dex-Net {row['own_models_fc_dexnet']}), Dex-Net Q "
              f"/ ours median {row['own_models_q_ratio_median']}")
    if not args.no_json:
        write_result(__file__, {**rows, "settings": settings(args)}, args.json_out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
