"""kinegrasp: grasp quality under kinematic (joint-angle) noise.

Importing the package registers its Gymnasium environments (see ``ENV_IDS``):
``gym.make("KineGrasp-v0")`` after ``import kinegrasp_env``, or
``gym.make("kinegrasp_env:KineGrasp-v0")`` without it.
"""

from __future__ import annotations

import gymnasium

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

__all__ = ["ENV_IDS", "__version__"]
