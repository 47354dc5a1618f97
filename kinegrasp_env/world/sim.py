"""The pybullet world: one ``BulletClient`` per world, bodies by name, idempotent close.

Nothing here touches pybullet's global client state: every call goes through the world's own
``BulletClient``. An :class:`ObjectWorld` holds one catalog object built from its exact
convex parts, with collision margins set to zero so that reported distances are exact; a
robot's scene (:mod:`kinegrasp_env.closing.scene`) adds the robot beside it.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
import sys

import numpy as np

from kinegrasp_env.quiet import quiet_c_output

with quiet_c_output():  # pybullet prints its build time on import
    import pybullet
    from pybullet_utils.bullet_client import BulletClient

from kinegrasp_env.assets import asset_path
from kinegrasp_env.world.objects import GraspObject

log = logging.getLogger(__name__)


def matrix_to_pose(transform: np.ndarray) -> tuple[list[float], list[float]]:
    """(4, 4) transform -> (position, quaternion xyzw) lists for pybullet."""
    rot = transform[:3, :3]
    # Shepperd's method
    trace = np.trace(rot)
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        quat = [(rot[2, 1] - rot[1, 2]) / s, (rot[0, 2] - rot[2, 0]) / s,
                (rot[1, 0] - rot[0, 1]) / s, 0.25 * s]
    else:
        i = int(np.argmax(np.diag(rot)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = 2.0 * np.sqrt(1.0 + rot[i, i] - rot[j, j] - rot[k, k])
        quat = [0.0, 0.0, 0.0, (rot[k, j] - rot[j, k]) / s]
        quat[i] = 0.25 * s
        quat[j] = (rot[j, i] + rot[i, j]) / s
        quat[k] = (rot[k, i] + rot[i, k]) / s
    return transform[:3, 3].tolist(), [float(v) for v in quat]


class NoDisplayError(RuntimeError):
    """pybullet's GUI was asked for where no display can show it."""


def display_available() -> bool:
    """Whether pybullet's GUI can open a window in this process.

    On Linux the GUI is an X11 window: without an X server pybullet's GUI connect ends the
    whole process (exit status 1, no message), so this asks first: ``$DISPLAY`` must be set
    and, where libX11 can be loaded, ``XOpenDisplay`` must reach that server. Other systems
    (macOS, Windows) always have a window system: True.
    """
    if not sys.platform.startswith("linux"):
        return True
    display = os.environ.get("DISPLAY", "")
    return bool(display) and x_server_answers(display)


def x_server_answers(display: str) -> bool:
    """Whether the X server ``display`` (e.g. ``:0``) accepts a connection (True when libX11
    cannot be loaded to ask: then ``$DISPLAY`` is all there is to go on)."""
    library = ctypes.util.find_library("X11")
    if library is None:
        return True
    try:
        xlib = ctypes.CDLL(library)
    except OSError:
        return True
    xlib.XOpenDisplay.argtypes = [ctypes.c_char_p]
    xlib.XOpenDisplay.restype = ctypes.c_void_p
    xlib.XCloseDisplay.argtypes = [ctypes.c_void_p]
    handle = xlib.XOpenDisplay(display.encode())
    if not handle:
        return False
    xlib.XCloseDisplay(handle)
    return True


def require_display() -> None:
    """Raise :class:`NoDisplayError` (one clear sentence) when the GUI cannot open here."""
    if not display_available():
        where = os.environ.get("DISPLAY", "")
        reason = f"the X server {where!r} does not answer" if where else "$DISPLAY is not set"
        raise NoDisplayError(f"pybullet's GUI needs a display and there is none ({reason}); "
                             "use the headless mode (gui=False, or render_mode='rgb_array')")


