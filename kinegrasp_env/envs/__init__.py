"""Gymnasium environments (registered on ``import kinegrasp_env``)."""

from kinegrasp_env.envs.kinegrasp import KineGraspEnv
from kinegrasp_env.envs.select import KineGraspSelectEnv

__all__ = ["KineGraspEnv", "KineGraspSelectEnv"]
