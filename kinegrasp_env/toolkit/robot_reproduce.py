"""Fig. 10 of the paper for a description robot: the same contacts reached with different
arm configurations.

The paper's Fig. 10 evaluates null-space variants of a grasp: configurations with the grasp's
palm pose (hence its nominal contacts) and elbow angles spread over the self-motion. For a
description robot with a 7-joint arm the variants are ``count`` configurations picked evenly
(by index) from :func:`~kinegrasp_env.toolkit.elbow_search.robot_reachable_configurations`
(the self-motion walked every :data:`~kinegrasp_env.toolkit.elbow.FINE_STEP` radians of psi,
within the joint limits and clear of the object); for a 6-joint arm, which has no
self-motion, they are the palm pose's IK branches
(:func:`~kinegrasp_env.toolkit.elbow_search.branch_variants`, at most ``count``). Either kind
is kept where its nominal closing is in force closure (as the default robot's variants
are). Each is evaluated on ``samples`` draws of joint noise on the
arm joints (:func:`~kinegrasp_env.montecarlo.robot_evaluate.evaluate_robot_grasp`, seed
``seed``: the draws of ``kinegrasp evaluate --robot NAME --seed SEED``); with two variants or
more, the most and the least robust (chosen on those draws) are reported again on fresh draws
(the rows after the selection's in the same run: :func:`~kinegrasp_env.toolkit.selection.
report_rows`, common to both) with the paired
difference of their force-closure indicators and its Student-t 95% interval.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE
from kinegrasp_env.montecarlo.execution import Executor
from kinegrasp_env.montecarlo.robot_evaluate import (
    RobotReferenceEngine,
    evaluate_robot_grasp,
    make_engine,
)
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.robot.ik_branches import DEFAULT_STARTS as DEFAULT_IK_STARTS
from kinegrasp_env.sampling.stats import paired_interval
from kinegrasp_env.toolkit.elbow_search import (
    branch_variants,
    robot_reachable_configurations,
)
from kinegrasp_env.toolkit.experiments import PAIR_COLUMNS, write_rows
from kinegrasp_env.toolkit.selection import extremes, report_rows
from kinegrasp_env.world.grasps import Grasp

#: fig10.csv's columns for a description robot (the default robot's, the robot and the
#: variant's elbow angle (7-joint arms) or IK branch label (6-joint arms) first).
COLUMNS = ("robot", "object", "id", "elbow_angle", "ik_branch", "p_fc", "q_mean", "q_std",
           "q_nominal", "error", "samples", "sigma", *PAIR_COLUMNS)


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


def robot_variants(grasp: Grasp, engine: RobotReferenceEngine, count: int) -> list[Grasp]:
    """Up to ``count`` configurations of the grasp's palm pose (see the module docstring; a
    6-joint arm's first ``count`` IK branches, the grasp's own always among them), as grasps
    with the grasp's palm pose and contacts, ids ``<id>v<k>``, their nominal Q and
    ``meta["elbow_angle"]`` (radians) or ``meta["ik_branch"]`` (the branch's label)."""
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
    for j, (where, q) in enumerate(found):
        draw = engine.run(np.asarray(q, dtype=float)[None])
        if draw.outcome[0] != FORCE_CLOSURE:
            continue
        out.append(replace(grasp, q0=np.asarray(q, dtype=float), id=f"{grasp.id}v{j + 1}",
                           q_nominal=float(draw.quality[0]),
                           meta={**grasp.meta, **where, "variant_of": grasp.id}))
    return out


def variant_block(description: RobotDescription, name: str, grasp: Grasp, *, samples: int,
                  sigma: float, count: int, seed: int, engine: str, friction: float,
                  method: str = "direct", executor: Executor | None = None
                  ) -> tuple[list[dict], list]:
    """(rows (:data:`COLUMNS`), the fresh evaluations of the robust and the fragile variant,
    empty with fewer than two variants) of ``count`` variants of ``grasp`` on object
    ``name`` (the module docstring's protocol); ``method`` ``reweight``: the variants' P(FC)
    from one batch of closings (:func:`~kinegrasp_env.toolkit.batch_stats.variant_stats`:
    the self-motion's variants of a 7-joint arm, the IK branches of a 6-joint one), the fresh
    draws direct; ``executor``: the direct evaluations' draws in
    chunks on it (the same draws, row for row)."""
    with RobotReferenceEngine(description, name) as reference:
        variants = robot_variants(grasp, reference, count)
    fresh = []
    with make_engine(engine, description, name, friction=friction) as runner:
        def direct(v: Grasp):
            return evaluate_robot_grasp(v, sigma=sigma, n=samples, seed=seed, engine=runner,
                                        executor=executor)

        if method == "reweight":
            from kinegrasp_env.toolkit.batch_stats import variant_stats

            stats = variant_stats(variants, sigma, samples, seed, engine=engine,
                                  friction=friction, robot=description, direct=direct)
        else:
            stats = [direct(v) for v in variants]
        block = [{"robot": description.name, "object": name, "id": v.id,
                  "elbow_angle": v.meta.get("elbow_angle", ""),
                  "ik_branch": v.meta.get("ik_branch", ""), "p_fc": s.p_fc,
                  "q_mean": s.q_mean, "q_std": s.q_std, "q_nominal": s.q_nominal,
                  "error": s.q_nominal - s.q_mean,
                  # a re-weighted variant's: its effective sample size
                  "samples": getattr(s, "samples", samples), "sigma": sigma,
                  **dict.fromkeys(PAIR_COLUMNS, "")}
                 for v, s in zip(variants, stats, strict=True)]
        if len(variants) >= 2:
            best, worst = extremes([s.p_fc for s in stats])
            fresh = [evaluate_robot_grasp(variants[i], sigma=sigma, n=samples, seed=seed,
                                          offset=report_rows(samples), engine=runner,
                                          executor=executor)
                     for i in (best, worst)]
            fc = [f.draws.outcome == FORCE_CLOSURE for f in fresh]
            gap, lo, hi = paired_interval(fc[0].astype(float) - fc[1].astype(float))
            for label, i, f in (("robust", best, fresh[0]), ("fragile", worst, fresh[1])):
                block[i].update({"config": label, "fresh_p_fc": f.p_fc,
                                 "fresh_p_fc_lo": f.ci[0], "fresh_p_fc_hi": f.ci[1],
                                 "fresh_samples": samples,
                                 "selection_p_fc": stats[i].p_fc, "gap": gap,
                                 "gap_lo": lo, "gap_hi": hi})
    return block, fresh


def check_method(method: str) -> None:
    """ValueError for an unknown fig10 method (``direct`` or ``reweight``: any arm with
    variants, :func:`check_variants`, has the six joints a palm deviation's Gaussian needs)."""
    if method not in ("direct", "reweight"):
        raise ValueError(f"unknown method {method!r}: direct or reweight")


def robot_fig10(description: RobotDescription, out_dir: str | Path, *,
                grasp_sets: Mapping[str, Sequence[Grasp]], samples: int = 1000,
                sigma: float = 0.0033, count: int = 10, seed: int = 0,
                engine: str = "pybullet", friction: float = 0.5,
                method: str = "direct", executor: Executor | None = None) -> list[dict]:
    """Fig. 10 of ``description`` (a 7-joint arm with an elbow angle, or a 6-joint arm): per
    object of ``grasp_sets``, ``count`` variants of its first grasp. Writes ``fig10.csv``
    (:data:`COLUMNS`), then ``fig10.png`` (a figure that fails is a warning: the CSV stays).

    Args:
        engine: the Monte Carlo engine (``pybullet``, ``fast`` or ``physics``); the
            variants and their nominal closings use the reference engine.
        method: ``direct`` (draws per variant) or ``reweight`` (one batch per object:
            :func:`variant_block`).
        executor: the direct evaluations' draws in chunks on it.

    Raises:
        ValueError: an arm without variants (:func:`check_variants`), an unknown method.
    """
    from kinegrasp_env.toolkit.plots import plot_success_quality, safe_figure

    check_variants(description, "fig10")
    check_method(method)
    rows = []
    for name, grasps in grasp_sets.items():
        rows += variant_block(description, name, grasps[0], samples=samples, sigma=sigma,
                              count=count, seed=seed, engine=engine, friction=friction,
                              method=method, executor=executor)[0]
    out = Path(out_dir)
    if not rows:
        raise ValueError(f"no variant of the first grasp of robot {description.name!r} closes "
                         "in force closure; nothing written")
    write_rows(out, "fig10.csv", rows, COLUMNS)
    safe_figure(lambda: plot_success_quality(
        rows, out / "fig10.png", title=f"fig10, robot {description.name}: sigma = {sigma:g}, "
                                       f"{samples} draws per variant"), out / "fig10.png")
    return rows
