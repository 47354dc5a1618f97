"""A robot as data: a short YAML description next to a URDF, read and checked.

The description names what the URDF cannot say (which joints are the noisy arm, which link
is the palm, which joints close the hand and in which direction); everything else (finger
chains, fingertips, mimic followers, limits) is derived from the URDF through
:func:`kinegrasp_env.robot.model.load_urdf`. Keys::

    name: panda                      # catalog name: a letter or digit, then [A-Za-z0-9_.-]
    urdf: panda.urdf                 # path relative to the YAML file (or absolute)
    arm_joints: [panda_joint1, ...]  # base to flange: the noisy joints, a serial chain
    palm_link: panda_hand            # the hand's frame; the arm chain ends here
    hand_joints: [panda_finger_joint1]  # actuated hand joints (mimic joints follow)
    close: {panda_finger_joint1: -1} # direction (+1 or -1) that closes a hand joint;
                                     # hand joints left out are pre-shape only (a spread)
    open: {panda_finger_joint1: 0.04}  # optional pre-shape (within the joint's limits;
                                     # a joint left out: 0 clipped into its limits)
    finger_links: [...]              # optional: the links that touch (default: every link
                                     # a hand joint moves; the tips then leave out a
                                     # linkage's bars, see linkage_bars)
    efforts: {joint: 20.0}           # optional motor effort overrides, N m or N (> 0)
    contact_model: soft              # optional: point, soft or patch (default: soft
                                     # for a two-finger hand, else point)
    packages: {NAME: path}           # optional: folders for package://NAME/... meshes
    arm_angle_links: [s, e, w]       # optional: shoulder, elbow, wrist links of the arm
                                     # angle (default for 7 arm joints: the links moved by
                                     # arm joints 2, 4 and 6)
    hand_mount: sdh_base             # optional: the link the hand is mounted on, whose frame
                                     # a palm error is given in (a link from the last arm
                                     # joint's child to palm_link; default: that child)
    home: {panda_joint4: -1.6}       # optional: the arm configuration a palm pose's IK and
                                     # studies of the arm alone start from, radians or
                                     # metres (a joint left out: the middle of its range)
    arm_name: Franka arm             # optional: how figures name the arm (default:
                                     # "<name> arm")
    preshapes: [{joints: [...], range: [lo, hi]}]  # optional: the pre-shapes the planners
                                     # draw the open hand from (robot.preshapes)

Mesh paths are resolved as URDF readers do: relative to the URDF's folder, absolute (or
``file://``), or ``package://NAME/rest``: through ``packages`` when it names NAME, else a
folder NAME beside the URDF or beside any folder above it (or a folder above it named NAME).

Every problem is one :class:`RobotDescriptionError` line naming the file, the key and the
bad value, raised before anything is written anywhere.
"""

from __future__ import annotations

import math
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from kinegrasp_env.robot.description_fields import (
    RobotDescriptionError,
    check_arm_angle_links,
    check_efforts,
    check_hand_mount,
    check_names,
    check_packages,
    check_text,
    fail,
    joint_values,
)
from kinegrasp_env.robot.linkage import linkage_bars
from kinegrasp_env.robot.model import RobotModel, load_urdf
from kinegrasp_env.robot.preshapes import PreshapeDraw, check_preshapes, draw_preshapes
from kinegrasp_env.robot.urdf_meshes import (
    MeshFile,
    MeshNotFound,
    collision_links,
    urdf_meshes,
)
from kinegrasp_env.robot.urdf_tree import (
    UrdfTree,
    check_chain,
    check_close,
    check_every_joint_listed,
    check_travel,
)
from kinegrasp_env.spec_yaml import read_spec

#: Robot names: a letter or digit, then letters, digits, ``_``, ``-``, ``.`` (64 at most).
NAME_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]{0,63}$")
REQUIRED_KEYS = ("name", "urdf", "arm_joints", "palm_link", "hand_joints", "close")
OPTIONAL_KEYS = ("open", "finger_links", "efforts", "contact_model", "packages",
                 "arm_angle_links", "hand_mount", "home", "arm_name", "preshapes")
CONTACT_MODELS = ("point", "soft", "patch")


