"""The grasp world: the object catalog (``objects``: convex parts, centre of mass, r_max;
``importer``: importing the user's meshes, with ``meshfile``, ``meshprep``, ``decompose``,
``deviation``, ``store``),
the pybullet world wrapper (``sim``, one BulletClient per world), the fast engine's distance
grids (``sdf``), convex-part geometry (``polytope``) and grasp sets (``grasps``). Uses
``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "objects": ("GraspObject", "load_object", "catalog", "object_names"),
    "importer": ("import_object", "remove_object", "ImportSettings"),
    "sim": ("BulletWorld", "GraspWorld"),
    "sdf": ("DistanceGrid", "object_grid"),
    "grasps": ("Grasp", "shipped_grasps", "grasp_by_index", "load_grasps", "save_grasps",
               "write_atomic"),
})
