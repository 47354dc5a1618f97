"""The grasp world: the object catalog (``objects``: convex parts, centre of mass, r_max;
``importer``: importing the user's meshes, with ``meshfile``, ``meshprep``, ``decompose``,
``deviation``, ``store``),
the pybullet world wrapper (``sim``, one BulletClient per world), the fast engine's distance
grids (``sdf``), convex-part geometry (``polytope``) and grasp sets (``grasps``). Uses
``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "GraspObject": "objects",
    "load_object": "objects",
    "catalog": "objects",
    "object_names": "objects",
    "import_object": "importer",
    "remove_object": "importer",
    "ImportSettings": "importer",
    "BulletWorld": "sim",
    "GraspWorld": "sim",
    "DistanceGrid": "sdf",
    "object_grid": "sdf",
    "Grasp": "grasps",
    "shipped_grasps": "grasps",
    "grasp_by_index": "grasps",
    "load_grasps": "grasps",
    "save_grasps": "grasps",
    "write_atomic": "grasps",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
