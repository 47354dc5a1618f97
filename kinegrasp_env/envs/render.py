"""Pictures of the arm, hand and object (pybullet's CPU renderer: works headless), and the
check that a ``human`` (GUI window) render mode can show anything here.

Every robot of the catalog, the default one included, is drawn by :class:`SceneViewer` from
its description's URDF; it holds a pybullet client of its own (never pybullet's global state)
and draws with one camera: 320 x 240 pixels, looking at (0.35, 0, 0.35) m from 1.6 m, yaw
50 degrees, pitch -25 degrees.
"""

from __future__ import annotations

import warnings

import numpy as np

from kinegrasp_env.closing.generic_reference import RobotWorld
from kinegrasp_env.robot.default_robot import default_description
from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.sim import BulletClient, display_available, pybullet


class NoDisplayWarning(UserWarning):
    """``render_mode="human"`` was asked for where no window can open; nothing is shown."""


def human_window_available() -> bool:
    """Whether a ``human`` render mode can open pybullet's GUI window here; when it cannot,
    warn once (:class:`NoDisplayWarning`) and return False (the caller renders nothing)."""
    if display_available():
        return True
    warnings.warn("render_mode='human' needs a display and there is none (no reachable "
                  "$DISPLAY): no window opens and render() returns None; use "
                  "render_mode='rgb_array' for pictures", NoDisplayWarning, stacklevel=3)
    return False

WIDTH, HEIGHT = 320, 240


def camera_image(bullet: BulletClient) -> np.ndarray:
    """(HEIGHT, WIDTH, 3) uint8 RGB picture of ``bullet``'s world from the envs' camera."""
    view = bullet.computeViewMatrixFromYawPitchRoll([0.35, 0.0, 0.35], 1.6, 50, -25, 0, 2)
    proj = bullet.computeProjectionMatrixFOV(60, WIDTH / HEIGHT, 0.05, 5.0)
    _, _, rgba, _, _ = bullet.getCameraImage(WIDTH, HEIGHT, view, proj,
                                             renderer=pybullet.ER_TINY_RENDERER)
    return np.asarray(rgba, dtype=np.uint8).reshape(HEIGHT, WIDTH, 4)[:, :, :3].copy()


class SceneViewer:
    """A world with a catalog robot's whole URDF (arm and hand, fixed at the world origin)
    and one object at its catalog pose, for rendering.

    Args:
        object_name: a catalog object.
        gui: open pybullet's GUI window (see :func:`human_window_available`).
        description: the robot (default: the default robot's).
    """

    def __init__(self, object_name: str, gui: bool = False,
                 description: RobotDescription | None = None) -> None:
        description = default_description() if description is None else description
        self.object_name = object_name
        self.robot = description.name
        self.world = RobotWorld(description, load_object(object_name), gui=gui)

    def show(self, q: np.ndarray) -> np.ndarray:
        """(HEIGHT, WIDTH, 3) uint8 picture of the robot at q (dof,) (arm joints then hand
        joints, radians: the description's actuated vector)."""
        self.world.set_configuration(q)
        return camera_image(self.world.bullet)

    def close(self) -> None:
        self.world.close()


def render_scene(object_name: str, q: np.ndarray, viewer: SceneViewer | None,
                 gui: bool = False, robot: RobotDescription | None = None
                 ) -> tuple[np.ndarray, SceneViewer]:
    """(HEIGHT, WIDTH, 3) uint8 picture of the robot at q with the object; reuses ``viewer``
    when it shows the same robot and object.

    Args:
        object_name: a catalog object.
        q: the robot's configuration (radians): (14,) for the default robot, (dof,) for
            ``robot``.
        viewer: the viewer of the previous picture (or None).
        gui: open pybullet's GUI window for a new viewer.
        robot: a description robot (None: the default robot).
    """
    robot = default_description() if robot is None else robot
    if viewer is None or viewer.object_name != object_name or viewer.robot != robot.name:
        if viewer is not None:
            viewer.close()
        viewer = SceneViewer(object_name, gui=gui, description=robot)
    return viewer.show(q), viewer


__all__ = ["HEIGHT", "WIDTH", "NoDisplayWarning", "SceneViewer",
           "camera_image", "human_window_available", "render_scene"]
