"""Which leaves of a hand's URDF tree are a linkage's bars, not fingertips (a description
without ``finger_links`` takes its fingers to end at the other leaves: its distal links)."""

from __future__ import annotations


def linkage_bars(chains: dict[str, list[str]], drivers: dict[str, str]) -> set[str]:
    """The leaves of a hand's tree that are a linkage's bars, not fingertips.

    A linkage finger (the four-bar of a Robotiq 2F-style gripper) is a closed loop, which a
    URDF's tree cuts open: one bar of the loop (the inner knuckle) becomes a leaf of its
    own, one movable joint from where it leaves a finger's chain (the palm, or a link of the
    chain), its joint following an actuator of that finger (a mimic joint). Such a leaf
    ``t`` is a bar, not a fingertip, when another leaf ``u``

    - has more movable joints below the palm than ``t`` (``u``'s chain is the distal one);
    - is moved by every actuator that moves ``t`` (``t`` moves with ``u``, not on its own);
    - has every movable joint of ``t``'s but the last as its own first ones (``t`` hangs
      off ``u``'s chain, or off the palm, by one joint at most: one rigid bar).

    A hand whose fingers each have an actuator of their own (the SDH-like hand), or whose
    coupled fingers are equally long (the Panda's jaws), has no bar.

    Args:
        chains: per leaf, the names of the movable joints from the palm to it, in order.
        drivers: per movable joint, the actuated joint setting it (itself, or the joint a
            mimic joint follows).
    """
    moved_by = {leaf: {drivers[j] for j in chain} for leaf, chain in chains.items()}
    bars = set()
    for t, chain in chains.items():
        for u, other in chains.items():
            if (u != t and len(other) > len(chain) and moved_by[t] <= moved_by[u]
                    and chain[:-1] == other[:len(chain) - 1]):
                bars.add(t)
                break
    return bars
