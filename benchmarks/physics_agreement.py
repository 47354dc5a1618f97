"""Which score predicts what physics does: every kinematic score of a draw against the holding
test's verdict on the same draw, as ROC AUCs with bootstrap intervals.

Draws and labels:

* **kuka_sdh** (the paper's arm and hand): the shipped grasps of ``--objects`` (default the four
  built-in ones), ``--samples`` draws each at joint noise ``--sigma`` and ``--seed``: exactly the
  draws of ``kinegrasp validate`` with those options, labelled *held* or not by the holding test
  in pybullet and in MuJoCo (the runs of ``benchmarks/simulator_agreement.py``, cached in
  ``--out``; run together they share the cache).
* **panda** (parallel jaws): its shipped grasps (and, on an object with none shipped, the
  antipodal planner's, ``--plan`` of them), on the built-in objects and on thin-walled and
  handled ones imported as a user imports a mesh (``--imported``: ``benchmarks/
  thin_objects.py``'s tube, tray and cup, in a catalog of the benchmark's own under
  ``--out`` unless ``KINEGRASP_HOME`` is set), ``--samples`` draws each at every joint noise of
  ``--panda-sigmas`` (palm poses a little and further off the planned one: at 0.0133 rad most
  of its draws drop, near 0 most hold, so both occur), labelled by the holding test in
  pybullet and in MuJoCo (the Panda's hand cut from its URDF in each).

Scores of each draw (the kinematic engines of a description robot, on the same
configuration; higher: predicted to hold):

* ``fc``: its closing in force closure (0/1); ``q``: its Ferrari-Canny Q (both with the
  robot's contact model);
* ``fc_patch``, ``q_patch``: the same with the patch contact model (a flat pad on a face
  scored as its patch's corners: :mod:`kinegrasp_env.montecarlo.patch_contacts`; rounded
  fingertips stay points);
* ``p_fc``: P(FC) of ``--pfc-samples`` further draws at ``--sigma`` around it (fast engine;
  kuka_sdh: a tenth of them, at least 10, by its reference engine);
* ``p_hold_static``: the static hold check's P(hold) on those same draws (what ``rank
  --criterion hold_static`` ranks by);
* ``static_hold``: the static hold check's verdict (0/1: the contacts carry the catalog mass
  in six gravity directions and the lift within the hand's effort limits);
* ``hold_capacity``: the largest multiple of that load they carry (continuous);
* ``quick_hold``: the quick holding test in pybullet (``QUICK_PROTOCOL``; 0/1): against
  MuJoCo's labels it is a dynamic score judged by the other simulator;
* ``quick_hold_mujoco``: the same quick test in MuJoCo: against pybullet's labels, the other
  simulator's dynamic score the other way round (a yes/no score's AUC is its balanced
  accuracy, which is not symmetric in score and label);
* ``hold_margin``, ``hold_margin_mujoco``: how far the draw got through the quick test in
  each simulator (:func:`~kinegrasp_env.physics.protocol.hold_margin`: the phases held in a
  row, then how little the object moved; continuous, every held draw above every other), the
  dynamic scores as rankings rather than yes/no;
* baselines from geometry alone: ``-centre_distance`` (the fingertips' centre at the
  pre-shape to the centre of mass, negated).

AUC: the Mann-Whitney probability that a held draw scores above a dropped one (ties count
half); its interval: the 2.5 and 97.5 percentiles of 10,000 bootstrap resamples of the
grasps (seed 0), each resampled grasp with all its draws (the draws of one grasp are not
independent of each other: resampling them one by one would give intervals too narrow). A
score predicts better than chance where the interval's lower end is above 0.5. Each score
against the geometry baseline: the difference of their AUCs on the same resamples (paired),
its interval simultaneous at 95% over the scores compared (Bonferroni: percentiles at 2.5 / k
and 100 - 2.5 / k for k scores); a score beats the baseline where the lower end is above 0.
Two more families, each simultaneous over its two pairs (:data:`FAMILIES`): each quick
test's margin against its own verdict, and the patch model's force closure and Q against
the robot's own contact model's.
Written as JSON (``benchmarks/results/physics_agreement.json``) and as a table in the physics
guide between ``<!-- physics-agreement:start -->`` and ``<!-- physics-agreement:end -->``.

    python benchmarks/physics_agreement.py [--objects cube drill] [--samples 3]
        [--sigma 0.0133] [--panda-sigmas 0.0033 0.0133] [--out out/simulator_agreement]

The holding tests take most of the time: 1-4 s per draw and simulator for kuka_sdh, about
0.5 s for panda.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import os
import sys
import time
from pathlib import Path

import numpy as np
from marked_section import write_between
from quick_hold import configurations
from results_file import add_options, settings, write_result
from scipy.stats import rankdata
from simulator_agreement import SIMULATORS, run_validate
from thin_objects import THIN_OBJECTS, import_thin_objects

from kinegrasp_env.montecarlo.chunks import chunk_configurations
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE, DrawBatch
from kinegrasp_env.montecarlo.engines import make_engine
from kinegrasp_env.montecarlo.hold_engine import RobotHoldEngine, quick_hold_engine
from kinegrasp_env.physics.protocol import HELD, HOLD_OUTCOMES, HoldProtocol
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.toolkit.grasp_planner import plan_grasps
from kinegrasp_env.world.grasps import shipped_grasps, shipped_objects
from kinegrasp_env.world.objects import OBJECT_NAMES

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "guides" / "physics.md"
START, END = "<!-- physics-agreement:start -->", "<!-- physics-agreement:end -->"
SCORES = ("fc", "q", "fc_patch", "q_patch", "p_fc", "p_hold_static", "static_hold",
          "hold_capacity", "quick_hold", "quick_hold_mujoco", "hold_margin",
          "hold_margin_mujoco", "-centre_distance")
BOOTSTRAP = 10_000
#: The geometry-only score every other score is compared with.
BASELINE = "-centre_distance"
#: The further families of paired comparisons: name -> (score -> its reference, what the
#: table says of them).
FAMILIES = {
    "margin_over_verdict": ({"hold_margin": "quick_hold",
                             "hold_margin_mujoco": "quick_hold_mujoco"},
                            "Each quick test's margin less its yes/no verdict"),
    "patch_over_own": ({"fc_patch": "fc", "q_patch": "q"},
                       "The patch model's scores less the robot's own model's"),
}


def auc(score: np.ndarray, label: np.ndarray) -> float:
    """The Mann-Whitney AUC (ties count half); NaN without both classes."""
    positives, negatives = int(label.sum()), int((~label).sum())
    if positives == 0 or negatives == 0:
        return float("nan")
    ranks = rankdata(score)
    return float((ranks[label].sum() - positives * (positives + 1) / 2)
                 / (positives * negatives))


def grasp_resamples(groups: np.ndarray, seed: int = 0) -> list[np.ndarray]:
    """:data:`BOOTSTRAP` resamples of the draws by grasp: each one's rows (the draws of as
    many grasps as there are, drawn with replacement; ``groups`` (n,): each draw's grasp).
    Every score's interval is taken over the same resamples."""
    members = [np.flatnonzero(groups == g) for g in dict.fromkeys(groups.tolist())]
    rng = np.random.default_rng(seed)
    return [np.concatenate([members[k] for k in rng.integers(0, len(members), len(members))])
            for _ in range(BOOTSTRAP)]


