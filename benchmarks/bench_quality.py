"""Ferrari-Canny quality: the fast exact path vs a plain per-grasp scipy ConvexHull loop.

Run: ``python benchmarks/bench_quality.py [--grasps 2000]``. Single-threaded (BLAS threads
pinned to 1 before numpy loads). Both paths see the same random contact sets (points on a
sphere, normals tilted up to ~0.3 rad); prints microseconds per grasp of the batch path
(compiled kernels loaded and tables built first), the ratio to the loop, the median of 100
single ``ferrari_canny`` calls, the share the exact paths could not certify (qhull serves
those), and that the answers agree (max relative difference over force-closure grasps, FC
decisions); and one soft-finger ``contact_quality`` call against one point-contact call on
the same contact sets (2-4 contacts).

The figures (seconds per grasp, ratios, shares) also go to
``benchmarks/results/bench_quality.json`` (``--json-out PATH``, ``--no-json``).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
from results_file import add_options, settings, write_result  # noqa: E402
from scipy.spatial import ConvexHull  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from quality_cases import sphere_contacts  # noqa: E402

from kinegrasp_env.quality import (  # noqa: E402
    FC_TOL,
    ferrari_canny,
    ferrari_canny_batch,
    wrench_matrix,
)
from kinegrasp_env.quality.expansion import epsilon_epa_batch  # noqa: E402
from kinegrasp_env.quality.soft_contacts import contact_quality  # noqa: E402
from kinegrasp_env.quality.three_contacts import candidate_tables, epsilon_three_contacts  # noqa: E402

TORQUE_SCALE = 20.0


def plain_loop(wrenches: np.ndarray) -> np.ndarray:
    """Q by one scipy ConvexHull per grasp (what a straightforward implementation does)."""
    out = np.empty(wrenches.shape[0])
    for i, w in enumerate(wrenches):
        offsets = ConvexHull(w).equations[:, -1]
        out[i] = max(0.0, -offsets.max())
    return out


def run(k: int, m: int, grasps: int, seed: int) -> dict:
    pts, nrm = sphere_contacts(np.random.default_rng(seed), grasps, k, jitter=0.3)
    w = wrench_matrix(pts, nrm, num_edges=m, torque_scale=TORQUE_SCALE)
    if k == 3:
        candidate_tables(m)  # build the constant tables outside the timing (cached)
    # load every kernel the timed calls use: the whole batch once (a part of it can miss a
    # rare path, which then compiled inside the timing when the kernels' cache was rebuilt)
    ferrari_canny_batch(pts, nrm, num_edges=m, torque_scale=TORQUE_SCALE)
    ferrari_canny(pts[0], nrm[0], num_edges=m, torque_scale=TORQUE_SCALE)
    start = time.perf_counter()
    fast = ferrari_canny_batch(pts, nrm, num_edges=m, torque_scale=TORQUE_SCALE)
    t_fast = time.perf_counter() - start
    n_plain = grasps if m <= 8 else max(50, grasps // 4)
    start = time.perf_counter()
    plain = plain_loop(w[:n_plain])
    t_plain = (time.perf_counter() - start) * grasps / n_plain
    # qhull's raw margin is ~1e-17 when the origin lies on the hull (an equilibrium that is
    # not force closure, e.g. two nearly antipodal contacts): both sides use one threshold
    scale = np.abs(w[:n_plain]).max(axis=(1, 2))
    boundary = (plain > 0) & (plain <= FC_TOL * scale)
    plain = np.where(boundary, 0.0, plain)
    fc = plain > 0
    same_fc = np.array_equal(fast[:n_plain] > 0, fc)
    rel = (np.abs(fast[:n_plain] - plain)[fc] / plain[fc]).max() if fc.any() else 0.0
    if k == 3:
        fallback = 1.0 - epsilon_three_contacts(w, m)[1].mean()
    else:
        fallback = 1.0 - epsilon_epa_batch(np.ascontiguousarray(w))[1].mean()
    single = single_median(pts, nrm, m)
    print(f"{k} contacts x {m:2d} edges: fast {t_fast / grasps * 1e6:8.1f} us/grasp | plain "
          f"ConvexHull loop {t_plain / grasps * 1e6:8.1f} us/grasp | ratio "
          f"{t_plain / t_fast:6.1f}x | single call median {single:6.1f} us"
          f" | qhull fallback {fallback:6.1%} | same FC: {same_fc} | "
          f"max rel diff {rel:.1e} | FC {fc.mean():.0%} | origin on hull {boundary.mean():.0%}")
    return {"contacts": k, "edges": m, "grasps": grasps, "plain_grasps": n_plain,
            "fast_s_per_grasp": t_fast / grasps, "plain_s_per_grasp": t_plain / grasps,
            "plain_over_fast": t_plain / t_fast, "single_call_median_s": single * 1e-6,
            "qhull_fallback_share": float(fallback), "same_fc": bool(same_fc),
            "max_rel_diff": float(rel), "fc_share": float(fc.mean()),
            "origin_on_hull_share": float(boundary.mean())}


def single_median(pts: np.ndarray, nrm: np.ndarray, m: int, calls: int = 100) -> float:
    """Median microseconds of one ``ferrari_canny`` call over the first ``calls`` grasps."""
    times = []
    for p, n in zip(pts[:calls], nrm[:calls], strict=False):
        start = time.perf_counter()
        ferrari_canny(p, n, num_edges=m, torque_scale=TORQUE_SCALE)
        times.append(time.perf_counter() - start)
    return float(np.median(times)) * 1e6


def soft_single(k: int, m: int, seed: int, calls: int = 200) -> dict:
    """Median microseconds of one ``contact_quality`` call, soft fingers against point
    contacts, on the same ``calls`` contact sets of k contacts (m cone edges)."""
    pts, nrm = sphere_contacts(np.random.default_rng(seed), calls, k, jitter=0.3)
    medians = {}
    for model in ("point", "soft"):
        for p, n in zip(pts[:5], nrm[:5], strict=True):  # loads the compiled kernels
            contact_quality(p, n, contact_model=model, num_edges=m, torque_scale=TORQUE_SCALE)
        times = []
        for p, n in zip(pts, nrm, strict=True):
            start = time.perf_counter()
            contact_quality(p, n, contact_model=model, num_edges=m, torque_scale=TORQUE_SCALE)
            times.append(time.perf_counter() - start)
        medians[model] = float(np.median(times))
    ratio = medians["soft"] / medians["point"]
    print(f"{k} contacts x {m:2d} edges, one call: soft {medians['soft'] * 1e6:6.1f} us, point "
          f"{medians['point'] * 1e6:6.1f} us: {ratio:.2f}x")
    return {"contacts": k, "edges": m, "calls": calls, "soft_median_s": medians["soft"],
            "point_median_s": medians["point"], "soft_over_point": ratio}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--grasps", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    add_options(parser, __file__)
    args = parser.parse_args()
    print("targets: batch >= 50x the plain loop on 3 contacts x 8 edges, >= 20x on "
          "4-5 contacts; single call median <= 50 us for k <= 5, m <= 12; exact")
    rows = [run(k, m, args.grasps if k == 3 else max(100, args.grasps // 10), args.seed)
            for k, m in ((3, 8), (3, 12), (3, 16), (4, 8), (5, 8), (5, 12))]
    print("target: a soft-finger call <= 2x a point-contact call at the same contact count")
    soft = [soft_single(k, 8, args.seed) for k in (2, 3, 4)]
    if not args.no_json:
        write_result(__file__, {"cases": rows, "soft_single_calls": soft,
                                "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
