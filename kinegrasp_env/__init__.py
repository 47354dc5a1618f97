"""kinegrasp: grasp quality under kinematic (joint-angle) noise.

The names a user starts from are exported here (loaded on first use, so ``import
kinegrasp_env`` stays cheap): ``evaluate_grasp``/``GraspStats`` (Monte Carlo P(FC) and the
moments of Q), ``JointNoise``, ``NoiseModel``/``load_noise_model`` (every source of error),
``ferrari_canny``/``ferrari_canny_batch``, ``load_object``,
``shipped_grasps``, ``GraspPlanner``, ``rank_fixed``/``rank_adaptive`` and ``ENV_IDS``.

The package is layered, top to bottom: ``cli``; ``envs``, ``toolkit``; ``montecarlo``;
``closing``; ``world``; ``robot``; ``quality``, ``sampling`` (imports point only down;
checked by import-linter). Conventions: docs/conventions.md.

Importing the package registers its Gymnasium environments (see ``ENV_IDS``):
``gym.make("KineGrasp-v0")`` after ``import kinegrasp_env``, or
``gym.make("kinegrasp_env:KineGrasp-v0")`` without it.
"""

from __future__ import annotations

import gymnasium

from kinegrasp_env.lazy import lazy_exports

__version__ = "0.1.0"

#: Registered environment IDs.
ENV_IDS: tuple[str, ...] = ("KineGrasp-v0", "KineGraspSelect-v0")

_ENTRY_POINTS = {
    "KineGrasp-v0": ("kinegrasp_env.envs:KineGraspEnv", 10),
    "KineGraspSelect-v0": ("kinegrasp_env.envs:KineGraspSelectEnv", 1),
}
for _env_id, (_entry, _steps) in _ENTRY_POINTS.items():
    if _env_id not in gymnasium.registry:
        gymnasium.register(id=_env_id, entry_point=_entry, max_episode_steps=_steps)

_EXPORTS = {
    "evaluate_grasp": "montecarlo.evaluate",
    "GraspStats": "montecarlo.evaluate",
    "JointNoise": "sampling.noise",
    "NoiseModel": "sampling.noise_model",
    "load_noise_model": "sampling.noise_spec",
    "ferrari_canny": "quality.epsilon",
    "ferrari_canny_batch": "quality.epsilon",
    "load_object": "world.objects",
    "shipped_grasps": "world.grasps",
    "GraspPlanner": "toolkit.planner",
    "rank_fixed": "toolkit.ranking",
    "rank_adaptive": "toolkit.ranking",
}
__getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = ["ENV_IDS", "__version__", *sorted(_EXPORTS)]
