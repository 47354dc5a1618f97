"""The MuJoCo model of the holding test: the hand from its URDF, one catalog object, its table.

MuJoCo is an optional dependency (``pip install kinegrasp-env[mujoco]``), imported on first
use (:func:`import_mujoco`). The model (:func:`build_model`) is compiled from an
:class:`mujoco.MjSpec`:

* the hand (:class:`MujocoHand`): a URDF parsed by MuJoCo's own URDF reader, the same file
  pybullet loads (the same links, capsules, meshes, joint axes and limits, a coupling as
  MuJoCo's equality from the URDF's ``mimic``; static links kept as bodies, visuals
  dropped; MuJoCo takes the links' inertias from the URDF, where pybullet estimates a
  finger link's from its collision shape, as it loads a URDF): a robot's hand cut from its
  URDF
  (:func:`~kinegrasp_env.physics.mujoco_robot_hold.description_hand`).
  Its root is a free body as heavy as pybullet's (``ROOT_MASS``,
  standing in for the arm) welded to a *mocap* body ``anchor``: where the arm's flange is
  (the robot's palm frame), moved only by the protocol (the lift and shake), as
  pybullet's anchor constraint moves its hand (a mocap hand root itself would move without
  a velocity, and friction, which MuJoCo resolves on velocities, held the object back: it
  slipped out in the lift). Every hand joint gets one ``general`` actuator (its motor) and
  one joint equality, off until the controller holds the joint there
  (:mod:`~kinegrasp_env.physics.mujoco_world`);
* the object: a free body at ``obj.pose`` whose collision shape is its exact convex parts (one
  mesh geom per part: MuJoCo collides with each mesh's convex hull), mass and inertia those
  of the uniform-density mesh (:func:`~kinegrasp_env.physics.pybullet_world.mass_properties`,
  the same numbers pybullet gets), pinned to the world by a weld equality while the hand
  closes and grips;
* the table, when the object has one: a static box (``obj.table.box``).

Contacts (:data:`CONTACT`): hand geoms collide only with the object and the table (the
hand's links never with each other, as pybullet loads a URDF without self-collision),
condim 3 (sliding friction only: point contacts), the elliptic cone (Coulomb's), friction mu
on every geom (MuJoCo takes the larger of two: mu), stiff ``solref``/``solimp`` and
``impratio`` 100 (friction stiff against MuJoCo's soft-constraint creep). The same settings
are the ones ``benchmarks/coulomb_consistency.py`` checks against Coulomb's law.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np

from kinegrasp_env.world.objects import GraspObject

#: Collision bit masks: hand geoms (type 1, affinity 2) touch object and table (2, 1) only.
HAND_BITS, OBJECT_BITS = (1, 2), (2, 1)


@dataclass(frozen=True)
class ContactSettings:
    """MuJoCo contact parameters (see the module docstring).

    Attributes:
        solref: (time constant s, damping ratio) of every contact.
        solimp: (dmin, dmax, width m, midpoint, power) impedance of every contact.
        impratio: friction-to-normal impedance ratio (elliptic cones).
        noslip_iterations: MuJoCo's no-slip post-solver (0: off; see the Coulomb
            benchmark for why).
        pin_solref: (time constant, damping ratio) of the weld that pins the object.
    """

    solref: tuple[float, float] = (0.002, 1.0)
    solimp: tuple[float, float, float, float, float] = (0.99, 0.999, 0.001, 0.5, 2.0)
    impratio: float = 100.0
    noslip_iterations: int = 0
    pin_solref: tuple[float, float] = (0.002, 1.0)


#: The settings used by the holding test and by the Coulomb consistency benchmark.
CONTACT = ContactSettings()


def import_mujoco() -> ModuleType:
    """The ``mujoco`` module; ImportError with a one-line hint when it is not installed."""
    try:
        import mujoco
    except ImportError as exc:
        raise ImportError("MuJoCo is not installed: pip install 'kinegrasp-env[mujoco]' "
                          "(or pip install mujoco)") from exc
    return mujoco


def matrix_quat(rotation: np.ndarray) -> np.ndarray:
    """(4,) unit quaternion (w, x, y, z: MuJoCo's order) of a (3, 3) rotation."""
    mujoco = import_mujoco()
    quat = np.empty(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(rotation, dtype=float).ravel())
    return quat


@dataclass(frozen=True)
class MujocoHand:
    """A hand for :func:`build_model`.

    Attributes:
        urdf: the hand's URDF text with MuJoCo's compiler options (:func:`with_compiler`).
        root: the name of its root link (the frame the anchor holds).
        palm: the name of its palm link.
        finger_links: finger link name -> (finger, index of the link in the finger, palm
            to tip).
        fingers: the number of fingers.
    """

    urdf: str
    root: str
    palm: str
    finger_links: dict[str, tuple[int, int]]
    fingers: int


def with_compiler(text: str, source: str) -> str:
    """URDF text with MuJoCo's compiler options after its ``<robot ...>`` tag: visuals
    dropped, static links kept as bodies (so that the palm and the tips have frames), mesh
    paths kept as written (absolute, or relative to the working directory). ValueError
    (one line, naming ``source``) without a ``<robot>`` element."""
    start = text.find("<robot")
    end = text.find(">", start)
    if start < 0 or end < 0:
        raise ValueError(f"{source}: no <robot> element")
    options = ('<mujoco><compiler discardvisual="true" fusestatic="false" strippath="false" '
               'balanceinertia="true"/></mujoco>')
    return text[:end + 1] + options + text[end + 1:]


def set_contact(geom, friction: float, bits: tuple[int, int], settings: ContactSettings) -> None:
    """Contact parameters of one spec geom (module docstring). Margin 0: MuJoCo's contact
    pushes from ``dist < margin`` on (the sum of the two geoms' margins, whatever their
    ``gap``: measured), so a margin would leave the fingers that far from the surface;
    with 0 a contact exists only once the surfaces touch."""
    geom.condim = 3
    geom.friction = [friction, 0.0, 0.0]
    geom.contype, geom.conaffinity = bits
    geom.solref = list(settings.solref)
    geom.solimp = list(settings.solimp)
    geom.margin = geom.gap = 0.0


def build_model(obj: GraspObject, hand: MujocoHand, friction: float, density: float,
                time_step: float, settings: ContactSettings = CONTACT):
    """The compiled :class:`mujoco.MjModel` of hand, object and table (module docstring).

    Args:
        obj: the catalog object (at ``obj.pose``).
        hand: the hand; its root's frame is held by the free joint ``hand_free`` and the
            anchor.
        friction: Coulomb friction mu between finger and object (and table).
        density: the object's, kg/m^3.
        time_step: seconds.
        settings: :class:`ContactSettings`.
    """
    from kinegrasp_env.physics.pybullet_world import ROOT_INERTIA, ROOT_MASS, mass_properties

    mujoco = import_mujoco()
    spec = mujoco.MjSpec.from_string(hand.urdf)
    spec.option.timestep = time_step
    spec.option.gravity = [0.0, 0.0, 0.0]
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = settings.impratio
    spec.option.noslip_iterations = settings.noslip_iterations
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    for geom in spec.geoms:
        set_contact(geom, friction, HAND_BITS, settings)
    for joint in spec.joints:
        hold = spec.add_equality(name=f"hold_{joint.name}", type=mujoco.mjtEq.mjEQ_JOINT,
                                 objtype=mujoco.mjtObj.mjOBJ_JOINT, name1=joint.name)
        hold.data = [0.0] * 11 + [0.0]  # joint = data[0] (+ data[1] x another joint: set
        #                                    by the controller, MujocoWorld.position/couple)
        hold.active = False
        hold.solref = list(settings.pin_solref)
        actuator = spec.add_actuator(name=f"motor_{joint.name}", target=joint.name)
        actuator.trntype = mujoco.mjtTrn.mjTRN_JOINT
        actuator.gaintype = mujoco.mjtGain.mjGAIN_FIXED
        actuator.biastype = mujoco.mjtBias.mjBIAS_AFFINE
        actuator.forcelimited = mujoco.mjtLimited.mjLIMITED_TRUE
        actuator.forcerange = [-1.0, 1.0]  # set by the controller
    root = spec.body(hand.root)
    root.add_freejoint(name="hand_free")
    root.explicitinertial = True
    root.mass, root.inertia = ROOT_MASS, [ROOT_INERTIA] * 3
    root.fullinertia = [float("nan")] + [0.0] * 5  # the URDF's full inertia dropped
    root.ipos, root.iquat = [0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]
    spec.worldbody.add_body(name="anchor", mocap=True)
    anchor = spec.add_equality(name="anchor", type=mujoco.mjtEq.mjEQ_WELD,
                               objtype=mujoco.mjtObj.mjOBJ_BODY, name1=hand.root,
                               name2="anchor")
    anchor.data = [0.0] * 6 + [1.0, 0.0, 0.0, 0.0] + [1.0, 0.0]  # coincident frames
    anchor.solref = list(settings.pin_solref)
    mass, moments, inertial = mass_properties(obj, density)
    body = spec.worldbody.add_body(name="object", pos=obj.pose[:3, 3].tolist(),
                                   quat=matrix_quat(obj.pose[:3, :3]).tolist())
    body.add_freejoint(name="object_free")
    body.explicitinertial = True
    body.mass = mass
    body.ipos = inertial[:3, 3].tolist()
    body.iquat = matrix_quat(inertial[:3, :3]).tolist()
    body.inertia = moments.tolist()
    for i, part in enumerate(obj.parts):
        spec.add_mesh(name=f"part_{i}", uservert=np.asarray(part, float).ravel().tolist())
        geom = body.add_geom(name=f"object_part_{i}", type=mujoco.mjtGeom.mjGEOM_MESH,
                             meshname=f"part_{i}", mass=0.0)
        set_contact(geom, friction, OBJECT_BITS, settings)
    if obj.table is not None:
        pose, half = obj.table.box(obj.pose)
        table = spec.worldbody.add_body(name="table", pos=pose[:3, 3].tolist(),
                                        quat=matrix_quat(pose[:3, :3]).tolist())
        geom = table.add_geom(name="table", type=mujoco.mjtGeom.mjGEOM_BOX, size=half.tolist())
        set_contact(geom, friction, OBJECT_BITS, settings)
    pin = spec.add_equality(name="pin", type=mujoco.mjtEq.mjEQ_WELD,
                            objtype=mujoco.mjtObj.mjOBJ_BODY, name1="object")
    pin.solref = list(settings.pin_solref)
    # anchor (in the world, body2's frame) at the object's centre of mass (at the world
    # origin, 0.6 m away, the weld's rotational softness let the object swing by millimetres),
    # relative pose from the reference configuration (the catalog pose: all zeros), torque
    # scale 1
    com = obj.pose[:3, :3] @ obj.center_of_mass + obj.pose[:3, 3]
    pin.data = [*com.tolist()] + [0.0] * 7 + [1.0, 0.0]
    return spec.compile()
