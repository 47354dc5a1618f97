"""The most robust elbow of any robot's grasp, with its certificate; for a 6-joint arm (no
self-motion) the most robust of its IK branches (:func:`optimize_robot_branches`).

- **Self-motion**: :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion` (Newton
  continuation on the palm pose and the arm angle of the description's ``arm_angle_links``)
  walks from the grasp's own configuration every ``step`` radians of psi in both directions,
  each configuration from the previous one, until the path leaves the joint limits, meets a
  singularity or an arm link other than the fingers would touch the object (pybullet's
  distance, :func:`~kinegrasp_env.toolkit.plan_checks.clearance`), or half a turn is
  walked each way. Every configuration keeps the grasp's palm pose (residual below
  :data:`~kinegrasp_env.robot.self_motion.CONVERGED_TOL`), hence its nominal contacts.
- **Curve** (selection draws): the coarse grid of psi, then the fine grid around the best
  coarse angles (:mod:`kinegrasp_env.toolkit.elbow`'s grids), each angle on the draws of
  ``seed`` (those of ``kinegrasp evaluate --seed SEED``) through any engine
  (:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`): common to every
  angle (draw i is the same error of every source at every angle), so differences between
  angles are far less noisy than each estimate.
- **Scoring** (fresh draws): every evaluated angle again on the rows after the selection's
  in the same run (:func:`~kinegrasp_env.toolkit.selection.report_rows`), common to every
  angle; the best angle of the curve is reported on them (no winner's curse), with the
  paired gain over the nominal angle and the certificate
  (:func:`~kinegrasp_env.toolkit.elbow.elbow_result`): an
  :class:`~kinegrasp_env.toolkit.elbow.ElbowResult`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from kinegrasp_env.counts import check_count
from kinegrasp_env.montecarlo.description_engine import RobotEngine
from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.evaluate import (
    ENGINES,
    RobotReferenceEngine,
    evaluate_grasp,
    make_engine,
)
from kinegrasp_env.montecarlo.execution import Executor, LocalExecutor
from kinegrasp_env.robot.ik_branches import (
    DEFAULT_STARTS,
    MERGE_TOL,
    IKBranch,
    ik_branches,
    joint_difference,
)
from kinegrasp_env.robot.null_motion import ArmSelfMotion
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.toolkit.elbow import (
    COARSE_EVERY,
    FINE_STEP,
    REFINE_TOP,
    ElbowPoint,
    ElbowResult,
    elbow_result,
    nominal_index,
    wrap_angle,
)
from kinegrasp_env.toolkit.elbow_certificate import (
    DEFAULT_DELTA,
    DEFAULT_EPSILON,
    Certificate,
    rounded_up,
)
from kinegrasp_env.toolkit.plan_checks import clearance
from kinegrasp_env.toolkit.search_checks import check_branch_arm, check_search
from kinegrasp_env.toolkit.selection import report_rows
from kinegrasp_env.world.grasps import Grasp


def robot_reachable_configurations(grasp: Grasp, engine: RobotReferenceEngine,
                                   step: float = FINE_STEP,
                                   motion: ArmSelfMotion | None = None
                                   ) -> list[tuple[float, np.ndarray]]:
    """(psi, q (dof,)) along the grasp's self-motion every ``step`` radians (see the module
    docstring), sorted by psi; the grasp's own configuration included (exactly its q0).

    Raises:
        ValueError: step not in (0, pi], or an arm that is not 7 joints with arm angle links.
    """
    if not (np.isfinite(step) and 0 < step <= np.pi):
        raise ValueError(f"step must be an angle in (0, pi] radians, got {step!r}")
    motion = motion or ArmSelfMotion(engine.description)
    q0 = engine.check(grasp.q0)[0]
    psi0 = float(motion.elbow_angle(q0[None])[0])
    found = [(wrap_angle(psi0), q0.copy())]
    steps = int(np.floor(np.pi / step))
    for sign in (1.0, -1.0):
        q = q0
        for k in range(1, steps + 1):
            psi = psi0 + sign * k * step
            moved, ok = motion.set_elbow_angle(q, psi)
            if not ok or clearance(engine, moved) <= 0.0:
                break
            q = moved
            found.append((wrap_angle(psi), moved))
    return sorted(found, key=lambda item: item[0])


@dataclass
class AngleScorer:
    """What evaluates an angle's draws: an engine of this process, or an engine's name and
    friction with an executor whose workers build their own
    (:func:`~kinegrasp_env.montecarlo.evaluate.evaluate_grasp`)."""

    engine: RobotEngine | str
    executor: Executor | None = None
    friction: float = 0.5
    own: bool = False

    @classmethod
    def of(cls, reference: RobotReferenceEngine, name: str, executor: Executor | None
           ) -> AngleScorer:
        """The scorer of engine ``name`` (the reference one reused where it can be)."""
        if name not in ENGINES:
            raise ValueError(f"engine must be one of {', '.join(ENGINES)}, got {name!r}")
        if executor is not None and not (isinstance(executor, LocalExecutor)
                                         and executor.workers == 1):
            return cls(name, executor, reference.friction)
        if name == "pybullet":
            return cls(reference)
        return cls(make_engine(name, reference.description, reference.obj.name,
                               friction=reference.friction), own=True)

    @property
    def name(self) -> str:
        return self.engine if isinstance(self.engine, str) else self.engine.name

    def close(self) -> None:
        if self.own:
            self.engine.close()


def angle_point(grasp: Grasp, psi: float, q: np.ndarray, noise: JointNoise | NoiseModel,
                samples: int, seed, scorer: AngleScorer, offset: int = 0) -> ElbowPoint:
    """The point of elbow angle ``psi`` at configuration q: P(FC), its Wilson interval, force
    closure and the outcome per draw, on rows ``offset ..`` of the seed's run
    (:func:`fresh_point`: the fresh ones)."""
    moved = replace(grasp, q0=np.asarray(q, dtype=float), id=f"{grasp.id}@{psi:.3f}",
                    meta={**grasp.meta, "elbow_angle": psi})
    joints = {"noise_model": noise} if isinstance(noise, NoiseModel) else {
        "sigma": noise.sigma, "noise": noise.kind}
    stats = evaluate_grasp(moved, n=samples, seed=seed, engine=scorer.engine,
                           executor=scorer.executor, friction=scorer.friction, offset=offset,
                           **joints)
    outcome = stats.draws.outcome
    return ElbowPoint(psi, q, stats.p_fc, stats.ci, outcome == FORCE_CLOSURE, outcome)


def fresh_point(grasp: Grasp, q: np.ndarray, noise: JointNoise | NoiseModel, samples: int,
                seed, scorer: AngleScorer) -> np.ndarray:
    """(samples,) force closure at configuration q on the fresh draws of run ``seed``: the
    rows after its selection's (:func:`~kinegrasp_env.toolkit.selection.report_rows`)."""
    return angle_point(grasp, 0.0, q, noise, samples, seed, scorer, report_rows(samples)).fc


