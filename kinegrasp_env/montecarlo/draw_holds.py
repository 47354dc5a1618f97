"""The noise every hold score of a robot's draws takes.

The quick holding test of every robot is :func:`~kinegrasp_env.montecarlo.hold_engine.
quick_hold_engine`. The static hold check
is the engines' own (``static_hold=True``: every engine of every robot runs
:class:`~kinegrasp_env.montecarlo.hold_check.StaticHoldCheck` on its closings, the draws'
``held``): it takes every source of error but a per-draw friction (it holds at one mu).
The holding test takes joint and hand noise only (:func:`check_hold_noise`): it places the
hand by its joints, so a palm or object error, which moves the palm against the object, is
not one it can simulate.
"""

from __future__ import annotations

from kinegrasp_env.sampling.noise_model import NoiseModel

__all__ = ["check_hold_noise"]


def check_hold_noise(noise, robot: str, score: str) -> None:
    """ValueError (one line) for a noise model with a palm, object or friction source:
    ``score`` (the holding test, as an option names it) of ``robot``'s draws takes joint and
    hand noise only (the holding test places the hand by its joints)."""
    if not isinstance(noise, NoiseModel):
        return
    other = [name for name in ("palm", "object", "friction") if getattr(noise, name) is not None]
    if other:
        raise ValueError(f"{score} of {robot}'s draws takes joint and hand noise only; the "
                         f"noise spec has {', '.join(other)}")