@dataclass(frozen=True)
class Finger:
    """One finger: the chain from the palm to a fingertip link.

    Attributes:
        tip: the fingertip link (a leaf of the finger links; with ``finger_links`` derived,
            not a linkage's bar: :func:`~kinegrasp_env.robot.linkage.linkage_bars`).
        joints: the closing joints on the chain, palm to tip (hand joints with a close
            direction and the mimic joints that follow them).
        links: the child link of each of ``joints``.
        directions: for each of ``joints``, +1 or -1: the sign of the joint's motion when
            the hand closes (the driver's close direction times the mimic multiplier's sign).
    """

    tip: str
    joints: tuple[str, ...]
    links: tuple[str, ...]
    directions: tuple[int, ...]


@dataclass(frozen=True)
class RobotDescription:
    """A checked robot description (see the module docstring for the keys).

    ``model`` is the URDF's :class:`~kinegrasp_env.robot.model.RobotModel` with the actuated
    vector ``arm_joints + hand_joints``; ``open`` holds a value for every hand joint.
    """

    name: str
    path: Path
    urdf: Path
    model: RobotModel
    arm_joints: tuple[str, ...]
    palm_link: str
    hand_joints: tuple[str, ...]
    close: dict[str, int]
    open: dict[str, float]
    finger_links: tuple[str, ...]
    fingertip_links: tuple[str, ...]
    fingers: tuple[Finger, ...]
    efforts: dict[str, float] = field(default_factory=dict)
    contact_model: str = "point"
    packages: dict[str, Path] = field(default_factory=dict)
    arm_angle_links: tuple[str, str, str] | None = None
    meshes: tuple[MeshFile, ...] = ()
    hand_mount: str = ""
    home: dict[str, float] = field(default_factory=dict)
    arm_name: str = ""
    preshapes: tuple[PreshapeDraw, ...] = ()

    @property
    def flange_link(self) -> str:
        """The link a palm error is relative to: ``hand_mount``, by default the child of the
        last arm joint."""
        return self.hand_mount or self.model.joint(self.arm_joints[-1]).child

    @property
    def quality_model(self) -> str:
        """The contact model each contact given to the quality is scored with: ``soft`` for
        the patch model (its contacts come as the patches' corners and rounded fingertips'
        points, each a point contact: torsion 0, and as flat pads' contacts off a face, each
        a soft contact), else :attr:`contact_model`."""
        return "soft" if self.contact_model == "patch" else self.contact_model

    @property
    def arm_dof(self) -> int:
        return len(self.arm_joints)

    @property
    def has_self_motion(self) -> bool:
        """Whether the arm moves along a self-motion with the palm held: 7 arm joints and
        ``arm_angle_links`` (its elbow angle)."""
        return self.arm_dof == 7 and self.arm_angle_links is not None

    def home_arm(self):
        """(arm_dof,) the arm's ``home`` configuration, base to flange (radians or metres)."""
        import numpy as np

        return np.array([self.home[j] for j in self.arm_joints])

    def open_configuration(self):
        """(dof,) actuated vector: arm at zero, hand at its ``open`` pre-shape."""
        import numpy as np

        return np.array([0.0] * self.arm_dof + [self.open[j] for j in self.hand_joints])

    def drawn_configurations(self, rng, n: int):
        """(n, dof) actuated vectors: arm at zero, the hand at pre-shapes drawn from
        ``preshapes`` (:func:`~kinegrasp_env.robot.preshapes.draw_preshapes`; every row the
        ``open`` pre-shape, drawing nothing, when there are none)."""
        import numpy as np

        out = np.zeros((n, self.arm_dof + len(self.hand_joints)))
        out[:, self.arm_dof:] = draw_preshapes(self.hand_joints, self.open_configuration()[
            self.arm_dof:], self.preshapes, rng, n)
        return out


def load_description(path: str | Path, *,
                     fixed_pads: list[tuple[str, str]] | None = None) -> RobotDescription:
    """Read and check a robot description YAML file.

    ``fixed_pads``: a list to collect (pad, finger link) into, one per link with collision
    geometry fixed below a link a closing joint moves (:func:`check_fixed_pads`), instead of
    refusing the description (only the check that every finger has collision geometry counts
    the pads' shapes as those links'; the description read still names the URDF as it is,
    whose closings ignore the pads: ``robots add`` moves them first).

    Raises:
        RobotDescriptionError: one line naming the file, the key and the bad value.
    """
    path = Path(path)
    where = path.name
    try:
        data = read_spec(path)
    except ValueError as exc:
        raise RobotDescriptionError(str(exc)) from None
    if not isinstance(data, dict):
        raise RobotDescriptionError(f"{where}: expected a mapping of keys, got {data!r}")
    return parse_description(data, path, fixed_pads=fixed_pads)


