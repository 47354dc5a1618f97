"""A picture of a robot: pybullet's software renderer in its own DIRECT client.

The robot stands at its open configuration (arm joints at zero, hand at the description's
``open`` pre-shape, mimic joints following), seen from the front-left, the camera aimed at
the centre of the robot's bounding box.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.robot.description import RobotDescription


def resolved_urdf_text(description: RobotDescription) -> str:
    """The URDF's text with every mesh path replaced by its resolved absolute path, so that
    any URDF reader finds the meshes wherever the file is written."""
    text = description.urdf.read_text()
    for mesh in {m.filename: m for m in description.meshes}.values():
        text = text.replace(f'"{mesh.filename}"', f'"{mesh.path.as_posix()}"')
    return text


def draw_robot(description: RobotDescription, out: str | Path, *, width: int = 640,
               height: int = 480, yaw: float = 50.0, pitch: float = -20.0) -> Path:
    """Render the robot at its open configuration into the PNG ``out``.

    Args:
        description: the robot.
        out: the PNG file to write.
        width, height: image size, pixels.
        yaw, pitch: camera direction, degrees (pybullet's convention).

    Returns:
        The path written.
    """
    import numpy as np
    from PIL import Image

    out = Path(out)
    values = description.model.expand(description.open_configuration())
    with quiet_c_output():  # pybullet's banner, "argv[0]=" on connect
        import pybullet
        from pybullet_utils.bullet_client import BulletClient

        bullet = BulletClient(connection_mode=pybullet.DIRECT)
    try:
        with tempfile.TemporaryDirectory() as folder, quiet_c_output():  # mesh-loader notes
            urdf = Path(folder) / description.urdf.name
            urdf.write_text(resolved_urdf_text(description))
            body = bullet.loadURDF(str(urdf), useFixedBase=True)
        names = {bullet.getJointInfo(body, i)[1].decode(): i
                 for i in range(bullet.getNumJoints(body))}
        for joint, value in values.items():
            bullet.resetJointState(body, names[joint], float(value))
        boxes = [bullet.getAABB(body, i) for i in range(-1, len(names))]
        low = np.min([b[0] for b in boxes], axis=0)
        high = np.max([b[1] for b in boxes], axis=0)
        centre, size = (low + high) / 2, float(np.linalg.norm(high - low))
        view = bullet.computeViewMatrixFromYawPitchRoll(centre.tolist(), 1.25 * size, yaw,
                                                        pitch, 0.0, 2)
        projection = bullet.computeProjectionMatrixFOV(50.0, width / height, 0.05 * size,
                                                       5.0 * size)
        image = bullet.getCameraImage(width, height, view, projection,
                                      renderer=pybullet.ER_TINY_RENDERER)[2]
    finally:
        bullet.disconnect()
    rgb = np.asarray(image, dtype=np.uint8).reshape(height, width, 4)[:, :, :3]
    out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(rgb).save(out, format="PNG")
    return out