def auc_interval(score: np.ndarray, label: np.ndarray,
                 resamples: list[np.ndarray]) -> list[float]:
    """The 95% percentile bootstrap interval of :func:`auc` over ``resamples``
    (:func:`grasp_resamples`)."""
    values = []
    for pick in resamples:
        value = auc(score[pick], label[pick])
        if not np.isnan(value):
            values.append(value)
    return [float(np.percentile(values, 2.5)), float(np.percentile(values, 97.5))]


def paired_differences(scores: dict, label: np.ndarray, resamples: list[np.ndarray],
                       pairs: list[tuple[str, str]]) -> dict:
    """Per (score, reference) of ``pairs``: the score's AUC less the reference's, and the
    interval of that difference over the same ``resamples`` of the grasps
    (:func:`grasp_resamples`: paired), simultaneous at 95% over the pairs (keyed by the
    score)."""
    values = {name: [] for name, _ in pairs}
    for pick in resamples:
        for name, reference in pairs:
            value = auc(scores[name][pick], label[pick]) - auc(scores[reference][pick],
                                                                  label[pick])
            if not np.isnan(value):
                values[name].append(value)
    tail = 2.5 / len(pairs)
    return {name: {"reference": reference,
                   "difference": auc(scores[name], label) - auc(scores[reference], label),
                   "ci95_simultaneous": [float(np.percentile(values[name], tail)),
                                         float(np.percentile(values[name], 100 - tail))]}
            for name, reference in pairs}