def parse_description(data: dict, path: Path, *,
                      fixed_pads: list[tuple[str, str]] | None = None) -> RobotDescription:
    """Check the mapping ``data`` read from the file ``path`` (relative paths start at its
    folder); see :func:`load_description`."""
    where = path.name
    name, urdf, model = _check_header(data, where, path)
    tree = UrdfTree(model, urdf, where)
    arm, palm, hand, path_links = check_chain(data, tree)
    check_every_joint_listed(tree, arm, hand, palm)
    close = check_close(data, tree, hand)
    opened = joint_values(data, where, "open", hand, tree.movable,
                          lambda lo, hi: min(max(0.0, lo), hi))
    finger_links, tips, fingers = _fingers(data, tree, palm, hand, close)
    check_fixed_pads(tree, fingers, "finger_links" in data, fixed_pads)
    efforts = check_efforts(data, where, tree.movable)
    contact_model = data.get("contact_model", default_contact_model(len(fingers)))
    if contact_model not in CONTACT_MODELS:
        raise fail(where, "contact_model", f"{contact_model!r} is not one of "
                   f"{', '.join(CONTACT_MODELS)}")
    packages = check_packages(data, where, path.parent)
    angle_links = check_arm_angle_links(data, where, arm, tree.movable, path_links)
    mount = check_hand_mount(data, where, path_links, tree.movable[arm[-1]].child)
    home = joint_values(data, where, "home", arm, tree.movable,
                        lambda lo, hi: 0.5 * (lo + hi))
    arm_name = check_text(data, where, "arm_name", f"{name} arm")
    preshapes = check_preshapes(data, where, hand, tree.movable)
    check_travel(tree, close, opened, preshapes)
    try:
        meshes = urdf_meshes(urdf, packages)
    except MeshNotFound as exc:
        raise fail(where, exc.key, str(exc)) from None
    return RobotDescription(name, path.resolve(), urdf, load_urdf(urdf, actuated=arm + hand),
                            arm, palm, hand, close, opened, finger_links, tips, tuple(fingers),
                            efforts, contact_model, packages, angle_links, meshes, mount, home,
                            arm_name, preshapes)


def _check_header(data: dict, where: str, path: Path) -> tuple[str, Path, RobotModel]:
    """(name, the URDF's resolved path, its model): the keys known and the required ones
    given, a valid name, a URDF file that loads."""
    unknown = [k for k in data if k not in REQUIRED_KEYS + OPTIONAL_KEYS]
    if unknown:
        raise fail(where, str(unknown[0]), f"unknown key (known: "
                   f"{', '.join(REQUIRED_KEYS + OPTIONAL_KEYS)})")
    missing = [k for k in REQUIRED_KEYS if k not in data]
    if missing:
        raise fail(where, missing[0], "missing (required)")
    name = data["name"]
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise fail(where, "name", f"{name!r} is not a valid name (a letter or digit, then "
                   "letters, digits, _ - .; 64 at most)")
    if not isinstance(data["urdf"], str) or not data["urdf"]:
        raise fail(where, "urdf", f"expected a file path, got {data['urdf']!r}")
    urdf = (path.parent / data["urdf"]).resolve()
    if not urdf.is_file():
        raise fail(where, "urdf", f"{data['urdf']!r}: no such file ({urdf})")
    try:
        model = load_urdf(urdf)
    except (ValueError, ET.ParseError) as exc:
        raise fail(where, "urdf", f"{data['urdf']!r} is not a usable URDF ({exc})") from None
    return name, urdf, model








