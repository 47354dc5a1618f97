"""The toolkit: the grasp planner (``planner``), ranking by robustness (``ranking``), the
paper's experiments (``experiments``), the sensitivity analysis per source of error
(``sensitivity``) and plots (``plots``). Uses ``montecarlo`` and below.
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
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
