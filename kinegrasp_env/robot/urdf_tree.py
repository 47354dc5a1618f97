"""A URDF's joint tree as a robot description reads it (:class:`UrdfTree`: its movable
joints, the joint above each link, the chain from a link up to the root, which joint drives
each movable joint, a mimic joint following another), and the description's checks against
it, each problem one :class:`~kinegrasp_env.robot.description_fields.RobotDescriptionError`
line: a joint or link the URDF does not have (or that cannot serve as named), the arm chain
(:func:`check_chain`), every movable joint listed (:func:`check_every_joint_listed`), the
closing directions (:func:`check_close`) and their travel (:func:`check_travel`)."""

from __future__ import annotations

import math
from pathlib import Path

from kinegrasp_env.robot.description_fields import check_mapping, check_names, fail
from kinegrasp_env.robot.model import Joint, RobotModel
from kinegrasp_env.robot.preshapes import PreshapeDraw


class UrdfTree:
    """The joints and links of a URDF's model.

    Args:
        model: the URDF's model (:func:`~kinegrasp_env.robot.model.load_urdf`).
        urdf: its file (named in errors).
        where: the description file's name (errors start with it).

    Attributes:
        movable: name -> every movable joint (mimic joints included).
        by_child: link -> the joint whose child it is.
        driver: movable joint name -> (the joint that drives it, its multiplier): itself and
            1 for an independent joint, the followed joint for a mimic joint.
    """

    def __init__(self, model: RobotModel, urdf: Path, where: str) -> None:
        self.model, self.urdf, self.where = model, urdf, where
        self.movable = {j.name: j for j in model.joints if j.movable}
        self.by_child = {j.child: j for j in model.joints}
        self.links = set(model.links)
        self.driver = {name: (j.mimic[0], j.mimic[1]) if j.mimic else (name, 1.0)
                       for name, j in self.movable.items()}

    def known_joint(self, key: str, joint: str) -> None:
        """Refuse (under ``key``) a joint that is not a movable, independent joint."""
        if joint not in self.movable:
            kind = "a fixed joint" if any(j.name == joint for j in self.model.joints) else \
                "unknown joint"
            raise fail(self.where, key, f"{kind} {joint!r} (movable joints in "
                       f"{self.urdf.name}: {', '.join(self.movable)})")
        if self.movable[joint].mimic is not None:
            raise fail(self.where, key, f"{joint!r} is a mimic joint (it follows "
                       f"{self.movable[joint].mimic[0]!r}); name the joint it follows")

    def known_link(self, key: str, link) -> None:
        """Refuse (under ``key``) a link the URDF does not have."""
        if not isinstance(link, str) or link not in self.links:
            raise fail(self.where, key, f"unknown link {link!r} in {self.urdf.name}")

    def ancestors(self, link: str) -> list[str]:
        """The links from ``link`` up to the root, ``link`` first."""
        chain = [link]
        while chain[-1] in self.by_child:
            chain.append(self.by_child[chain[-1]].parent)
        return chain

    def beyond(self, link: str, joint: Joint) -> bool:
        """Whether ``joint`` moves a link beyond ``link`` (its parent is ``link`` or below
        it)."""
        return link in self.ancestors(joint.parent)

    def path_joints(self, top: str, tip: str) -> list[Joint]:
        """The joints from link ``top`` down to link ``tip`` (one of its descendants), in
        order."""
        up = self.ancestors(tip)
        return [self.by_child[link] for link in reversed(up[:up.index(top)])]

    def fixed_below(self, link: str) -> list[tuple[str, Joint]]:
        """The links rigidly attached below ``link`` (through fixed joints alone, at any
        depth), each with the fixed joint above it."""
        out, todo = [], [link]
        while todo:
            parent = todo.pop()
            for joint in self.model.joints:
                if joint.parent == parent and not joint.movable:
                    out.append((joint.child, joint))
                    todo.append(joint.child)
        return out

    def moved_links(self, joints) -> list[str]:
        """The links that any of ``joints`` moves, their mimic followers included, in the
        model's order."""
        moved = [j.child for j in self.movable.values() if self.driver[j.name][0] in joints]
        return [link for link in self.model.links
                if any(m in self.ancestors(link) for m in moved)]


