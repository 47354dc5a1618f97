"""kinegrasp: grasp quality under kinematic (joint-angle) noise.

The names a user starts from are exported here (loaded on first use, so ``import
kinegrasp_env`` stays cheap): ``evaluate_grasp``/``GraspEvaluation`` (Monte Carlo P(FC) and the
moments of Q of a grasp of any catalog robot), ``JointNoise``,
``NoiseModel``/``load_noise_model`` (every source of error), ``ferrari_canny``/
``ferrari_canny_batch``, ``load_object``, ``shipped_grasps``, ``plan_grasps`` (grasps of any
catalog robot), ``rank_fixed``/``rank_adaptive`` and ``ENV_IDS``.

The package is layered, top to bottom: ``cli``; ``envs``, ``toolkit``; ``montecarlo``;
``closing``; ``world``; ``robot``; ``quality``, ``sampling`` (imports point only down;
checked by import-linter). Conventions: docs/conventions.md.

Importing the package registers its Gymnasium environments (see ``ENV_IDS``):
``gym.make("KineGrasp-v0")`` after ``import kinegrasp_env``, or
``gym.make("kinegrasp_env:KineGrasp-v0")`` without it. Gymnasium itself is not imported
for it: the IDs are registered at once if Gymnasium is already loaded, else the moment it is
(so ``kinegrasp --help`` never pays for Gymnasium and NumPy).
"""

from __future__ import annotations

from kinegrasp_env.lazy import lazy_exports, when_imported

__version__ = "0.1.0"

#: Registered environment IDs.
ENV_IDS: tuple[str, ...] = ("KineGrasp-v0", "KineGraspSelect-v0")

#: Their entry points. Each env truncates its episodes itself, at its ``max_steps``: a
#: registered ``max_episode_steps`` would add a TimeLimit that overrides the argument.
_ENTRY_POINTS = {
    "KineGrasp-v0": "kinegrasp_env.envs:KineGraspEnv",
    "KineGraspSelect-v0": "kinegrasp_env.envs:KineGraspSelectEnv",
}


def _register_envs(gymnasium) -> None:
    """Register :data:`ENV_IDS` with ``gymnasium`` (the module), once."""
    for env_id, entry in _ENTRY_POINTS.items():
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point=entry)


when_imported("gymnasium", _register_envs)

__getattr__, __dir__, _LAZY = lazy_exports(__name__, {
    "montecarlo.evaluate": ("evaluate_grasp", "GraspEvaluation"),
    "sampling.noise": ("JointNoise",),
    "sampling.noise_model": ("NoiseModel",),
    "sampling.noise_spec": ("load_noise_model",),
    "quality.epsilon": ("ferrari_canny", "ferrari_canny_batch"),
    "world.objects": ("load_object",),
    "world.grasps": ("shipped_grasps",),
    "toolkit.grasp_planner": ("plan_grasps",),
    "toolkit.ranking": ("rank_fixed",),
    "toolkit.adaptive_ranking": ("rank_adaptive",),
})

__all__ = ["ENV_IDS", "__version__", *_LAZY]
