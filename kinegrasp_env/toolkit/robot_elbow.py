"""The most robust elbow of a description robot's grasp (a 7-joint arm other than the
default robot's), through the reference engine, with the same protocol and certificate.

The protocol is :mod:`kinegrasp_env.toolkit.elbow`'s, robot-independent in every rule but
two: the self-motion and the engine.

- **Self-motion**: :class:`~kinegrasp_env.robot.null_motion.ArmSelfMotion` (Newton
  continuation on the palm pose and the arm angle of the description's ``arm_angle_links``)
  walks from the grasp's own configuration every ``step`` radians of psi in both directions,
  each configuration from the previous one, until the path leaves the joint limits, meets a
  singularity or an arm link other than the fingers would touch the object (pybullet's
  distance, :func:`~kinegrasp_env.toolkit.robot_planner.clearance`), or half a turn is
  walked each way. Every configuration keeps the grasp's palm pose (residual below
  :data:`~kinegrasp_env.robot.null_motion.RESIDUAL_TOL`), hence its nominal contacts.
- **Engine**: :func:`~kinegrasp_env.montecarlo.robot_evaluate.evaluate_robot_grasp` (the
  reference closing on the URDF's own geometry, the robot's contact model), one pybullet
  world for every angle. The selection draws are those of ``seed`` (the draws of
  ``kinegrasp evaluate --robot NAME --seed SEED``), the fresh draws those of the
  :class:`numpy.random.SeedSequence` ``[seed, 1]``: an independent stream; both are common
  to every angle (draw i is the same joint noise at every angle).

The grids (:data:`~kinegrasp_env.toolkit.elbow.FINE_STEP`, ``COARSE_EVERY``,
``REFINE_TOP``), the selection, the scoring on fresh draws, the paired gain and the
certificate (:func:`~kinegrasp_env.toolkit.elbow_certificate.certify`) are the default
robot's; the result is an :class:`~kinegrasp_env.toolkit.elbow.ElbowResult`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from kinegrasp_env.montecarlo.engines import FORCE_CLOSURE
from kinegrasp_env.montecarlo.robot_evaluate import RobotReferenceEngine, evaluate_robot_grasp
from kinegrasp_env.robot.null_motion import ArmSelfMotion
from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.toolkit.elbow import (
    COARSE_EVERY,
    FINE_STEP,
    REFINE_TOP,
    ElbowPoint,
    ElbowResult,
    elbow_result,
    wrap_angle,
)
from kinegrasp_env.toolkit.elbow_certificate import (
    DEFAULT_DELTA,
    DEFAULT_EPSILON,
    check_levels,
)
from kinegrasp_env.toolkit.robot_planner import clearance
from kinegrasp_env.world.grasps import Grasp

#: The fresh draws' stream: ``SeedSequence([seed, FRESH_STREAM])``.
FRESH_STREAM = 1


def fresh_seed(seed: int) -> np.random.SeedSequence:
    """The seed of the fresh (scoring) draws of run seed ``seed``."""
    return np.random.SeedSequence([int(seed), FRESH_STREAM])


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


def _point(grasp: Grasp, psi: float, q: np.ndarray, noise: JointNoise, samples: int,
           seed, engine: RobotReferenceEngine) -> tuple[np.ndarray, float, tuple]:
    """(force closure per draw (samples,), P(FC), its Wilson interval) at configuration q."""
    moved = replace(grasp, q0=np.asarray(q, dtype=float), id=f"{grasp.id}@{psi:.3f}",
                    meta={**grasp.meta, "elbow_angle": psi})
    stats = evaluate_robot_grasp(moved, sigma=noise.sigma, n=samples, seed=seed,
                                 noise=noise.kind, engine=engine)
    return stats.draws.outcome == FORCE_CLOSURE, stats.p_fc, stats.ci


def _curve(grasp, reach, nominal: int, noise, samples, seed, engine, report
           ) -> list[ElbowPoint]:
    """The coarse grid, then the fine grid around the REFINE_TOP best coarse angles (the
    default robot's grid rules), on the selection draws."""
    done: dict[int, ElbowPoint] = {}

    def evaluate(i: int) -> None:
        psi, q = reach[i]
        fc, p_fc, ci = _point(grasp, psi, q, noise, samples, seed, engine)
        done[i] = ElbowPoint(psi, q, p_fc, ci, fc)
        report(len(done))

    coarse = sorted(set(range(0, len(reach), COARSE_EVERY)) | {len(reach) - 1, nominal})
    for i in coarse:
        evaluate(i)
    for centre in sorted(coarse, key=lambda i: -done[i].p_fc)[:REFINE_TOP]:
        for i in range(max(centre - COARSE_EVERY, 0), min(centre + COARSE_EVERY + 1, len(reach))):
            if i not in done:
                evaluate(i)
    return [done[i] for i in sorted(done)]


def optimize_robot_elbow(grasp: Grasp, noise: JointNoise, samples: int, seed: int = 0, *,
                         engine: RobotReferenceEngine | None = None, step: float = FINE_STEP,
                         epsilon: float = DEFAULT_EPSILON, delta: float = DEFAULT_DELTA,
                         reach: list[tuple[float, np.ndarray]] | None = None,
                         progress: Callable[[int], None] | None = None) -> ElbowResult:
    """The most robust elbow angle of a description robot's ``grasp`` under ``noise``.

    Args:
        grasp: the grasp (its ``robot`` names the robot); palm pose and contacts stay fixed.
        noise: joint noise on the arm joints.
        samples: draws per evaluated angle, for the selection and again (fresh) for the
            scoring and the certificate.
        seed: run seed (selection: ``seed``; fresh draws: :func:`fresh_seed`).
        engine: a reference engine of the grasp's robot and object to reuse.
        step: fine-grid spacing of psi, radians.
        epsilon, delta: the certificate's margin and error level.
        reach: :func:`robot_reachable_configurations`, when already computed.
        progress: optional ``progress(evaluations)`` callback.

    Raises:
        ValueError: epsilon or delta out of range, bad samples (before any draw); a robot
            whose arm has no self-motion.
    """
    check_levels(epsilon, delta)
    if isinstance(samples, bool) or not isinstance(samples, int | np.integer) or samples < 1:
        raise ValueError(f"samples must be a positive number of draws, got {samples!r}")
    report = progress or (lambda done: None)
    own = engine is None
    engine = engine or RobotReferenceEngine(grasp.robot, grasp.object)
    try:
        reach = reach if reach is not None else robot_reachable_configurations(grasp, engine,
                                                                               step)
        q0 = np.asarray(grasp.q0, dtype=float)
        nominal_index = min(range(len(reach)),
                            key=lambda i: float(np.abs(reach[i][1] - q0).max()))
        curve = _curve(grasp, reach, nominal_index, noise, samples, seed, engine, report)
        fresh = fresh_seed(seed)
        for k, point in enumerate(curve):
            point.fresh_fc = _point(grasp, point.psi, point.q, noise, samples, fresh, engine)[0]
            report(len(curve) + k + 1)
    finally:
        if own:
            engine.close()
    best = max(curve, key=lambda p: p.p_fc)
    nominal = next(p for p in curve if p.q is reach[nominal_index][1])
    return elbow_result(grasp, curve, best, nominal, nominal.psi, noise, samples, seed,
                        "pybullet", step, epsilon, delta)
