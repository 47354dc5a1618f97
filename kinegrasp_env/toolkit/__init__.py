"""The toolkit: grasp planning for any robot (``grasp_planner``: antipodal pairs for
parallel jaws; ``approach_planner``: sampled approaches and pre-shapes for any other hand),
candidates given as palm poses (``candidates``; every robot's solved by
``candidate_solver``), ranking by robustness (``ranking``; certified, ``adaptive_ranking``),
the most robust elbow of any robot (``elbow_search``; its results: ``elbow``; its figures:
``elbow_plots``), the paper's
experiments (``experiments``), the sensitivity analysis per source of error
(``sensitivity``), the physics validation (``validation``), HTML reports (the ``report``
room), progress (``progress``) and plots (``plots``). Uses ``montecarlo`` and below.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "grasp_planner": ("plan_grasps",),
    "ranking": ("rank_fixed", "CandidateResult"),
    "adaptive_ranking": ("rank_adaptive",),
    "experiments": ("fig7", "fig10"),
    "sensitivity": ("Sensitivity",),
    "elbow": ("ElbowResult",),
    "elbow_search": ("optimize_robot_elbow", "optimize_robot_branches"),
    "validation": ("run_validation",),
})
