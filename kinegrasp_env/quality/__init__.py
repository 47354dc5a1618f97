"""Grasp quality: friction cones and edge wrenches (``wrenches``), the Ferrari-Canny L1
quality and force closure (``epsilon``: the entry point; its qhull reference in
``qhull_quality``), and its two fast
exact paths: the three-contact facet tables (``three_contacts``) and the certified
nearest-facet-first expansion (``expansion``: its start, a simplex around the origin or a
certificate that none exists, in ``phase_one``; its polytope's facet tables in ``facets``),
which ``single`` runs for one grasp in one compiled call; contact models
(``soft_contacts``): point contacts and soft fingers (torsional friction over a patch:
parallel-jaw grasps; their torsional wrenches in ``torsion``). Conventions:
docs/conventions.md. Depends on nothing else in the package.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "epsilon": ("ferrari_canny", "ferrari_canny_batch", "is_force_closure",
                "is_force_closure_batch", "grasp_wrench_space_volume"),
    "wrenches": ("tangent_basis", "friction_cone_edges", "wrench_matrix", "FC_TOL"),
    "soft_contacts": ("CONTACT_MODELS", "contact_wrenches", "contact_quality",
                      "contact_quality_batch", "contact_force_closure", "torsion_coefficient"),
})
