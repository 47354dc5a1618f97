"""A Coulomb test grasp (:mod:`grasps`) simulated in pybullet and in MuJoCo.

The same scene in both simulators: the object free (its mass from the grasp, gravity off),
each finger a sphere of radius :data:`FINGER_RADIUS` on a slide joint along its contact's
normal, touching the object at the contact point at the start; a force along the slide (the
finger's motor) presses it into the object. The finger cannot move across its slide, so the
contact's tangential (friction) force is whatever the contact solver gives it, and its normal
force is the pressing force once the object is at rest. Friction coefficient mu between
finger and object; no rolling or torsional friction (point contacts).

Load: the finger forces F_i s(t) and the disturbance wrench W s(t) (applied at the object's
centre of mass, world frame) rise together, s(t) a minimum-jerk ramp from 0 to 1 over
:data:`RAMP_TIME`, then stay for the rest of :data:`TEST_TIME` (so the ratio of disturbance to
grip is the final one throughout). Outcome: the object's centre-of-mass displacement
(metres) and rotation (radians) at the end, from where it started; it *slipped* when either
exceeds :data:`SLIP_DISTANCE` or :data:`SLIP_ANGLE`.

Settings (1 ms steps; MuJoCo in 4 substeps of 0.25 ms, as in the holding test):

* pybullet: the fingers are prismatic links of one fixed-base body (their motors off, the
  press a ``TORQUE_CONTROL`` force each step), 100 solver iterations; Bullet combines two
  bodies' friction as their product, so the fingers get lateralFriction 1 and the object mu;
  rolling and spinning friction 0; collision margins 0; the frustum a convex mesh with the
  solid's inertia.
* MuJoCo: the holding test's contact settings (``kinegrasp_env.physics.mujoco_model.
  CONTACT``): condim 3 (sliding friction only), the elliptic (exact Coulomb) cone,
  ``solref`` (0.002 s, 1), ``solimp`` (0.99, 0.999, 0.001 m, 0.5, 2): stiff contacts; ``impratio``
  100 (friction 100 times stiffer than the normal direction: MuJoCo's soft friction gives way
  elastically inside the cone, at the default ratio 1 by ~1 mm here, at 10 the box tripod
  turned 0.87 degrees under its torque while holding, at 100 0.09); no noslip iterations
  (at 5 or 20 the frustum squeeze's outcome was no longer monotone in mu: it slipped at
  1.12 mu* and held at 1.05 and 1.2); both geoms' friction mu (MuJoCo takes the larger of
  the two); the fingers' slide joints driven by ``motor`` actuators.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from .grasps import DENSITY, CoulombGrasp

#: Finger sphere radius, metres, and mass, kg.
FINGER_RADIUS = 0.005
FINGER_MASS = 0.02
#: Simulation step, seconds; load ramp and whole test, seconds.
TIME_STEP = 1e-3
RAMP_TIME = 0.3
TEST_TIME = 1.0
#: Slip thresholds: centre-of-mass displacement (m) and rotation (rad) at the end.
SLIP_DISTANCE = 1e-3
SLIP_ANGLE = math.radians(1.0)


@dataclass(frozen=True)
class SlipResult:
    """Outcome of one simulated test.

    Attributes:
        displacement: of the centre of mass at the end, metres.
        rotation: of the object at the end, radians.
        slipped: displacement > SLIP_DISTANCE or rotation > SLIP_ANGLE.
    """

    displacement: float
    rotation: float

    @property
    def slipped(self) -> bool:
        return self.displacement > SLIP_DISTANCE or self.rotation > SLIP_ANGLE


def load_factor(t: float) -> float:
    """s(t): minimum-jerk ramp from 0 (t = 0) to 1 (t >= RAMP_TIME)."""
    x = min(max(t / RAMP_TIME, 0.0), 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x**2)


def rotation_angle(q0: np.ndarray, q1: np.ndarray) -> float:
    """Angle (rad) of the rotation between two unit quaternions (any component order, the
    same in both)."""
    return 2.0 * math.acos(min(1.0, abs(float(np.dot(q0, q1)))))


def finger_centres(grasp: CoulombGrasp) -> np.ndarray:
    """(k, 3) sphere centres touching the contact points from outside."""
    return grasp.points - FINGER_RADIUS * grasp.normals


def solid_inertia(grasp: CoulombGrasp) -> np.ndarray:
    """(3,) principal moments (kg m^2) of the uniform solid; the test objects' principal axes
    are the coordinate axes (box; frustum: 3-fold symmetric about z)."""
    hull = trimesh.convex.convex_hull(grasp.vertices)
    return np.diag(hull.moment_inertia) * DENSITY / hull.density


def simulate_pybullet(grasp: CoulombGrasp, mu: float) -> SlipResult:
    """Run the test in pybullet (its own ``BulletClient``) at friction ``mu``."""
    import pybullet

    from kinegrasp_env.world.sim import BulletWorld

    with BulletWorld() as world:
        bullet = world.bullet
        bullet.setGravity(0, 0, 0)
        bullet.setTimeStep(TIME_STEP)
        bullet.setPhysicsEngineParameter(numSolverIterations=100,
                                         deterministicOverlappingPairs=1)
        if grasp.shape == "box":
            shape = bullet.createCollisionShape(pybullet.GEOM_BOX,
                                                halfExtents=grasp.vertices.max(axis=0).tolist())
        else:
            shape = bullet.createCollisionShape(pybullet.GEOM_MESH,
                                                vertices=grasp.vertices.tolist())
        body = bullet.createMultiBody(baseMass=grasp.mass, baseCollisionShapeIndex=shape)
        bullet.changeDynamics(body, -1, lateralFriction=mu, rollingFriction=0.0,
                              spinningFriction=0.0, restitution=0.0, linearDamping=0.0,
                              angularDamping=0.0, collisionMargin=0.0,
                              localInertiaDiagonal=solid_inertia(grasp).tolist())
        k = len(grasp.points)
        sphere = bullet.createCollisionShape(pybullet.GEOM_SPHERE, radius=FINGER_RADIUS)
        hand = bullet.createMultiBody(
            baseMass=0.0, linkMasses=[FINGER_MASS] * k, linkCollisionShapeIndices=[sphere] * k,
            linkVisualShapeIndices=[-1] * k,
            linkPositions=finger_centres(grasp).tolist(), linkOrientations=[[0, 0, 0, 1]] * k,
            linkInertialFramePositions=[[0, 0, 0]] * k,
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * k, linkParentIndices=[0] * k,
            linkJointTypes=[pybullet.JOINT_PRISMATIC] * k, linkJointAxis=grasp.normals.tolist())
        joints = list(range(k))
        for j in joints:
            bullet.changeDynamics(hand, j, lateralFriction=1.0, rollingFriction=0.0,
                                  spinningFriction=0.0, restitution=0.0, linearDamping=0.0,
                                  angularDamping=0.0, jointDamping=0.0)
        bullet.setJointMotorControlArray(hand, joints, pybullet.VELOCITY_CONTROL,
                                         forces=[0.0] * k)
        start_pos, start_quat = (np.array(v) for v in bullet.getBasePositionAndOrientation(body))
        steps = round(TEST_TIME / TIME_STEP)
        for step in range(steps):
            s = load_factor(step * TIME_STEP)
            bullet.setJointMotorControlArray(hand, joints, pybullet.TORQUE_CONTROL,
                                             forces=(s * grasp.forces).tolist())
            position, _ = bullet.getBasePositionAndOrientation(body)
            bullet.applyExternalForce(body, -1, (s * grasp.wrench[:3]).tolist(), position,
                                      pybullet.WORLD_FRAME)
            bullet.applyExternalTorque(body, -1, (s * grasp.wrench[3:]).tolist(),
                                       pybullet.WORLD_FRAME)
            bullet.stepSimulation()
        pos, quat = (np.array(v) for v in bullet.getBasePositionAndOrientation(body))
    return SlipResult(float(np.linalg.norm(pos - start_pos)), rotation_angle(start_quat, quat))


def _vec(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.ravel(values))


def mujoco_xml(grasp: CoulombGrasp, mu: float) -> str:
    """The MJCF of the test scene at friction ``mu`` (module docstring), with the holding
    test's MuJoCo contact settings (:data:`kinegrasp_env.physics.mujoco_model.CONTACT`)."""
    from kinegrasp_env.physics.mujoco_model import CONTACT as c
    from kinegrasp_env.physics.mujoco_world import SUBSTEPS

    if grasp.shape == "box":
        asset = ""
        geom = f'type="box" size="{_vec(grasp.vertices.max(axis=0))}"'
    else:
        asset = f'<asset><mesh name="object" vertex="{_vec(grasp.vertices)}"/></asset>'
        geom = 'type="mesh" mesh="object"'
    fingers, motors = [], []
    for i, (centre, normal) in enumerate(zip(finger_centres(grasp), grasp.normals, strict=True)):
        fingers.append(
            f'<body name="finger{i}" pos="{_vec(centre)}">'
            f'<joint name="slide{i}" type="slide" axis="{_vec(normal)}"/>'
            f'<geom type="sphere" size="{FINGER_RADIUS}" mass="{FINGER_MASS}"/></body>')
        motors.append(f'<motor name="press{i}" joint="slide{i}" gear="1"/>')
    return f"""<mujoco model="coulomb_{grasp.name}">
  <option timestep="{TIME_STEP / SUBSTEPS}" gravity="0 0 0" cone="elliptic" impratio="{c.impratio}"
          noslip_iterations="{c.noslip_iterations}"/>
  <default><geom condim="3" friction="{mu} 0 0" solref="{_vec(c.solref)}"
                 solimp="{_vec(c.solimp)}"/></default>
  {asset}
  <worldbody>
    <body name="object"><freejoint/><geom {geom} density="{DENSITY}"/></body>
    {"".join(fingers)}
  </worldbody>
  <actuator>{"".join(motors)}</actuator>
</mujoco>"""


def simulate_mujoco(grasp: CoulombGrasp, mu: float) -> SlipResult:
    """Run the test in MuJoCo at friction ``mu``."""
    from kinegrasp_env.physics.mujoco_model import import_mujoco
    from kinegrasp_env.physics.mujoco_world import SUBSTEPS

    mujoco = import_mujoco()
    model = mujoco.MjModel.from_xml_string(mujoco_xml(grasp, mu))
    data = mujoco.MjData(model)
    body = model.body("object").id
    mujoco.mj_forward(model, data)
    start_pos, start_quat = data.xipos[body].copy(), data.xquat[body].copy()
    for step in range(round(TEST_TIME / TIME_STEP)):
        s = load_factor(step * TIME_STEP)
        data.ctrl[:] = s * grasp.forces
        data.xfrc_applied[body] = s * grasp.wrench
        mujoco.mj_step(model, data, nstep=SUBSTEPS)
    return SlipResult(float(np.linalg.norm(data.xipos[body] - start_pos)),
                      rotation_angle(start_quat, data.xquat[body]))


SIMULATORS = {"pybullet": simulate_pybullet, "mujoco": simulate_mujoco}
