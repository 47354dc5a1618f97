"""Pictures of the arm, hand and object (pybullet's CPU renderer: works headless), and the
check that a ``human`` (GUI window) render mode can show anything here."""

from __future__ import annotations

import warnings

import numpy as np

from kinegrasp_env.robot.model import kuka_sdh, urdf_path
from kinegrasp_env.world.objects import load_object
from kinegrasp_env.world.sim import GraspWorld, display_available, pybullet


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


class SceneViewer:
    """A world with the whole robot and one object, for rendering."""

    def __init__(self, object_name: str, gui: bool = False) -> None:
        self.object_name = object_name
        self.world = GraspWorld(load_object(object_name), gui=gui)
        bullet = self.world.bullet
        # the stand-alone hand of the grasp world is parked out of view
        bullet.resetBasePositionAndOrientation(self.world.bodies["hand"], [0, 0, -10],
                                               [0, 0, 0, 1])
        robot = bullet.loadURDF(str(urdf_path()), useFixedBase=True)
        self.world.bodies["robot"] = robot
        self.joints = {bullet.getJointInfo(robot, j)[1].decode(): j
                       for j in range(bullet.getNumJoints(robot))}

    def show(self, q: np.ndarray) -> np.ndarray:
        bullet = self.world.bullet
        for name, value in kuka_sdh().expand(q).items():
            bullet.resetJointState(self.world.bodies["robot"], self.joints[name], float(value))
        view = bullet.computeViewMatrixFromYawPitchRoll([0.35, 0.0, 0.35], 1.6, 50, -25, 0, 2)
        proj = bullet.computeProjectionMatrixFOV(60, WIDTH / HEIGHT, 0.05, 5.0)
        _, _, rgba, _, _ = bullet.getCameraImage(WIDTH, HEIGHT, view, proj,
                                                 renderer=pybullet.ER_TINY_RENDERER)
        return np.asarray(rgba, dtype=np.uint8).reshape(HEIGHT, WIDTH, 4)[:, :, :3].copy()

    def close(self) -> None:
        self.world.close()


def render_scene(object_name: str, q: np.ndarray, viewer: SceneViewer | None,
                 gui: bool = False) -> tuple[np.ndarray, SceneViewer]:
    """(H, W, 3) uint8 picture of the robot at q with the object; reuses ``viewer``."""
    if viewer is None or viewer.object_name != object_name:
        if viewer is not None:
            viewer.close()
        viewer = SceneViewer(object_name, gui=gui)
    return viewer.show(q), viewer


__all__ = ["NoDisplayWarning", "SceneViewer", "human_window_available", "render_scene"]