def _curve(grasp, reach, nominal: int, noise, samples, seed, scorer: AngleScorer, report
           ) -> list[ElbowPoint]:
    """The coarse grid, then the fine grid around the REFINE_TOP best coarse angles, on the
    selection draws."""
    done: dict[int, ElbowPoint] = {}

    def evaluate(i: int) -> None:
        psi, q = reach[i]
        done[i] = angle_point(grasp, psi, q, noise, samples, seed, scorer)
        report(len(done))

    coarse = sorted(set(range(0, len(reach), COARSE_EVERY)) | {len(reach) - 1, nominal})
    for i in coarse:
        evaluate(i)
    for centre in sorted(coarse, key=lambda i: -done[i].p_fc)[:REFINE_TOP]:
        for i in range(max(centre - COARSE_EVERY, 0), min(centre + COARSE_EVERY + 1, len(reach))):
            if i not in done:
                evaluate(i)
    return [done[i] for i in sorted(done)]


def _score_fresh(grasp: Grasp, curve: list[ElbowPoint], noise: JointNoise | NoiseModel,
                 samples: int, seed: int, scorer: AngleScorer, report) -> None:
    """Every point of the curve again on the fresh draws (its ``fresh_fc``)."""
    for k, point in enumerate(curve):
        point.fresh_fc = fresh_point(grasp, point.q, noise, samples, seed, scorer)
        report(len(curve) + k + 1)


@contextmanager
def _scoring(grasp: Grasp, engine: RobotReferenceEngine | None, friction: float,
             evaluate_with: str, executor: Executor | None
             ) -> Iterator[tuple[RobotReferenceEngine, AngleScorer]]:
    """(the reference engine, the angle scorer) of a search: ``engine`` when given, else one
    of the grasp's robot and object built here; both closed at the end (a given engine is
    the caller's)."""
    own = engine is None
    engine = engine or RobotReferenceEngine(grasp.robot, grasp.object, friction=friction)
    scorer = None
    try:
        scorer = AngleScorer.of(engine, evaluate_with, executor)
        yield engine, scorer
    finally:
        if scorer is not None:
            scorer.close()
        if own:
            engine.close()


