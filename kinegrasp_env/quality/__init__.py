"""Grasp quality: friction cones and edge wrenches (``wrenches``), the Ferrari-Canny L1
quality and force closure (``epsilon``: the entry point, qhull reference), and its two fast
exact paths: the three-contact facet tables (``three_contacts``) and the certified
nearest-facet-first expansion (``expansion``), which ``single`` runs for one grasp in one
compiled call; contact models (``soft_contacts``): point contacts and soft fingers
(torsional friction over a patch: parallel-jaw grasps). Conventions:
docs/conventions.md. Depends on nothing else in the package.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "ferrari_canny": "epsilon",
    "ferrari_canny_batch": "epsilon",
    "is_force_closure": "epsilon",
    "is_force_closure_batch": "epsilon",
    "grasp_wrench_space_volume": "epsilon",
    "tangent_basis": "wrenches",
    "friction_cone_edges": "wrenches",
    "wrench_matrix": "wrenches",
    "FC_TOL": "wrenches",
    "CONTACT_MODELS": "soft_contacts",
    "contact_wrenches": "soft_contacts",
    "contact_quality": "soft_contacts",
    "contact_quality_batch": "soft_contacts",
    "contact_force_closure": "soft_contacts",
    "torsion_coefficient": "soft_contacts",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
