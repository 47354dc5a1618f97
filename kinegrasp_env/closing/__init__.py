"""Auto-close: the fingers closed until they touch the object, GraspIt-style.

Entry points: every robot of the catalog (a description beside a URDF), the default one
included: ``generic_reference`` (one draw at a time, pybullet closest points in the robot's
scene, ``scene``, exact near contact for rounded links) and ``generic_fast`` (a batch
of draws; the links' geometry from ``link_geometry``, their distances in ``link_distances``,
object edges against link hulls in ``hull_edges``, the batched loop ``finger_closing``,
fingers of two
capsule phalanxes by the compiled loop of ``capsule_fingers``: ``close_kernel``, its per-row
helpers ``finger_axes`` and ``capsule_gap``, the exact capsule-object pairs of
``segment_distance`` (its packed parts: ``packed_geometry``, its small kernels:
``segment_primitives``)); pads pressed on faces at their patch centres (``contact_patch``), a
closing's contacts and result (``close_result``), where palm and object pose errors put
the links (``hand_errors``), a rounded link's contact (the point model: ``hand_geometry``).
All follow the rules of ``close_rules``. Uses ``world`` and ``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "generic_reference": ("RobotWorld",),
})
