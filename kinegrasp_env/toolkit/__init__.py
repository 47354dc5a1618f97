"""The toolkit: the grasp planner (``planner``), candidates given as palm poses
(``candidates``), ranking by robustness (``ranking``), the most robust elbow (``elbow``), the
paper's experiments (``experiments``), the sensitivity analysis per source of error
(``sensitivity``), the physics validation (``validation``), HTML reports (the ``report`` room),
progress (``progress``) and plots (``plots``). Uses ``montecarlo`` and below.
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "GraspPlanner": "planner",
    "PlannerSettings": "planner",
    "rank_fixed": "ranking",
    "rank_adaptive": "ranking",
    "CandidateResult": "ranking",
    "table1": "experiments",
    "fig7": "experiments",
    "fig9_10": "experiments",
    "Sensitivity": "sensitivity",
    "optimize_elbow": "elbow",
    "ElbowResult": "elbow",
    "run_validation": "validation",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
