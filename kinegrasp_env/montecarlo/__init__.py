"""Monte Carlo: engines that turn a batch of draws into outcomes, in one format for every
engine and robot (``draws``: the outcomes, contacts, closed hand and hold verdicts; scored by
one function, ``description_engine.score_batch``): every catalog robot's engines over its
description (``description_engine``; ``reference_engine``: the pybullet reference;
``batched_engine``: the fast one; ``physics_engine``: the physics closing; by name:
``engines``; the holding test as an engine: ``hold_engine``, its results ``hold_batch``),
``evaluate_grasp`` (``evaluate``: one grasp of any robot, in chunks of the run's random
streams: ``chunks``, ``noise_rows``; merged statistics: ``grasp_stats``), executors
(``execution``: local process pool, Ray), sweeps over a grid of settings (``sweep``; its
spec: ``sweep_spec``, ``sweep_grasps``, ``sweep_noise``) and a grasp's nominal contacts from
one closing (``nominal``).
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports

__getattr__, __dir__, __all__ = lazy_exports(__name__, {
    "draws": ("DrawBatch",),
    "engines": ("make_engine", "ENGINES"),
    "evaluate": ("evaluate_grasp", "GraspEvaluation"),
    "grasp_stats": ("GraspStats",),
    "execution": ("make_executor", "Executor", "LocalExecutor", "RayExecutor"),
    "sweep": ("SweepSpec", "run_sweep"),
})