def _fingers(data: dict, tree: UrdfTree, palm: str, hand: tuple[str, ...],
             close: dict[str, int]) -> tuple[tuple[str, ...], tuple[str, ...], list[Finger]]:
    """(finger links, fingertips, fingers): ``finger_links`` as given (each moved by a hand
    joint), else every link a hand joint moves, the tips then without a linkage's bars
    (:func:`~kinegrasp_env.robot.linkage.linkage_bars`); each finger the closing joints on
    the path from the palm to its tip, and collision geometry on the links they move."""
    where, driver = tree.where, tree.driver
    hand_links = tree.moved_links(hand)
    if "finger_links" in data:
        finger_links = check_names(data["finger_links"], where, "finger_links")
        for link in finger_links:
            tree.known_link("finger_links", link)
            if link not in hand_links:
                raise fail(where, "finger_links", f"{link!r} is not moved by any of "
                           "hand_joints")
    else:
        finger_links = tuple(hand_links)
    parents = {tree.by_child[link].parent for link in finger_links}
    tips = tuple(link for link in finger_links if link not in parents)
    if "finger_links" not in data:  # derived: a linkage's bars are no fingertips
        bars = linkage_bars({tip: [j.name for j in tree.path_joints(palm, tip) if j.movable]
                             for tip in tips}, {j: driver[j][0] for j in driver})
        tips = tuple(tip for tip in tips if tip not in bars)
    fingers = []
    for tip in tips:
        on_path = tree.path_joints(palm, tip)
        closing = [j for j in on_path if j.movable and driver[j.name][0] in close]
        if not closing:
            drivers = dict.fromkeys(driver[j.name][0] for j in on_path
                                    if j.movable and driver[j.name][0] in hand)
            raise fail(where, "close", f"the finger ending at {tip!r} has no closing joint: "
                       f"give {' or '.join(map(repr, drivers))} a close direction")
        fingers.append(Finger(tip, tuple(j.name for j in closing),
                              tuple(j.child for j in closing),
                              tuple(int(close[driver[j.name][0]]
                                        * math.copysign(1.0, driver[j.name][1]))
                                    for j in closing)))
    return finger_links, tips, fingers


def check_fixed_pads(tree: UrdfTree, fingers: list[Finger], named: bool,
                     found: list[tuple[str, str]] | None = None) -> None:
    """Links with collision geometry fixed below a link a closing joint moves (a pad on a
    fixed joint, as Robotiq-style URDFs have): a finger touches the object with the links
    its closing joints move, so such a pad's shapes would never touch. Refused, naming the
    pad and the link to give its shapes to; or, with a list ``found``, each appended as
    (pad, finger link) and that link counted as touching (``robots add`` then moves the
    shapes onto it in its copy of the URDF:
    :func:`~kinegrasp_env.robot.fixed_collisions.move_fixed_collisions`). Then every finger
    must touch with some link (``named``: the description names its ``finger_links``)."""
    where = tree.where
    touching = set(collision_links(tree.urdf))
    for finger in fingers:  # the links a finger's closing moves are the ones that touch
        for link in finger.links:
            for pad, joint in tree.fixed_below(link):
                if pad not in touching:
                    continue
                if found is None:
                    raise fail(where, "urdf", f"link {pad!r} has collision geometry and is "
                               f"fixed (joint {joint.name!r}) to {link!r}, which a closing "
                               "joint moves; a finger touches the object with the links its "
                               f"closing joints move: give {link!r} {pad!r}'s collision "
                               f"shapes in {tree.urdf.name} (and drop them from {pad!r}; "
                               "`kinegrasp robots add` does so in its copy)")
                found.append((pad, link))
                touching.add(link)
        if not touching.intersection(finger.links):
            raise fail(where, "finger_links" if named else "urdf",
                       f"the finger ending at {finger.tip!r} has no collision geometry on "
                       f"the links its closing joints move ({', '.join(finger.links)} in "
                       f"{tree.urdf.name}): a finger closes until their collision shapes "
                       "touch the object")


def never_in_force_closure(description: RobotDescription) -> str | None:
    """Why ``description``'s hand can never be in force closure, or None. A closing gives one
    contact per touching finger link (a link a closing joint moves, with collision
    geometry): fewer than two contacts push the object one way; two point contacts resist
    no torque about the line between them."""
    touching = collision_links(description.urdf)
    contacts = sum(len(touching.intersection(f.links)) for f in description.fingers)
    if contacts < 2:
        return (f"a hand whose closing gives {contacts} contact at most is never in force "
                "closure (it pushes the object one way)")
    if contacts == 2 and description.contact_model == "point":
        return ("two point contacts are never in force closure (they resist no torque about "
                "the line between them): give contact_model soft or patch")
    return None


def default_contact_model(fingers: int) -> str:
    """The contact model of a description that names none: ``soft`` for a two-finger hand
    (point contacts never put two fingers in force closure, and of the models the physics
    benchmark compares on the Panda, soft predicts its holding best:
    docs/guides/physics.md), ``point`` otherwise (the paper's hard fingers)."""
    return "soft" if fingers == 2 else "point"


