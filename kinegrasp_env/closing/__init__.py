"""Auto-close: the fingers closed until they touch the object, GraspIt-style.

Entry points: ``reference.auto_close`` (one draw, pybullet distance queries: the reference;
its hand in pybullet: ``hand_probe``) and ``fast.FastHand`` (a batch of draws: distance grids
and compiled kernels). Both follow the rules of ``close_rules`` and share the exact
near-contact geometry of ``hand_geometry`` and ``segment_distance`` (its packed parts:
``packed_geometry``, its small kernels: ``segment_primitives``); the compiled closing loop is
``close_kernel``, its per-row helpers ``finger_axes`` and ``capsule_gap``, the same loop as
array operations ``close_vectorized``. Any robot of the
catalog (a description beside a URDF): ``generic_reference`` (pybullet closest points) and
``generic_fast`` (batched; the links' geometry from ``link_geometry``, object edges against
link hulls in ``hull_edges``), pads pressed on faces at their patch centres
(``contact_patch``), a closing's contacts and result (``robot_contacts``), where palm and
object pose errors put the links (``hand_errors``). Uses ``world`` and ``robot``.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "reference": ("auto_close", "CloseResult", "Contact"),
    "fast": ("FastHand", "BatchClose"),
})
