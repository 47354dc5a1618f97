"""The grasp world: the object catalog (``objects``: convex parts, centre of mass, r_max;
``catalog_listing``: one summary row per object; ``importer``: importing the user's meshes,
with ``import_settings``, ``meshfile``, ``meshprep``, ``decompose``, ``deviation``,
``store``),
the pybullet world wrapper (``sim``, one BulletClient per world), the fast engine's distance
grids (``sdf``), convex-part geometry (``polytope``) and grasp sets (``grasps``). Uses
``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "objects": ("GraspObject", "load_object", "object_names"),
    "catalog_listing": ("catalog",),
    "importer": ("import_object", "remove_object"),
    "import_settings": ("ImportSettings",),
    "sim": ("BulletWorld", "ObjectWorld"),
    "sdf": ("DistanceGrid", "object_grid"),
    "grasps": ("Grasp", "shipped_grasps", "grasp_by_index", "load_grasps", "save_grasps",
               "write_atomic"),
})
