"""Monte Carlo: engines that turn a batch of draws into outcomes (``engines``: pybullet
reference and fast), ``evaluate_grasp`` and its chunked random streams (``evaluate``), executors
(``execution``: local process pool, Ray), sweeps over a grid of settings (``sweep``) and a
grasp's nominal contacts from one closing (``nominal``).
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "draws": ("DrawBatch",),
    "engines": ("make_engine", "Engine"),
    "evaluate": ("evaluate_grasp", "GraspStats", "ENGINES"),
    "execution": ("make_executor", "Executor", "LocalExecutor", "RayExecutor"),
    "sweep": ("SweepSpec", "run_sweep"),
})
