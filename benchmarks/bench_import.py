"""Importing meshes nobody here wrote, and using them end to end.

Run: ``python benchmarks/bench_import.py [--home DIR] [--grasps 5] [--draws 2000]
[--reference-draws 200] [--rank-samples 200] [--agree-draws 40] [--only duck bunny]`` (tens
of minutes on 2 cores: CoACD and the planner dominate; ``--home`` keeps the catalog, so a
second run reuses the imports; the planned grasp files go to ``DIR/bench_grasps``).

1. Import five meshes of ``pybullet_data`` (duck.obj, y-up, scaled to 0.05; bunny.obj scaled
   from its 2 m to 0.2 m, objects/mug.obj, teddy2_VHACD_CHs.obj and random_urdfs/000/000.urdf)
   with the default CoACD settings: wall time, parts, size, r_max and the deviation of the
   parts from the mesh.
2. Plan ``--grasps`` force-closure grasps of each (``kinegrasp plan``'s planner): time and
   count; the grasps are written as a grasp file.
3. Per object, on that file: ``kinegrasp rank`` (fast engine, ``--rank-samples`` draws per
   grasp, sigma 0.0133): the top grasp and its P(FC) with its 95% interval; one episode of
   ``KineGraspEnv`` (reset, one step that moves the elbow and ends the episode): the reward;
   the engines' agreement of ``benchmarks/agreement.py`` (every planned grasp x
   ``--agree-draws`` draws x sigma 0.0133 and 0.0266): draws with the same outcome and the
   largest contact point, normal and Q differences, fast vs pybullet engine and each engine
   vs pybullet's own collision queries.
4. Grasp 0 of each, ``--draws`` noisy draws (sigma = 0.0133 rad) with the fast engine and
   ``--reference-draws`` with the pybullet engine, on one process, engines warm: draws/s,
   P(FC) of each engine, next to the built-in objects' shipped grasp 0, with the number of
   convex parts (both engines' cost per draw grows with the parts near the fingers).

Every table (seconds, draws/s, P(FC), millimetre deviations, agreement counts and
differences) also goes to ``benchmarks/results/bench_import.json`` (``--json-out PATH``,
``--no-json``).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import io
import os
import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pybullet_data
from results_file import add_options, settings, write_result

if TYPE_CHECKING:
    from kinegrasp_env.montecarlo.agreement import Agreement

#: (file in pybullet_data, --scale, --up, name)
MESHES = (
    ("duck.obj", 0.05, "y", "duck"),
    ("bunny.obj", 0.1, "z", "bunny"),
    ("objects/mug.obj", 1.0, "z", "pb_mug"),
    ("teddy2_VHACD_CHs.obj", 0.1, "z", "teddy"),
    ("random_urdfs/000/000.urdf", 1.0, "z", "blob000"),
)
SIGMA = 0.0133
#: Noise levels of the agreement check (radians), as in ``benchmarks/agreement.py``.
AGREE_SIGMAS = (0.0133, 0.0266)


def import_all(names: list[str], rows: list[dict]) -> list[str]:
    """Import the meshes of ``names``; print a line and append a row to ``rows`` each."""
    from kinegrasp_env.world.import_settings import ImportSettings
    from kinegrasp_env.world.importer import import_object

    done = []
    print(f"{'object':<8} {'import [s]':>10} {'parts':>5} {'size x, y, z [m]':<22} "
          f"{'r_max [m]':>9}  deviation [mm] lost max/mean, added max/mean")
    for file, scale, up, name in MESHES:
        if name not in names:
            continue
        path = os.path.join(pybullet_data.getDataPath(), file)
        result = import_object(path, name, ImportSettings(scale=scale, up=up))
        e, d = result.entry, result.entry["deviation"]
        seconds = e["import_seconds"]
        size = ", ".join(f"{v:.3f}" for v in e["size"])
        print(f"{name:<8} {seconds:>10.1f} {e['parts']:>5} {size:<22} {e['r_max']:>9.4f}  "
              f"{1e3 * d['missing_max']:.2f}/{1e3 * d['missing_mean']:.2f}, "
              f"{1e3 * d['added_max']:.2f}/{1e3 * d['added_mean']:.2f}"
              f"{'  (reused entry)' if result.reused else ''}", flush=True)
        rows.append({"object": name, "file": file, "import_s": seconds, "parts": e["parts"],
                     "size_m": list(e["size"]), "r_max_m": e["r_max"],
                     "lost_max_mm": 1e3 * d["missing_max"], "lost_mean_mm": 1e3 * d["missing_mean"],
                     "added_max_mm": 1e3 * d["added_max"], "added_mean_mm": 1e3 * d["added_mean"],
                     "reused": bool(result.reused)})
        done.append(name)
    return done


def plan_all(names: list[str], count: int, folder: Path, rows: list[dict]) -> dict:
    """{name: planned grasps}; each object's grasps also written to ``folder/NAME.json``, a
    row per object appended to ``rows``."""
    from kinegrasp_env.toolkit.grasp_planner import plan_grasps
    from kinegrasp_env.world.grasps import save_grasps

    folder.mkdir(parents=True, exist_ok=True)
    grasps = {}
    for name in names:
        start = time.perf_counter()
        found = plan_grasps("kuka_sdh", name, count=count, seed=0)
        seconds = time.perf_counter() - start
        grasps[name] = found
        if found:
            save_grasps(found, folder / f"{name}.json", planner_seed=0)
        print(f"{name:<8} plan: {len(found)} force-closure grasps in "
              f"{seconds:.1f} s; nominal Q "
              + ", ".join(f"{g.q_nominal:.4f}" for g in found), flush=True)
        rows.append({"object": name, "grasps": len(found), "plan_s": seconds,
                     "nominal_q": [g.q_nominal for g in found]})
    return grasps


def rate(engine_name: str, name: str, q0: np.ndarray, draws: int) -> tuple[float, float]:
    """(draws/s, P(FC)) of ``draws`` noisy draws of q0 through one warm engine."""
    from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
    from kinegrasp_env.montecarlo.engines import make_engine
    from kinegrasp_env.robot.catalog import DEFAULT_ROBOT
    from kinegrasp_env.sampling.noise import JointNoise
    from kinegrasp_env.sampling.noise_model import chunk_stream

    engine = make_engine(engine_name, DEFAULT_ROBOT, name)
    try:
        engine.run(np.repeat(q0[None], 4, axis=0))  # warm-up: grid, kernels, bodies
        q = np.repeat(q0[None], draws, axis=0)
        q[:, :7] += JointNoise(SIGMA).sample(draws, 7, chunk_stream(0, 0))  # chunk 0's stream
        start = time.perf_counter()
        out = engine.run(q)
        wall = time.perf_counter() - start
    finally:
        engine.close()
    return draws / wall, float(np.mean(out.outcome == FORCE_CLOSURE))


def engines(grasps: dict, draws: int, reference: int) -> list[dict]:
    from kinegrasp_env.world.grasps import shipped_grasps
    from kinegrasp_env.world.objects import OBJECT_NAMES, load_object

    rows = [(name, shipped_grasps(name)[0]) for name in OBJECT_NAMES]
    rows += [(name, found[0]) for name, found in grasps.items() if found]
    print(f"\n{'object':<12} {'parts':>5} {'fast draws/s':>12} {'P(FC)':>6} "
          f"{'pybullet draws/s':>16} {'P(FC)':>6}   (grasp 0, sigma {SIGMA} rad, 1 process)")
    out = []
    for name, grasp in rows:
        fast, p_fast = rate("fast", name, grasp.q0, draws)
        slow, p_slow = rate("pybullet", name, grasp.q0, reference)
        parts = len(load_object(name).parts)
        print(f"{name:<12} {parts:>5} {fast:>12.0f} {p_fast:>6.3f} "
              f"{slow:>16.0f} {p_slow:>6.3f}", flush=True)
        out.append({"object": name, "parts": parts, "fast_draws": draws,
                    "fast_draws_per_s": fast, "fast_p_fc": p_fast, "pybullet_draws": reference,
                    "pybullet_draws_per_s": slow, "pybullet_p_fc": p_slow})
    return out


def rank_file(grasp_file: Path, samples: int) -> tuple[float, dict]:
    """(seconds, best CSV row) of ``kinegrasp rank grasp_file --engine fast`` (in this process,
    its console table swallowed; the ranking goes next to the file as ``*_ranked.csv``)."""
    from kinegrasp_env.cli.main import main as kinegrasp

    out = grasp_file.with_name(f"{grasp_file.stem}_ranked.csv")
    start = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()):
        code = kinegrasp(["rank", str(grasp_file), "--samples", str(samples), "--seed", "0",
                          "--sigma", str(SIGMA), "--engine", "fast", "--out", str(out)])
    seconds = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f"kinegrasp rank {grasp_file} failed with exit status {code}")
    with open(out, newline="") as f:
        return seconds, next(csv.DictReader(f))


def episode(name: str, grasp_file: Path) -> tuple[float, float, dict]:
    """(seconds, reward, info) of one ``KineGraspEnv`` episode on the object's grasp file:
    reset(seed=0), then one step that moves the elbow half a step and ends the episode."""
    from kinegrasp_env.envs.kinegrasp import KineGraspEnv

    start = time.perf_counter()
    env = KineGraspEnv(objects=(name,), grasp_file=str(grasp_file), n_draws=8, engine="fast")
    try:
        env.reset(seed=0)
        _, reward, *_, info = env.step(np.array([0.5, 1.0], dtype=np.float32))
    finally:
        env.close()
    return time.perf_counter() - start, float(reward), info


def agree(name: str, grasps: list, draws: int) -> tuple[float, dict]:
    """(seconds, {comparison: Agreement over both sigmas}) of ``benchmarks/agreement.py``'s
    comparisons on ``grasps`` x ``draws`` draws x :data:`AGREE_SIGMAS` (seed 0)."""
    from agreement import compare_object  # benchmarks/agreement.py, next to this script

    start = time.perf_counter()
    per_sigma = [compare_object(name, sigma, grasps, draws, 0) for sigma in AGREE_SIGMAS]
    return time.perf_counter() - start, {
        label: merge([rows[label] for rows in per_sigma]) for label in per_sigma[0]}


def merge(parts: list[Agreement]) -> Agreement:
    """One Agreement of several runs: counts summed, largest differences the largest."""
    from kinegrasp_env.montecarlo.agreement import Agreement

    def most(field: str) -> float:
        values = [getattr(a, field) for a in parts if not np.isnan(getattr(a, field))]
        return max(values) if values else float("nan")

    return Agreement(**{f: sum(getattr(a, f) for a in parts) for f in (
        "draws", "same_outcome", "closed", "list_mismatch", "stop_mismatch", "contacts",
        "q_pairs")}, **{f: most(f) for f in (
        "point_max", "normal_max", "offset_max", "offset_normal_max", "q_max", "q_abs_max",
        "q_abs_max_untied")}, point_median=float("nan"))


def end_to_end(grasps: dict, folder: Path, rank_samples: int, agree_draws: int) -> dict:
    """Rank, one env episode and the engines' agreement of each object's planned grasps
    (printed; returned as lists of rows ``rank``, ``env`` and ``agreement``)."""
    print(f"\nrank: fast engine, {rank_samples} draws per grasp, sigma {SIGMA}; env: reset "
          f"+ one step, 8 draws; agreement: every grasp x {agree_draws} draws x sigma "
          f"{'/'.join(map(str, AGREE_SIGMAS))}")
    out: dict[str, list[dict]] = {"rank": [], "env": [], "agreement": []}
    for name, found in grasps.items():
        if not found:
            continue
        grasp_file = folder / f"{name}.json"
        seconds, best = rank_file(grasp_file, rank_samples)
        print(f"{name:<8} rank: {len(found)} grasps in {seconds:.1f} s; top {best['id']} "
              f"P(FC) {float(best['p_fc']):.3f} [{float(best['p_fc_lo']):.3f}, "
              f"{float(best['p_fc_hi']):.3f}]", flush=True)
        out["rank"].append({"object": name, "grasps": len(found), "rank_s": seconds,
                            "top": best["id"], "p_fc": float(best["p_fc"]),
                            "p_fc_lo": float(best["p_fc_lo"]),
                            "p_fc_hi": float(best["p_fc_hi"])})
        seconds, reward, info = episode(name, grasp_file)
        print(f"{name:<8} env: grasp {info['grasp']}, sigma {info['sigma']:.4f}, reward "
              f"{reward:.3f} (P(FC) {info['p_fc']:.3f}) in {seconds:.1f} s", flush=True)
        out["env"].append({"object": name, "grasp": info["grasp"], "sigma": info["sigma"],
                           "reward": reward, "p_fc": info["p_fc"], "episode_s": seconds})
        seconds, rows = agree(name, found, agree_draws)
        for label, a in rows.items():
            offset = "" if np.isnan(a.offset_max) else (
                f", offset max {a.offset_max:.1e} m, off.nrm max {a.offset_normal_max:.3f} deg")
            print(f"{name:<8} {label:<18} same outcome {a.same_outcome}/{a.draws} "
                  f"({a.same_outcome / a.draws:.3f}); point max {a.point_max:.1e} m, normal "
                  f"max {a.normal_max:.3f} deg, Q abs max {a.q_abs_max:.1e} (untied "
                  f"{a.q_abs_max_untied:.1e}, rel {a.q_max:.1e}, {a.q_pairs} FC pairs)"
                  f"{offset}", flush=True)
            out["agreement"].append({"object": name, "comparison": label,
                                     "same_outcome_fraction": a.same_outcome / a.draws,
                                     **dataclasses.asdict(a)})
        print(f"{name:<8} agreement: {seconds:.1f} s", flush=True)
        for row in out["agreement"]:
            if row["object"] == name:
                row["agreement_s"] = seconds
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--home", help="catalog folder ($KINEGRASP_HOME; default: a new "
                        "temporary one)")
    parser.add_argument("--grasps", type=int, default=5, help="grasps to plan per object")
    parser.add_argument("--draws", type=int, default=2000, help="fast-engine draws")
    parser.add_argument("--reference-draws", type=int, default=200,
                        help="pybullet-engine draws")
    parser.add_argument("--rank-samples", type=int, default=200,
                        help="rank: fast-engine draws per planned grasp")
    parser.add_argument("--agree-draws", type=int, default=40,
                        help="agreement: draws per planned grasp and sigma")
    names = [m[-1] for m in MESHES]
    parser.add_argument("--only", nargs="*", default=names, choices=names,
                        help="meshes to use, by name")
    add_options(parser, __file__)
    args = parser.parse_args()
    os.environ["KINEGRASP_HOME"] = args.home or tempfile.mkdtemp(prefix="kinegrasp-home-")
    print(f"catalog: {os.environ['KINEGRASP_HOME']}")
    folder = Path(os.environ["KINEGRASP_HOME"]) / "bench_grasps"
    imports: list[dict] = []
    plans: list[dict] = []
    names = import_all(args.only, imports)
    grasps = plan_all(names, args.grasps, folder, plans) if args.grasps > 0 else {}
    record = {"catalog": os.environ["KINEGRASP_HOME"], "imports": imports, "plans": plans,
              **end_to_end(grasps, folder, args.rank_samples, args.agree_draws),
              "engines": engines(grasps, args.draws, args.reference_draws)}
    if not args.no_json:
        write_result(__file__, {**record, "settings": settings(args)}, args.json_out)


if __name__ == "__main__":
    main()