class BulletWorld:
    """A pybullet physics client with bodies registered by name.

    Args:
        gui: open the GUI instead of the headless DIRECT mode.

    Raises:
        NoDisplayError: ``gui`` is asked for where no display can show it (checked before
            connecting: pybullet itself would end the process).
    """

    def __init__(self, gui: bool = False) -> None:
        if gui:
            require_display()
        with quiet_c_output():  # DIRECT mode prints "argv[0]=" on connect
            self.client: BulletClient | None = BulletClient(
                connection_mode=pybullet.GUI if gui else pybullet.DIRECT)
        self.bodies: dict[str, int] = {}

    @property
    def bullet(self) -> BulletClient:
        if self.client is None:
            raise RuntimeError("this world has been closed")
        return self.client

    def body(self, name: str) -> int:
        try:
            return self.bodies[name]
        except KeyError:
            raise KeyError(f"no body named {name!r}; bodies: {sorted(self.bodies)}") from None

    def close(self) -> None:
        """Disconnect; safe to call more than once."""
        if self.client is not None:
            try:
                self.client.disconnect()
            except pybullet.error:  # already disconnected
                pass
            self.client = None

    def __reduce__(self):
        raise TypeError(f"a {type(self).__name__} holds a pybullet client, which cannot be "
                        "copied or pickled: make another (an engine or an env anew, with the "
                        "same arguments)")

    def __deepcopy__(self, memo):
        self.__reduce__()

    def __enter__(self) -> BulletWorld:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self) -> None:  # pragma: no cover - best effort
        try:
            self.close()
        except Exception:
            pass


def body_indices(bullet, body: int, base_link: str) -> tuple[dict[str, int], dict[str, int]]:
    """(joint name -> pybullet joint index, link name -> link index) of a body loaded in
    ``bullet`` (a BulletClient) from a URDF; its base link ``base_link`` is -1."""
    joint_index: dict[str, int] = {}
    link_index: dict[str, int] = {base_link: -1}
    for j in range(bullet.getNumJoints(body)):
        info = bullet.getJointInfo(body, j)
        joint_index[info[1].decode()] = j
        link_index[info[12].decode()] = j
    return joint_index, link_index


def load_hand(bullet) -> tuple[int, dict[str, int], dict[str, int]]:
    """The SDH hand URDF in ``bullet`` (a BulletClient), its root fixed: (body, joint name ->
    pybullet joint index, link name -> link index (-1: the root ``hand_root``)), every link's
    collision margin zero."""
    hand = bullet.loadURDF(str(asset_path("robots", "sdh_hand.urdf")), useFixedBase=True,
                           flags=pybullet.URDF_USE_INERTIA_FROM_FILE)
    joint_index, link_index = body_indices(bullet, hand, "hand_root")
    for link in link_index.values():
        bullet.changeDynamics(hand, link, collisionMargin=0.0)
    return hand, joint_index, link_index


class ObjectWorld(BulletWorld):
    """A world with one catalog object (body ``object``, fixed at ``obj.pose``, one convex
    part a link, collision margins zero), for bodies added beside it.

    Attributes:
        obj: the catalog object.
    """

    def __init__(self, obj: GraspObject, gui: bool = False) -> None:
        super().__init__(gui)
        self.obj = obj
        self.bodies["object"] = self._load_object(obj)

    def _load_object(self, obj: GraspObject) -> int:
        bullet = self.bullet
        shapes = [bullet.createCollisionShape(pybullet.GEOM_MESH, vertices=part.tolist())
                  for part in obj.parts]
        visual = -1
        try:
            visual = bullet.createVisualShape(
                pybullet.GEOM_MESH, fileName=str(obj.mesh_file or asset_path(
                    "objects", f"{obj.name}.obj")),
                rgbaColor=[0.85, 0.55, 0.2, 1.0])
        except pybullet.error:  # pragma: no cover - rendering only
            log.warning("could not create the visual shape of %s", obj.name)
        position, orientation = matrix_to_pose(obj.pose)
        rest = shapes[1:]
        body = bullet.createMultiBody(
            baseMass=0.0, baseCollisionShapeIndex=shapes[0], baseVisualShapeIndex=visual,
            basePosition=position, baseOrientation=orientation,
            linkMasses=[0.0] * len(rest), linkCollisionShapeIndices=rest,
            linkVisualShapeIndices=[-1] * len(rest),
            linkPositions=[[0, 0, 0]] * len(rest), linkOrientations=[[0, 0, 0, 1]] * len(rest),
            linkInertialFramePositions=[[0, 0, 0]] * len(rest),
            linkInertialFrameOrientations=[[0, 0, 0, 1]] * len(rest),
            linkParentIndices=[0] * len(rest), linkJointTypes=[pybullet.JOINT_FIXED] * len(rest),
            linkJointAxis=[[0, 0, 1]] * len(rest))
        for link in range(-1, len(rest)):
            bullet.changeDynamics(body, link, collisionMargin=0.0)
        return body
