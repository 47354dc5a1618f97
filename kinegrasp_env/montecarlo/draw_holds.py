"""The default robot's quick holding test on its engines' draws, and the noise every hold
score of a robot's draws takes.

**The quick holding test** (:class:`QuickHoldTest`): the default robot's own holding test
(:class:`~kinegrasp_env.montecarlo.physics_engine.PhysicsEngine`, its grip balanced over the
three fingers) with the quick protocol (:data:`~kinegrasp_env.physics.protocol.
QUICK_PROTOCOL`), in pybullet or MuJoCo, on the same draws' configurations.

The static hold check is the engines' own (``static_hold=True``: every engine of every robot
runs :class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck` on its closings, the
draws' ``held``): it takes every source of error but a per-draw friction (it holds at one
mu). The holding test takes joint and hand noise only (:func:`check_hold_noise`): it places
the hand by its joints, so a palm or object error, which moves the palm against the object,
is not one it can simulate.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.evaluate import chunk_configurations, chunk_sizes
from kinegrasp_env.physics.protocol import HELD, QUICK_PROTOCOL
from kinegrasp_env.sampling.noise_model import NoiseModel
from kinegrasp_env.world.grasps import DEFAULT_ROBOT

__all__ = ["QuickHoldTest", "check_hold_noise", "check_hold_scores_noise"]


def check_hold_noise(noise, robot: str = DEFAULT_ROBOT, score: str = "the hold scores"
                     ) -> None:
    """ValueError (one line) for a noise model with a palm, object or friction source:
    ``score`` of ``robot``'s draws (the default robot's hold scores; any robot's holding
    test) takes joint and hand noise only (the holding test places the hand by its joints)."""
    if not isinstance(noise, NoiseModel):
        return
    other = [name for name in ("palm", "object", "friction") if getattr(noise, name) is not None]
    if other:
        raise ValueError(f"{score} of {robot}'s draws take joint and hand noise only; the "
                         f"noise spec has {', '.join(other)}")


def run_configurations(q0: np.ndarray, noise, seed: int, n: int, chunk: int,
                       first_chunk: int = 0) -> np.ndarray:
    """(n, 14) the configurations of the n draws a run from q0 (14,) makes with ``noise`` and
    ``seed`` in chunks of ``chunk`` from chunk ``first_chunk`` on."""
    if n == 0:
        return np.empty((0, np.asarray(q0).size))
    chunks = [(first_chunk + i, size) for i, size in enumerate(chunk_sizes(n, chunk))]
    return chunk_configurations(q0, noise, seed, chunks)


def check_hold_scores_noise(noise, *, static: bool, test: bool) -> None:
    """ValueError (one line) for a noise model the hold scores asked for cannot take: the
    holding test (``test``) joint and hand noise only (:func:`check_hold_noise`), the static
    hold check (``static``) every source but a friction source
    (:func:`~kinegrasp_env.montecarlo.robot_noise.check_static_hold_noise`)."""
    from kinegrasp_env.montecarlo.robot_noise import check_static_hold_noise

    if test:
        check_hold_noise(noise, score="the holding test")
    if static:
        check_static_hold_noise(noise)


class QuickHoldTest:
    """The default robot's quick holding test on one catalog object (module docstring).

    Args:
        object_name: the catalog object; friction: Coulomb mu, finger-object.
        simulator: ``pybullet`` or ``mujoco``.
    """

    def __init__(self, object_name: str, *, friction: float = 0.5,
                 simulator: str = "pybullet") -> None:
        from kinegrasp_env.montecarlo.physics_engine import PhysicsEngine

        self.engine = PhysicsEngine(object_name, friction, protocol=QUICK_PROTOCOL,
                                    simulator=simulator)
        self.simulator = simulator

    def chunk_held(self, q0: np.ndarray, noise, seed: int, n: int, *, chunk: int,
                   first_chunk: int = 0) -> np.ndarray:
        """(n,) whether the test holds each of the n draws a run from q0 (14,) makes with
        ``noise`` and ``seed`` in chunks of ``chunk`` from chunk ``first_chunk`` on."""
        check_hold_noise(noise)
        q = run_configurations(q0, noise, seed, n, chunk, first_chunk)
        return self.engine.run_hold(q)[1].outcome == HELD

    def close(self) -> None:
        self.engine.close()

    def __enter__(self) -> QuickHoldTest:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
