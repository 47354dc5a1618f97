"""Monte Carlo: engines that turn a batch of draws into outcomes (``engines``: pybullet
reference and fast), ``evaluate_grasp`` and its chunked random streams (``evaluate``), executors
(``execution``: local process pool, Ray), sweeps over a grid of settings (``sweep``) and a
grasp's nominal contacts from one closing (``nominal``).
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

_EXPORTS = {
    "make_engine": "engines",
    "Engine": "engines",
    "DrawBatch": "engines",
    "evaluate_grasp": "evaluate",
    "GraspStats": "evaluate",
    "ENGINES": "evaluate",
    "make_executor": "execution",
    "Executor": "execution",
    "LocalExecutor": "execution",
    "RayExecutor": "execution",
    "SweepSpec": "sweep",
    "run_sweep": "sweep",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)
__all__ = sorted(_EXPORTS)
