"""The most robust elbow's results and grids, and the default robot's self-motion.

A 7-DOF arm reaches the same palm pose (hence the same nominal contacts) with a one-parameter
family of configurations, the self-motion, parametrized by the elbow angle psi (radians; see
docs/conventions.md). The search along it, for any robot, is
:func:`~kinegrasp_env.toolkit.elbow_search.optimize_robot_elbow` (direct draws) or
:func:`~kinegrasp_env.toolkit.elbow_reweight_search.optimize_robot_elbow_reweighted` (one
re-weighted batch); what both share lives here:

1. **Grids**: a coarse grid of psi (every :data:`COARSE_EVERY` fine steps of
   :data:`FINE_STEP`), then the fine grid around the :data:`REFINE_TOP` best coarse angles,
   all on the same selection draws (common random numbers: differences between angles are
   far less noisy than each estimate).
2. **Result** (:func:`elbow_result`): the best angle of the curve by P(FC), scored with the
   nominal one on fresh draws the selection never used, so the reported P(FC) of the best
   angle is not biased upwards by the selection (winner's curse); the gain over the nominal
   as a paired difference with a t-interval; and the **certificate**
   (:mod:`~kinegrasp_env.toolkit.elbow_certificate`): with confidence 1 - delta, no
   evaluated angle beats the chosen one by more than a bound B in P(FC) (exact one-sided
   binomial bounds on each rival's wins and losses on the fresh draws); certified at epsilon
   when B <= epsilon. Angles between fine-grid points are not covered: the grid step is
   reported with it.

:func:`reachable_configurations`, :func:`configuration_at` and :func:`with_configuration`
move a grasp of the default robot along its self-motion with its arm's analytic walk
(:class:`ArmWalk`; the benchmarks' calibration cases use them, and the tests as a second
walk to check the shared one against).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from kinegrasp_env.sampling.noise import JointNoise
from kinegrasp_env.sampling.stats import paired_interval, wilson_interval
from kinegrasp_env.toolkit.elbow_certificate import (
    Certificate,
    certify,
)
from kinegrasp_env.world.grasps import Grasp

#: Spacing of the fine grid of elbow angles (radians): 3 degrees.
FINE_STEP = float(np.deg2rad(3.0))
#: The coarse grid takes every COARSE_EVERY-th fine configuration (15 degrees).
COARSE_EVERY = 5
#: Coarse angles around which the fine grid is evaluated.
REFINE_TOP = 2
#: Clearance the arm links keep from the object along :class:`ArmWalk`, metres.
ARM_CLEARANCE = 0.004


@dataclass
class ElbowPoint:
    """P(FC) of one elbow angle on the selection draws (and on the fresh draws, once they
    are run)."""

    psi: float
    q: np.ndarray = field(repr=False)
    p_fc: float
    p_fc_ci: tuple[float, float]
    fc: np.ndarray = field(repr=False)  # (n,) bool: force closure per selection draw
    #: (n,) int8 outcome (index into ``OUTCOMES``) per selection draw, when kept
    outcome: np.ndarray | None = field(default=None, repr=False)
    #: (n,) bool: force closure per fresh draw (chunks the selection never used)
    fresh_fc: np.ndarray | None = field(default=None, repr=False)

    def to_json(self) -> dict:
        out = {"psi": self.psi, "p_fc": self.p_fc, "p_fc_ci": list(self.p_fc_ci)}
        if self.fresh_fc is not None:
            out["fresh_p_fc"] = float(self.fresh_fc.mean())
        return out


@dataclass
class ElbowResult:
    """The most robust elbow of a grasp and its evidence (angles in radians)."""

    object: str
    grasp: str
    sigma: float | list[float]
    samples: int
    seed: int
    engine: str
    nominal_psi: float
    nominal_p_fc: float
    nominal_p_fc_ci: tuple[float, float]
    best_psi: float
    best_q: np.ndarray = field(repr=False)
    best_p_fc: float
    best_p_fc_ci: tuple[float, float]
    gain: float
    gain_ci: tuple[float, float]
    certificate: Certificate
    grid_step: float
    curve: list[ElbowPoint] = field(repr=False)

    def to_json(self) -> dict:
        keys = ("object", "grasp", "sigma", "samples", "seed", "engine", "nominal_psi",
                "nominal_p_fc", "best_psi", "best_p_fc", "gain", "grid_step")
        out = {k: getattr(self, k) for k in keys}
        out.update(nominal_p_fc_ci=list(self.nominal_p_fc_ci),
                   best_p_fc_ci=list(self.best_p_fc_ci), gain_ci=list(self.gain_ci),
                   best_q=self.best_q.tolist(), certificate=self.certificate.to_json(),
                   curve=[p.to_json() for p in self.curve])
        return out


def wrap_angle(psi: float) -> float:
    """psi wrapped to (-pi, pi]."""
    return float(np.angle(np.exp(1j * psi)))


class ArmWalk:
    """The default robot's arm on its analytic self-motion beside one object
    (:class:`~kinegrasp_env.robot.ik.ArmIK`), its 7 arm links checked against the object in
    pybullet: the walk :func:`reachable_configurations` and :func:`configuration_at` take
    (the shared one of every 7-joint arm is :func:`~kinegrasp_env.toolkit.elbow_search.
    robot_reachable_configurations`)."""

    def __init__(self, object_name: str) -> None:
        from kinegrasp_env.robot.default_robot import kuka_sdh, urdf_path
        from kinegrasp_env.robot.ik import ArmIK
        from kinegrasp_env.robot.kinematics import Kinematics
        from kinegrasp_env.world.objects import load_object
        from kinegrasp_env.world.sim import ObjectWorld

        self.model = kuka_sdh()
        self.ik = ArmIK(Kinematics(self.model))
        self.world = ObjectWorld(load_object(object_name))
        bullet = self.world.bullet
        self.arm = bullet.loadURDF(str(urdf_path()), useFixedBase=True)
        self.joints = {bullet.getJointInfo(self.arm, j)[1].decode(): j
                       for j in range(bullet.getNumJoints(self.arm))}

    def close(self) -> None:
        self.world.close()

    def arm_clear(self, q: np.ndarray) -> bool:
        """True when the 7 arm links at q (14,) keep :data:`ARM_CLEARANCE` (metres) from the
        object (the hand is the closing's to judge)."""
        bullet = self.world.bullet
        for name, value in self.model.expand(q).items():
            bullet.resetJointState(self.arm, self.joints[name], float(value))
        obj = self.world.bodies["object"]
        return not any(bullet.getClosestPoints(self.arm, obj, ARM_CLEARANCE, linkIndexA=link)
                       for link in range(7))

    def elbow_range(self, q0: np.ndarray, step: float) -> list[tuple[float, np.ndarray]]:
        """(psi, q) every ``step`` radians from q0 (14,) both ways up to pi, until the path
        leaves the joint limits; the configurations whose arm is clear of the object."""
        psi0 = float(self.ik.elbow_angle(q0[None])[0])
        found = []
        for sign in (1.0, -1.0):
            q = q0.copy()
            for i in range(1, int(np.pi / step) + 1):
                psi = psi0 + sign * i * step
                moved, ok = self.ik.set_elbow_angle(q, psi)
                if not ok[0]:
                    break
                q = moved[0]
                if self.arm_clear(q):
                    found.append((wrap_angle(psi), q.copy()))
        return found


def reachable_configurations(grasp: Grasp, step: float = FINE_STEP,
                             walk: ArmWalk | None = None) -> list[tuple[float, np.ndarray]]:
    """(psi, q (14,)) along the grasp's self-motion, every ``step`` radians, within the joint
    limits and clear of collisions, sorted by psi; the nominal configuration included."""
    owned = walk is None
    walk = walk or ArmWalk(grasp.object)
    try:
        found = walk.elbow_range(np.asarray(grasp.q0, dtype=float), step)
        psi0 = float(walk.ik.elbow_angle(np.asarray(grasp.q0, float)[None])[0])
    finally:
        if owned:
            walk.close()
    found.append((wrap_angle(psi0), np.asarray(grasp.q0, dtype=float).copy()))
    return sorted(found, key=lambda item: item[0])


def configuration_at(grasp: Grasp, psi: float, walk: ArmWalk | None = None) -> np.ndarray:
    """The grasp's configuration moved along its self-motion to elbow angle ``psi`` (radians).

    Raises:
        ValueError: psi is out of reach (the path leaves the joint limits first).
    """
    owned = walk is None
    walk = walk or ArmWalk(grasp.object)
    try:
        moved, ok = walk.ik.set_elbow_angle(np.asarray(grasp.q0, dtype=float), psi)
        if not ok[0]:
            psi0 = float(walk.ik.elbow_angle(np.asarray(grasp.q0, float)[None])[0])
            reach = reachable_configurations(grasp, walk=walk)
            raise ValueError(f"elbow angle {psi:g} rad is out of reach for grasp {grasp.id} of "
                             f"{grasp.object} (nominal {psi0:.3f}; reachable "
                             f"{reach[0][0]:.3f} .. {reach[-1][0]:.3f} rad)")
        return moved[0]
    finally:
        if owned:
            walk.close()


def with_configuration(grasp: Grasp, q: np.ndarray, psi: float) -> Grasp:
    """The same grasp (palm pose, nominal contacts) reached with configuration q (14,)."""
    return Grasp(grasp.object, np.asarray(q, dtype=float), grasp.palm_pose, grasp.points,
                 grasp.normals, grasp.fingers, grasp.links, grasp.q_nominal,
                 id=f"{grasp.id}@{psi:.3f}", meta={**grasp.meta, "elbow_angle": psi})


def nominal_index(grasp: Grasp, reach: list[tuple[float, np.ndarray]]) -> int:
    """Index in ``reach`` of the grasp's own configuration q0."""
    q0 = np.asarray(grasp.q0, dtype=float)
    return min(range(len(reach)), key=lambda i: float(np.abs(reach[i][1] - q0).max()))


def elbow_result(grasp: Grasp, curve: list[ElbowPoint], best: ElbowPoint, nominal: ElbowPoint,
                 nominal_psi: float, noise: JointNoise, samples: int, seed: int, engine: str,
                 step: float, epsilon: float, delta: float,
                 certificate: Certificate | None = None) -> ElbowResult:
    """The result of an elbow search whose curve chose ``best``: the best and the nominal
    angle's P(FC) on their fresh draws (``fresh_fc``) with Wilson intervals, the paired gain
    and the certificate over the rivals (any robot): ``certificate`` when given, else the
    exact one from every curve point's ``fresh_fc``."""
    best_fc, nominal_fc = best.fresh_fc, nominal.fresh_fc
    gain, lo, hi = paired_interval(best_fc.astype(float) - nominal_fc.astype(float))
    rivals = [p for p in curve if p is not best]
    certificate = certificate or certify(best.psi, best_fc, [p.psi for p in rivals],
                          np.array([p.fresh_fc for p in rivals]).reshape(len(rivals),
                                                                          best_fc.size),
                          epsilon, delta)
    n = best_fc.size
    return ElbowResult(
        object=grasp.object, grasp=str(grasp.id),
        sigma=noise.sigma if isinstance(noise.sigma, float) else list(noise.sigma),
        samples=int(samples), seed=int(seed), engine=engine, nominal_psi=nominal_psi,
        nominal_p_fc=float(nominal_fc.mean()),
        nominal_p_fc_ci=wilson_interval(int(nominal_fc.sum()), n), best_psi=best.psi,
        best_q=best.q, best_p_fc=float(best_fc.mean()),
        best_p_fc_ci=wilson_interval(int(best_fc.sum()), n), gain=gain, gain_ci=(lo, hi),
        certificate=certificate, grid_step=float(step), curve=curve)