def optimize_robot_elbow(grasp: Grasp, noise: JointNoise | NoiseModel, samples: int,
                         seed: int = 0, *,
                         engine: RobotReferenceEngine | None = None, step: float = FINE_STEP,
                         epsilon: float = DEFAULT_EPSILON, delta: float = DEFAULT_DELTA,
                         reach: list[tuple[float, np.ndarray]] | None = None,
                         progress: Callable[[int], None] | None = None,
                         friction: float = 0.5, evaluate_with: str = "fast",
                         executor: Executor | None = None) -> ElbowResult:
    """The most robust elbow angle of ``grasp`` under ``noise`` (the module docstring).

    Args:
        grasp: the grasp (its ``robot`` names the robot); palm pose and contacts stay fixed.
        noise: joint noise on the arm joints, or a noise model of the robot's sources
            (:mod:`~kinegrasp_env.montecarlo.noise_rows`: every draw of it).
        samples: draws per evaluated angle, for the selection and again (fresh) for the
            scoring and the certificate.
        seed: run seed (selection: its first ``samples`` rows; fresh draws: the rows
            after them, :func:`fresh_point`).
        engine: a reference engine of the grasp's robot and object to reuse.
        step: fine-grid spacing of psi, radians.
        epsilon, delta: the certificate's margin and error level.
        reach: :func:`robot_reachable_configurations`, when already computed.
        progress: optional ``progress(evaluations)`` callback.
        friction: the contacts' mu (of the engine built when none is given).
        evaluate_with: the engine of the draws (``pybullet``, ``fast`` or ``physics``); the
            self-motion's clearance is the reference engine's (pybullet distances).
        executor: run each angle's draws in chunks on it (the same draws).

    Raises:
        ValueError: :func:`~kinegrasp_env.toolkit.search_checks.check_search`'s refusals
            (before any draw); a robot whose arm has no self-motion.
    """
    check_search(grasp, noise, samples, seed, epsilon, delta, engine)
    report = progress or (lambda done: None)
    with _scoring(grasp, engine, friction, evaluate_with, executor) as (engine, scorer):
        reach = reach if reach is not None else robot_reachable_configurations(grasp, engine,
                                                                               step)
        nominal = nominal_index(grasp, reach)
        curve = _curve(grasp, reach, nominal, noise, samples, seed, scorer, report)
        _score_fresh(grasp, curve, noise, samples, seed, scorer, report)
    best = max(curve, key=lambda p: p.p_fc)
    nominal = next(p for p in curve if p.q is reach[nominal][1])
    return elbow_result(grasp, curve, best, nominal, nominal.psi, noise, samples, seed,
                        scorer.name, step, epsilon, delta)


def branch_variants(grasp: Grasp, engine: RobotReferenceEngine, starts: int
                    ) -> tuple[list[IKBranch], int]:
    """The IK branches of the grasp's palm pose (:func:`ik_branches`, its starts seeded by
    :data:`~kinegrasp_env.robot.ik_branches.BRANCH_SEED`, as the envs' branch coordinates
    are) and the index of the grasp's own one: the branch within ``MERGE_TOL`` of its arm
    joints takes them exactly, or they are added last, a branch of their own (labelled
    ``nominal``), where the envs' coordinate adds them too."""
    description = engine.description
    dof = description.arm_dof
    q0 = engine.check(grasp.q0)[0]
    branches = ik_branches(description, grasp.palm_pose, starts=starts)
    gaps = [float(joint_difference(description, b.q, q0[:dof])) for b in branches]
    if gaps and min(gaps) <= MERGE_TOL:
        k = int(np.argmin(gaps))
        branches[k] = replace(branches[k], q=q0[:dof].copy())
        return branches, k
    return [*branches, IKBranch(q0[:dof].copy(), "nominal", 0)], len(branches)


@dataclass
class BranchResult:
    """The most robust IK branch of a 6-joint arm's grasp: an :class:`ElbowResult` whose
    "angles" are branch indices (a curve point's psi is its branch's index in ``branches``;
    a search may leave a branch out), and the branches."""

    result: ElbowResult
    branches: list[IKBranch]
    nominal: int
    best: int

    def to_json(self) -> dict:
        """``ElbowResult.to_json()`` with branches for angles: ``best_branch``,
        ``nominal_branch``, the curve's and the certificate's ``branch`` entries (no psi),
        ``variants: "ik_branches"`` and the ``branches`` (index, label, arm joints, hits)."""
        out = self.result.to_json()
        for key in ("best_psi", "nominal_psi", "grid_step"):
            out.pop(key)
        out.update(variants="ik_branches", best_branch=self.best,
                   best_label=self.branches[self.best].label, nominal_branch=self.nominal,
                   nominal_label=self.branches[self.nominal].label)
        for point in out["curve"]:
            branch = round(point.pop("psi"))
            point.update(branch=branch, label=self.branches[branch].label)
        cert = out["certificate"]
        cert["chosen_branch"] = round(cert.pop("chosen_psi"))
        worst = cert.pop("worst_psi")
        cert["worst_branch"] = None if worst is None else round(worst)
        for rival in cert["rivals"]:
            rival["branch"] = round(rival.pop("psi"))
        cert["statement"] = branch_statement(self.result.certificate, self.branches)
        out["branches"] = [{"branch": i, "label": b.label, "q": b.q.tolist(), "hits": b.hits}
                           for i, b in enumerate(self.branches)]
        return out


