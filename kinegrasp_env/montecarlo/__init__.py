"""Monte Carlo: engines that turn a batch of draws into outcomes, in one format for every
engine and robot (``draws``: the outcomes, contacts, closed hand and hold verdicts; scored by
one function, ``description_engine.score_batch``): any catalog robot's engines over its
description (``description_engine``; ``reference_engine``: the pybullet reference;
``batched_engine``: the fast one; ``robot_physics``: the physics closing; the holding test
as an engine: ``hold_engine``, its results ``hold_batch``; every robot's by name:
``robot_engines``) and the default robot's by name over 14-entry configurations
(``engines``: its description's engines), ``evaluate_grasp`` and its chunked random streams
(``evaluate``; a description robot's runs: ``robot_evaluate``, ``robot_chunks``,
``robot_noise``, the same streams), executors (``execution``: local process pool, Ray),
sweeps over a grid of settings (``sweep``; its spec: ``sweep_spec``, ``sweep_grasps``,
``sweep_noise``) and a grasp's nominal contacts from one closing
(``nominal``).
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
