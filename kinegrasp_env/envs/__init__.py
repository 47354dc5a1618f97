"""Gymnasium environments (registered on ``import kinegrasp_env``)."""

from kinegrasp_env.envs.kinegrasp import KineGraspEnv, KineGraspSelectEnv

__all__ = ["KineGraspEnv", "KineGraspSelectEnv"]