def draw_scores(robot: str, obj: str, q: np.ndarray, sigma: float, pfc_samples: int,
                seed: int) -> dict[str, np.ndarray]:
    """Every score (module docstring) of configurations q (n, dof)."""
    engine_name = "pybullet" if robot == "kuka_sdh" else "fast"  # the SDH's capsule tips
    with make_engine(engine_name, robot, obj, static_hold=True) as engine:
        batch = engine.close_batch(engine.check(q))
        draws: DrawBatch = engine.scored(q, batch)
        touched = draws.n_contacts > 0
        capacity = np.zeros(q.shape[0])
        if touched.any():
            rows = np.flatnonzero(touched)
            capacity[rows] = engine.hold_check.capacity(
                q[rows], {k: v[rows] for k, v in batch.joints.items()}, draws.points[rows],
                draws.normals[rows], draws.finger[rows], draws.link[rows])
        description = engine.description
        tips = [finger.tip for finger in description.fingers]
        poses = engine.hold_check.kinematics.forward(q, tips)
        centre = np.mean([poses[t][:, :3, 3] for t in tips], axis=0)
        centre = centre @ engine.obj.pose_inverse[:3, :3].T + engine.obj.pose_inverse[:3, 3]
        distance = np.linalg.norm(centre - engine.obj.center_of_mass, axis=1)
        fc = (draws.outcome == FORCE_CLOSURE).astype(float)
    patched = dataclasses.replace(description, contact_model="patch")
    with make_engine(engine_name, patched, obj) as engine:
        patch_draws = engine.run(q)
    with make_engine("fast" if robot != "kuka_sdh" else "pybullet", robot, obj,
                     static_hold=True) as engine:
        arm = engine.description.arm_dof
        rng = np.random.default_rng(seed)
        p_fc, p_hold_static = np.zeros(q.shape[0]), np.zeros(q.shape[0])
        count = pfc_samples if robot != "kuka_sdh" else max(pfc_samples // 10, 10)
        for i, row in enumerate(q):
            around = np.repeat(row[None], count, axis=0)
            around[:, :arm] += JointNoise(sigma).sample(count, arm, rng)
            nearby = engine.run(around)
            p_fc[i] = float((nearby.outcome == FORCE_CLOSURE).mean())
            p_hold_static[i] = float(nearby.holds.mean())
    return {"fc": fc, "q": draws.quality,
            "fc_patch": (patch_draws.outcome == FORCE_CLOSURE).astype(float),
            "q_patch": patch_draws.quality, "p_fc": p_fc, "p_hold_static": p_hold_static,
            "static_hold": draws.holds.astype(float), "hold_capacity": capacity,
            **quick_hold(robot, obj, q, "pybullet", ""),
            **quick_hold(robot, obj, q, "mujoco", "_mujoco"),
            "-centre_distance": -distance}


def quick_hold(robot: str, obj: str, q: np.ndarray, simulator: str,
               suffix: str) -> dict[str, np.ndarray]:
    """The quick holding test in ``simulator`` of configurations q (n, dof): ``quick_hold``
    (n,) 1.0 where it holds, ``hold_margin`` (n,) how far each draw got through it, each
    name with ``suffix``."""
    engine = quick_hold_engine(robot, obj, simulator=simulator)
    try:
        hold = engine.run_hold(q)[1]
    finally:
        engine.close()
    return {f"quick_hold{suffix}": (hold.outcome == HELD).astype(float),
            f"hold_margin{suffix}": hold.margin(engine.protocol)}


def kuka_draws(objects: list[str], args) -> tuple[dict, dict, dict]:
    """The kuka_sdh draws' scores, their labels per simulator, and per object the draws and
    those held in pybullet."""
    labels: dict[str, list[bool]] = {s: [] for s in SIMULATORS}
    composition, groups = {}, []
    scores: dict[str, list[np.ndarray]] = {s: [] for s in SCORES}
    validate = argparse.Namespace(grasp=list(range(12)), sigma=args.sigma,
                                  samples=args.samples, seed=args.seed)
    for obj in objects:
        held = {}
        for simulator in SIMULATORS:
            path = run_validate(simulator, obj, validate, args.out)
            with path.open() as handle:
                held[simulator] = {(int(r["grasp"]), int(r["draw"])): r["hold_outcome"] == "held"
                                   for r in csv.DictReader(handle)}
        grasps = shipped_grasps(obj)
        # rows 0 .. samples - 1 of each grasp's run (the draws validate ran; 7 arm joints)
        q = np.concatenate([chunk_configurations(g.q0, 7, args.sigma, "gaussian", args.seed,
                                                 0, args.samples) for g in grasps])
        keys = [(i, d) for i in range(len(grasps)) for d in range(args.samples)]
        groups += [f"{obj}/{i}" for i, _ in keys]
        for simulator in SIMULATORS:
            labels[simulator] += [held[simulator][k] for k in keys]
        composition[obj] = {"draws": len(keys)} | {
            f"held_{s}": sum(held[s][k] for k in keys) for s in SIMULATORS}
        for name, value in draw_scores("kuka_sdh", obj, q, args.sigma, args.pfc_samples,
                                       args.seed).items():
            scores[name].append(value)
        print(f"  kuka_sdh {obj}: {len(keys)} draws scored", file=sys.stderr)
    return ({k: np.concatenate(v) for k, v in scores.items()},
            {k: np.array(v) for k, v in labels.items()}, composition, np.array(groups))


def panda_draws(objects: list[str], args) -> tuple[dict, dict, dict]:
    """The panda draws' scores, their labels per simulator, and per object the draws and
    those held in each simulator."""
    labels: dict[str, list[bool]] = {s: [] for s in SIMULATORS}
    composition, groups = {}, []
    scores: dict[str, list[np.ndarray]] = {s: [] for s in SCORES}
    protocol = HoldProtocol()
    for obj in objects:
        grasps = (shipped_grasps(obj, robot="panda") if obj in shipped_objects("panda")
                  else plan_grasps("panda", obj, count=args.plan, seed=args.seed))
        if not grasps:
            print(f"  panda {obj}: no grasp planned, skipped", file=sys.stderr)
            continue
        q = configurations(grasps, args.panda_sigmas, args.samples, args.seed)
        start = time.perf_counter()
        composition[obj] = {"grasps": len(grasps), "draws": int(q.shape[0])}
        groups += [f"{obj}/{i}" for i in range(len(grasps))
                   for _ in range(q.shape[0] // len(grasps))]  # each grasp's rows in turn
        for simulator in SIMULATORS:
            with RobotHoldEngine("panda", obj, protocol=protocol,
                                 simulator=simulator) as physics:
                _, hold = physics.run_hold(q)
            labels[simulator] += list(hold.outcome == HELD)
            composition[obj][f"held_{simulator}"] = int((hold.outcome == HELD).sum())
            counts = np.bincount(hold.outcome, minlength=len(HOLD_OUTCOMES))
            print(f"  panda {obj} {simulator}: " + ", ".join(
                f"{name} {count}" for name, count in zip(HOLD_OUTCOMES, counts, strict=True)),
                file=sys.stderr)
        for name, value in draw_scores("panda", obj, q, args.sigma, args.pfc_samples,
                                       args.seed).items():
            scores[name].append(value)
        print(f"  panda {obj}: {q.shape[0]} draws, holding tests "
              f"{time.perf_counter() - start:.0f} s", file=sys.stderr)
    return ({k: np.concatenate(v) for k, v in scores.items()},
            {k: np.array(v) for k, v in labels.items()}, composition, np.array(groups))


def table(scores: dict, labels: dict, groups: np.ndarray) -> dict:
    """Per simulator: draws, held, and per score its AUC and interval."""
    out, resamples = {}, grasp_resamples(groups)
    for simulator, label in labels.items():
        record = {"draws": int(label.size), "held": int(label.sum())}
        for name in SCORES:
            record[name] = {"auc": auc(scores[name], label),
                            "ci95": auc_interval(scores[name], label, resamples)}
        record["above_baseline"] = paired_differences(
            scores, label, resamples, [(name, BASELINE) for name in SCORES if name != BASELINE])
        for family, (pairs, _) in FAMILIES.items():
            record[family] = paired_differences(scores, label, resamples, list(pairs.items()))
        out[simulator] = record
    return out


def label_agreement(labels: dict) -> dict:
    """The two simulators' verdicts on the same draws: how many agree, the Wilson 95%
    interval of the rate, and Cohen's kappa (agreement beyond what the held rates alone
    give)."""
    first, second = (labels[s] for s in SIMULATORS)
    same, n = int((first == second).sum()), int(first.size)
    if n == 0:
        return {"same": 0, "draws": 0, "ci95": [float("nan")] * 2, "kappa": float("nan")}
    chance = first.mean() * second.mean() + (1 - first.mean()) * (1 - second.mean())
    kappa = float((same / n - chance) / (1 - chance)) if chance < 1 else float("nan")
    return {"same": same, "draws": n, "ci95": list(wilson_interval(same, n)), "kappa": kappa}


def markdown(result: dict) -> str:
    """The AUC table, then the draws per object."""
    lines = ["| robot | simulator | draws | held | " + " | ".join(SCORES) + " |",
             "|---" * (len(SCORES) + 4) + "|"]
    for robot, per in result["robots"].items():
        for simulator, record in per.items():
            cells = [f"{record[s]['auc']:.2f} [{record[s]['ci95'][0]:.2f}, "
                     f"{record[s]['ci95'][1]:.2f}]" for s in SCORES]
            lines.append(f"| {robot} | {simulator} | {record['draws']} | {record['held']} | "
                         + " | ".join(cells) + " |")
    others = [name for name in SCORES if name != BASELINE]
    lines += ["", f"AUC less {BASELINE}'s on the same draws (paired bootstrap over the "
              f"grasps; intervals simultaneous at 95% over the {len(others)} scores):", "",
              "| robot | simulator | " + " | ".join(others) + " |",
              "|---" * (len(others) + 2) + "|"]
    for robot, per in result["robots"].items():
        for simulator, record in per.items():
            cells = [f"{d['difference']:+.2f} [{d['ci95_simultaneous'][0]:+.2f}, "
                     f"{d['ci95_simultaneous'][1]:+.2f}]"
                     for d in (record["above_baseline"][s] for s in others)]
            lines.append(f"| {robot} | {simulator} | " + " | ".join(cells) + " |")
    for family, (pairs, words) in FAMILIES.items():
        lines += ["", f"{words} on the same draws (paired bootstrap over the grasps; intervals "
                  f"simultaneous at 95% over its {len(pairs)} pairs):", "",
                  "| robot | simulator | " + " | ".join(
                      f"{name} - {reference}" for name, reference in pairs.items()) + " |",
                  "|---" * (len(pairs) + 2) + "|"]
        for robot, per in result["robots"].items():
            for simulator, record in per.items():
                cells = [f"{d['difference']:+.2f} [{d['ci95_simultaneous'][0]:+.2f}, "
                         f"{d['ci95_simultaneous'][1]:+.2f}]"
                         for d in (record[family][name] for name in pairs)]
                lines.append(f"| {robot} | {simulator} | " + " | ".join(cells) + " |")
    lines += ["", "| robot | verdicts the same in both simulators | 95% interval | "
                  "Cohen's kappa |", "|---|---|---|---|"]
    for robot, record in result["simulators_agree"].items():
        lines.append(f"| {robot} | {record['same']} of {record['draws']} | "
                     f"{record['ci95'][0]:.2f}-{record['ci95'][1]:.2f} | "
                     f"{record['kappa']:.2f} |")
    lines += ["", "| robot | object | draws | " + " | ".join(
        f"held ({s})" for s in SIMULATORS) + " |", "|---" * (3 + len(SIMULATORS)) + "|"]
    for robot, per in result["composition"].items():
        for obj, record in per.items():
            lines.append(f"| {robot} | {obj} | {record['draws']} | " + " | ".join(
                str(record[f"held_{s}"]) for s in SIMULATORS) + " |")
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--objects", nargs="+", default=list(OBJECT_NAMES),
                        choices=OBJECT_NAMES)
    parser.add_argument("--robots", nargs="+", default=["kuka_sdh", "panda"],
                        choices=["kuka_sdh", "panda"])
    parser.add_argument("--samples", type=int, default=3)
    parser.add_argument("--sigma", type=float, default=0.0133)
    parser.add_argument("--panda-sigmas", type=float, nargs="+", default=[0.0033, 0.0133])
    parser.add_argument("--pfc-samples", type=int, default=200)
    parser.add_argument("--plan", type=int, default=4)
    parser.add_argument("--imported", nargs="*", default=list(THIN_OBJECTS),
                        choices=THIN_OBJECTS)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=ROOT / "out" / "simulator_agreement")
    parser.add_argument("--page", type=Path, default=PAGE)
    parser.add_argument("--no-page", action="store_true")
    add_options(parser, __file__)
    args = parser.parse_args()
    os.environ.setdefault("KINEGRASP_HOME", str(args.out / "catalog"))
    imported = import_thin_objects(args.out / "meshes", args.imported)
    result = {"robots": {}, "simulators_agree": {}, "composition": {}}
    for robot in args.robots:
        runner = kuka_draws if robot == "kuka_sdh" else panda_draws
        scores, labels, composition, groups = runner(
            args.objects + (imported if robot == "panda" else []), args)
        result["robots"][robot] = table(scores, labels, groups)
        result["simulators_agree"][robot] = label_agreement(labels)
        result["composition"][robot] = composition
    text = markdown(result)
    print(text)
    if not args.no_json:
        write_result(__file__, {**result, "settings": settings(args)}, args.json_out)
    if not args.no_page:
        write_between(args.page, START, END, text)


if __name__ == "__main__":
    main()