def branch_statement(cert: Certificate, branches: list[IKBranch]) -> str:
    """The certificate's claim (:meth:`Certificate.statement`) in words of IK branches."""
    chosen = round(cert.chosen_psi)
    name = f"branch {chosen} ({branches[chosen].label})"
    if cert.bound is None:
        return f"{name} is the only IK branch found"
    shown = rounded_up(cert.bound)
    if shown < 0:
        return (f"with {cert.confidence} confidence every other IK branch found has a P(FC) "
                f"at least {-shown:.3f} below that of {name}")
    return (f"with {cert.confidence} confidence no other IK branch found beats {name} by "
            f"more than {shown:.3f} in P(FC)")


def optimize_robot_branches(grasp: Grasp, noise: JointNoise | NoiseModel, samples: int,
                            seed: int = 0, *,
                            engine: RobotReferenceEngine | None = None,
                            starts: int = DEFAULT_STARTS, epsilon: float = DEFAULT_EPSILON,
                            delta: float = DEFAULT_DELTA,
                            progress: Callable[[int], None] | None = None,
                            friction: float = 0.5, evaluate_with: str = "fast",
                            executor: Executor | None = None) -> BranchResult:
    """The most robust IK branch of a 6-joint arm's ``grasp`` under ``noise``: the protocol
    of :func:`optimize_robot_elbow` with the IK branches of the grasp's palm pose for the
    elbow angles. Every branch is evaluated on the selection draws (``seed``; a branch whose
    arm or hand meets the object scores as the engine scores it), the best is chosen, every
    branch is scored again on the fresh draws (:func:`fresh_point`), with the paired gain
    over the grasp's own branch and the certificate
    (:func:`~kinegrasp_env.toolkit.elbow_certificate.certify`) over the other branches.

    Args:
        grasp: the grasp (its ``robot`` names the robot); palm pose and contacts stay fixed.
        noise: joint noise on the arm joints, or a noise model of the robot's sources
            (:mod:`~kinegrasp_env.montecarlo.noise_rows`: every draw of it).
        samples: draws per branch, for the selection and again (fresh) for the scoring.
        seed: run seed (the IK starts have their own, fixed:
            :data:`~kinegrasp_env.robot.ik_branches.BRANCH_SEED`).
        engine: a reference engine of the grasp's robot and object to reuse.
        starts: random IK starts (:func:`~kinegrasp_env.robot.ik_branches.ik_branches`).
        epsilon, delta: the certificate's margin and error level.
        progress: optional ``progress(evaluations)`` callback (2 per branch).
        friction, evaluate_with, executor: as :func:`optimize_robot_elbow`.

    Raises:
        ValueError: :func:`~kinegrasp_env.toolkit.search_checks.check_search`'s refusals,
            an arm that is not a 6-joint one, bad starts (before any draw).
    """
    check_branch_arm(check_search(grasp, noise, samples, seed, epsilon, delta, engine))
    check_count(starts, "starts")
    report = progress or (lambda done: None)
    with _scoring(grasp, engine, friction, evaluate_with, executor) as (engine, scorer):
        branches, nominal = branch_variants(grasp, engine, int(starts))
        hand = np.asarray(grasp.q0, dtype=float)[engine.description.arm_dof:]
        curve = []
        for i, branch in enumerate(branches):
            q = np.concatenate([branch.q, hand])
            curve.append(angle_point(grasp, float(i), q, noise, samples, seed, scorer))
            report(i + 1)
        _score_fresh(grasp, curve, noise, samples, seed, scorer, report)
    best = max(range(len(curve)), key=lambda i: curve[i].p_fc)
    result = elbow_result(grasp, curve, curve[best], curve[nominal], float(nominal), noise,
                          samples, seed, scorer.name, 0.0, epsilon, delta)
    return BranchResult(result, branches, nominal, best)


def optimize_variants(grasp: Grasp, noise: JointNoise | NoiseModel, samples: int,
                      seed: int = 0, **kwargs) -> tuple[ElbowResult, bool]:
    """(the most robust variant of the grasp's arm configuration, whether the variants were
    IK branches): along a 7-joint arm's self-motion (:func:`optimize_robot_elbow`), or across a
    6-joint arm's IK branches (:func:`optimize_robot_branches`' result, its points' ``psi``
    the branch indices); ``kwargs``: their options."""
    from kinegrasp_env.robot.catalog import load_robot

    if load_robot(grasp.robot).arm_dof == 6:
        return optimize_robot_branches(grasp, noise, samples, seed, **kwargs).result, True
    return optimize_robot_elbow(grasp, noise, samples, seed, **kwargs), False
