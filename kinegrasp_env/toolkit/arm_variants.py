"""Configurations of one palm pose (the paper's Figs. 7 and 10: the same contacts reached with
different arm configurations), for any robot, and the rows of their evaluation.

The variants of a 7-joint arm are ``count`` configurations picked evenly (by index) from
:func:`~kinegrasp_env.toolkit.elbow_search.robot_reachable_configurations` (the self-motion
walked every :data:`~kinegrasp_env.toolkit.elbow.FINE_STEP` radians of psi, within the joint
limits and clear of the object); for a 6-joint arm, which has no self-motion, they are the
palm pose's IK branches (:func:`~kinegrasp_env.toolkit.elbow_search.branch_variants`, at most
``count``). Either kind is kept where its nominal closing is in force closure (at the engine's
friction: the run's). Each is evaluated on ``samples`` draws of joint noise on the arm joints
(:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`, seed ``seed``: the
draws of ``kinegrasp evaluate --robot NAME --seed SEED``); with two variants or more, the most
and the least robust (chosen on those draws) are reported again on fresh draws (the rows after
the selection's in the same run: :func:`~kinegrasp_env.toolkit.selection.robust_fragile`) with
the paired difference of their force-closure indicators and its Student-t 95% interval.
"""

from __future__ import annotations

import itertools
from collections.abc import Collection, Mapping
from dataclasses import replace

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import (
    RobotReferenceEngine,
    evaluate_grasp,
    make_engine,
)
from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.montecarlo.palm_batch import BATCH_FACTOR
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.ik_branches import DEFAULT_STARTS as DEFAULT_IK_STARTS
from kinegrasp_env.toolkit.elbow_search import (
    branch_variants,
    robot_reachable_configurations,
)
from kinegrasp_env.toolkit.progress import Progress, reported_cell
from kinegrasp_env.toolkit.selection import report_rows, robust_fragile
from kinegrasp_env.world.grasps import Grasp

#: The columns of the chosen pair (empty for the other variants): P(FC) on the fresh draws
#: with its Wilson 95% interval, the selection's estimate, the paired gap (robust - fragile)
#: with its Student-t 95% interval, and Q's mean, variance and skewness over the fresh
#: draws in force closure.
PAIR_COLUMNS = ("config", "fresh_p_fc", "fresh_p_fc_lo", "fresh_p_fc_hi", "fresh_samples",
                "selection_p_fc", "gap", "gap_lo", "gap_hi", "fresh_q_mean", "fresh_q_var",
                "fresh_q_skew")
#: A variant row's columns (fig7.csv, fig10.csv): the robot and the variant's elbow angle
#: (7-joint arms) or IK branch label (6-joint arms) first; then ``estimate``: ``direct``
#: (its own draws) or ``reweighted`` (from one batch: ``samples`` is then its effective
#: sample size), and P(FC)'s 95% interval (Wilson's, at the effective number of draws where
#: re-weighted), last so that readers of the older columns by position keep working.
COLUMNS = ("robot", "object", "id", "elbow_angle", "ik_branch", "p_fc", "q_mean", "q_std",
           "q_nominal", "error", "samples", "sigma", *PAIR_COLUMNS, "estimate", "p_fc_lo",
           "p_fc_hi")


def check_variants(description: RobotDescription, experiment: str) -> None:
    """ValueError (one line, naming ``experiment``) unless the robot's arm has configuration
    variants of one palm pose: a 7-joint arm's self-motion or a 6-joint arm's IK branches."""
    if not (description.arm_dof == 6 or description.has_self_motion):
        raise ValueError(f"robot {description.name!r} has {description.arm_dof} arm joints"
                         f"{'' if description.arm_angle_links else ' and no elbow angle'}; "
                         f"{experiment}'s variants are a 7-joint arm's self-motion or a "
                         "6-joint arm's IK branches")


def variant_label(row: Mapping, digits: int = 3) -> str:
    """A variant row's configuration in words: its elbow angle (``digits`` decimals) or its
    IK branch."""
    if row.get("ik_branch"):
        return f"IK branch {row['ik_branch']}"
    return f"elbow {row['elbow_angle']:+.{digits}f} rad"


def variants_of(grasp: Grasp, engine: RobotReferenceEngine, count: int,
                taken: Collection[str] = ()) -> list[Grasp]:
    """Up to ``count`` configurations of the grasp's palm pose (see the module docstring; a
    6-joint arm's first ``count`` IK branches, the grasp's own always among them), as grasps
    with the grasp's palm pose and contacts, ids ``<id>v<k>`` (k from 1, skipping the ids in
    ``taken``: those of the set the grasp came from, whose own variants may bear them), their
    nominal Q and ``meta["elbow_angle"]`` (radians) or ``meta["ik_branch"]`` (the branch's
    label)."""
    if engine.description.arm_dof == 6:
        branches, nominal = branch_variants(grasp, engine, DEFAULT_IK_STARTS)
        kept = list(range(min(count, len(branches))))
        if nominal not in kept:  # the grasp's own branch always among them
            kept[-1] = nominal
        hand = engine.check(grasp.q0)[0][engine.description.arm_dof:]
        found = [({"ik_branch": branches[i].label}, np.concatenate([branches[i].q, hand]))
                 for i in kept]
    else:
        reach = robot_reachable_configurations(grasp, engine)
        pick = np.unique(np.round(np.linspace(0, len(reach) - 1, count)).astype(int))
        found = [({"elbow_angle": float(reach[i][0])}, reach[i][1]) for i in pick]
    out = []
    names = (name for k in itertools.count(1) if (name := f"{grasp.id}v{k}") not in taken)
    for where, q in found:
        name = next(names)
        draw = engine.run(np.asarray(q, dtype=float)[None])
        if draw.outcome[0] != FORCE_CLOSURE:
            continue
        out.append(replace(grasp, q0=np.asarray(q, dtype=float), id=name,
                           q_nominal=float(draw.quality[0]),
                           meta={**grasp.meta, **where, "variant_of": grasp.id}))
    return out