def check_chain(data: dict, tree: UrdfTree
                 ) -> tuple[tuple[str, ...], str, tuple[str, ...], list[str]]:
    """(arm joints, palm link, hand joints, the links from the root to the palm): the arm
    exactly the movable joints on the path from the base to the palm, in order; every hand
    joint beyond the palm."""
    where = tree.where
    arm = check_names(data["arm_joints"], where, "arm_joints")
    for j in arm:
        tree.known_joint("arm_joints", j)
    palm = data["palm_link"]
    tree.known_link("palm_link", palm)
    hand = check_names(data["hand_joints"], where, "hand_joints")
    for j in hand:
        tree.known_joint("hand_joints", j)
        if not tree.beyond(palm, tree.movable[j]):
            raise fail(where, "hand_joints", f"{j!r} moves link {tree.movable[j].child!r}, "
                       f"which is not beyond palm_link {palm!r}")
    path_links = tree.ancestors(palm)[::-1]
    chain = [tree.by_child[link].name for link in path_links[1:]
             if tree.by_child[link].movable]
    if list(arm) != chain:
        base = tree.model.base_link
        stray = [j for j in arm if j not in chain]
        if stray:
            problem = (f"{stray[0]!r} is not on the chain from the base {base!r} to "
                       f"palm_link {palm!r}")
        else:
            problem = (f"{list(arm)} is not the chain from the base {base!r} to palm_link "
                       f"{palm!r}: its movable joints are {chain}")
        raise fail(where, "arm_joints", problem)
    return arm, palm, hand, path_links


def check_every_joint_listed(tree: UrdfTree, arm: tuple[str, ...], hand: tuple[str, ...],
                              palm: str) -> None:
    """Every movable joint is an arm or a hand joint, or a mimic joint that follows one (and
    not a mimic joint of a mimic joint)."""
    where, movable, listed = tree.where, tree.movable, set(arm) | set(hand)
    for joint in movable.values():
        source = joint.mimic[0] if joint.mimic is not None else joint.name
        if source != joint.name and source in movable and movable[source].mimic is not None:
            raise fail(where, "urdf", f"{joint.name!r} mimics {source!r}, itself a mimic joint "
                       f"of {movable[source].mimic[0]!r}: make it mimic that joint in "
                       f"{tree.urdf.name} (a chain of mimic joints is not supported)")
        if source in listed:
            continue
        follows = "" if source == joint.name else f" (it mimics {source!r})"
        if tree.beyond(palm, joint):
            raise fail(where, "hand_joints", f"{joint.name!r} is a movable joint beyond "
                       f"palm_link {palm!r} that is in neither arm_joints nor hand_joints"
                       f"{follows}: list {source!r} in hand_joints, or make palm_link a link "
                       "beyond it")
        raise fail(where, "urdf", f"{joint.name!r} is a movable joint of {tree.urdf.name} in "
                   f"neither arm_joints nor hand_joints{follows}: list {source!r} in one of "
                   "them, or make it a fixed joint in the URDF")


def check_close(data: dict, tree: UrdfTree, hand: tuple[str, ...]) -> dict[str, int]:
    """The ``close`` mapping: hand joint -> +1 or -1, at least one."""
    where = tree.where
    close = {}
    for j, d in check_mapping(data["close"], where, "close").items():
        if j not in hand:
            raise fail(where, "close", f"{j!r} is not one of hand_joints")
        if isinstance(d, bool) or d not in (1, -1):
            raise fail(where, "close", f"{j}: {d!r} is not +1 or -1")
        close[j] = int(d)
    if not close:
        raise fail(where, "close", "give the closing direction of at least one hand joint")
    return close


def check_travel(tree: UrdfTree, close: dict[str, int], opened: dict[str, float],
                  preshapes: tuple[PreshapeDraw, ...]) -> None:
    """A closing joint that no pre-shape draws does not start at the limit it closes
    toward."""
    drawn = {j for draw in preshapes for j in draw.joints}
    for j, d in close.items():
        end = tree.movable[j].upper if d > 0 else tree.movable[j].lower
        if j not in drawn and math.isfinite(end) and d * (end - opened[j]) <= 0.0:
            raise fail(tree.where, "close", f"{j}: {d:+d} closes toward its "
                       f"{'upper' if d > 0 else 'lower'} limit {end:g}, where it opens "
                       f"({opened[j]:g}): no travel; give the other direction, an open value "
                       "away from that limit or a pre-shape")
