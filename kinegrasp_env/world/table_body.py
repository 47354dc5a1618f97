"""The support table as a pybullet body (:func:`table_body`): a static box where an object's
:class:`~kinegrasp_env.world.support.SupportTable` puts it, for every world that has the
table (the reference closing's scene, the physics worlds)."""

from __future__ import annotations

from kinegrasp_env.quiet import quiet_c_output
from kinegrasp_env.world.objects import GraspObject
from kinegrasp_env.world.sim import matrix_to_pose

with quiet_c_output():
    import pybullet


def table_body(bullet, obj: GraspObject, friction: float | None = None) -> int:
    """A static box body for ``obj``'s table in ``bullet`` (a BulletClient), collision
    margin zero (``friction``: its lateral friction, else pybullet's default)."""
    pose, half = obj.table.box(obj.pose)
    shape = bullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=half.tolist())
    position, orientation = matrix_to_pose(pose)
    body = bullet.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=shape,
                                  basePosition=position, baseOrientation=orientation)
    bullet.changeDynamics(body, -1, collisionMargin=0.0)
    if friction is not None:
        bullet.changeDynamics(body, -1, lateralFriction=friction)
    return body