def find_variants(description: RobotDescription, name: str, grasp: Grasp, count: int,
                  friction: float = 0.5, taken: Collection[str] = ()) -> list[Grasp]:
    """:func:`variants_of` ``grasp`` (a grasp of ``description`` on object ``name``; ids not
    in ``taken``), on the reference engine with the contacts' friction coefficient
    ``friction``."""
    with RobotReferenceEngine(description, name, friction=friction) as reference:
        return variants_of(grasp, reference, count, taken)


def variant_work(variants: list[Grasp], samples: int, method: str = "direct"
                 ) -> tuple[int, int]:
    """(cells, draws) of :func:`variant_block` on ``variants``: a direct evaluation of
    ``samples`` draws per variant (``method`` direct) or one batch of ``BATCH_FACTOR *
    samples`` closings for them all (reweight; a variant the batch cannot answer adds a
    direct cell when it runs), and the chosen pair's two fresh evaluations where there are
    two variants or more."""
    fresh = 2 if len(variants) >= 2 else 0
    if not variants:
        return 0, 0
    if method == "reweight":
        return 1 + fresh, BATCH_FACTOR * samples + fresh * samples
    return len(variants) + fresh, (len(variants) + fresh) * samples


def variant_block(description: RobotDescription, name: str, variants: list[Grasp], *,
                  samples: int, sigma: float, seed: int, engine: str, friction: float,
                  method: str = "direct", executor: Executor | None = None,
                  report: Progress | None = None) -> tuple[list[dict], list]:
    """(rows (:data:`COLUMNS`), the fresh evaluations of the robust and the fragile variant,
    empty with fewer than two variants) of ``variants`` (:func:`find_variants`) on object
    ``name`` at joint noise ``sigma`` (radians; the module docstring's protocol).

    Args:
        method: ``direct`` (draws per variant) or ``reweight`` (the variants' P(FC) from one
            batch of closings: :func:`~kinegrasp_env.toolkit.batch_stats.variant_stats`; the
            fresh draws direct).
        executor: the direct evaluations' draws in chunks on it (the same draws, row for
            row).
        report: a progress report, one cell per evaluation or batch (:func:`variant_work`).
    """
    if not variants:
        return [], []

    direct_ids = set() if method == "reweight" else {v.id for v in variants}
    with make_engine(engine, description, name, friction=friction) as runner:
        def direct(v: Grasp, offset: int = 0, progress=None):
            return evaluate_grasp(v, sigma=sigma, n=samples, seed=seed, offset=offset,
                                  engine=runner, executor=executor, progress=progress)

        def evaluated(v: Grasp, offset: int, label: str):
            return reported_cell(report, samples, f"{label} sigma {sigma:g}",
                                 lambda progress: direct(v, offset, progress))

        if method == "reweight":
            from kinegrasp_env.toolkit.batch_stats import variant_stats

            def batch_done() -> None:
                if report is not None:
                    report.finish_cell(BATCH_FACTOR * samples,
                                       f"{name} grasp {variants[0].id}'s {len(variants)} "
                                       f"variants: one batch of {BATCH_FACTOR * samples} "
                                       f"closings, sigma {sigma:g}")

            def fallback(v: Grasp):
                direct_ids.add(v.id)
                if report is not None:
                    report.add_cell(samples)
                return evaluated(v, 0, f"{name} grasp {v.id} (direct: the batch's effective "
                                       "sample is too small)")

            stats = variant_stats(variants, sigma, samples, seed, engine=engine,
                                  friction=friction, robot=description, direct=fallback,
                                  on_batch=batch_done)
        else:
            stats = [evaluated(v, 0, f"{name} grasp {v.id}") for v in variants]
        block = [{"robot": description.name, "object": name, "id": v.id,
                  "elbow_angle": v.meta.get("elbow_angle", ""),
                  "ik_branch": v.meta.get("ik_branch", ""), "p_fc": s.p_fc,
                  "q_mean": s.q_mean, "q_std": s.q_std, "q_nominal": s.q_nominal,
                  "error": s.q_nominal - s.q_mean,
                  # a re-weighted variant's: its effective sample size
                  "samples": samples if v.id in direct_ids else s.samples, "sigma": sigma,
                  "estimate": "direct" if v.id in direct_ids else "reweighted",
                  "p_fc_lo": s.ci[0], "p_fc_hi": s.ci[1], **dict.fromkeys(PAIR_COLUMNS, "")}
                 for v, s in zip(variants, stats, strict=True)]
        if len(variants) < 2:
            return block, []

        pair = robust_fragile(
            [s.p_fc for s in stats],
            lambda i: evaluated(variants[i], report_rows(samples),
                                f"{name} grasp {variants[i].id} (fresh draws)"))
    for label, i, f in (("robust", pair.robust, pair.fresh[0]),
                        ("fragile", pair.fragile, pair.fresh[1])):
        block[i].update({"config": label, "fresh_p_fc": f.p_fc, "fresh_p_fc_lo": f.ci[0],
                         "fresh_p_fc_hi": f.ci[1], "fresh_samples": samples,
                         "selection_p_fc": stats[i].p_fc, "gap": pair.gap,
                         "gap_lo": pair.gap_lo, "gap_hi": pair.gap_hi,
                         "fresh_q_mean": f.q_mean, "fresh_q_var": f.q_std ** 2,
                         "fresh_q_skew": f.q_skew})
    return block, list(pair.fresh)
