"""How each finger of a description robot closes, for the batched closing: its closing joints
and their rates and limits, the joint chain from the palm to each of its links, its speed
bound (:class:`FingerPath`), and the links' poses along the way (:func:`link_poses`, one
chain at a time; :func:`tree_poses`, every link of a finger in one compiled pass from the
palm: the same poses to a few ulps)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kinegrasp_env.closing.link_geometry import LinkGeometry
from kinegrasp_env.robot.description import Finger, RobotDescription
from kinegrasp_env.robot.kinematics import Kinematics, axis_angle_matrix
from kinegrasp_env.robot.model import RobotModel
from kinegrasp_env.robot.touch_rule import moved_by, touch_stops

__all__ = ["FingerPath", "closing_joints", "finger_paths", "joint_tree", "link_poses",
           "link_speeds", "net_levers", "net_speeds", "palm_tree", "parallel_signs",
           "tree_poses"]


@dataclass(frozen=True)
class FingerPath:
    """One finger's closing by its parameter t: closing joint j at its pre-shape value plus
    ``rates[j] * t``, clipped to [lower[j], upper[j]].

    Attributes:
        joints: the closing joints' names (J,).
        rates: (J,) d(joint value)/dt (the mimic multiplier times the close direction).
        lower, upper: (J,) the joints' limits (metres or radians).
        links: the finger's links with collision geometry.
        chains: link -> the joints from the palm to it, palm first.
        speeds: (K, J) bound on the speed (metres per unit t) that closing joint j gives any
            point of link k while it turns (:func:`link_speeds`): a link's bound while the
            joints ``turning`` (J,) bool turn is ``speeds @ turning``, unless ``net`` gives
            one (:meth:`speed_bounds`).
        translating: every closing joint is prismatic (the links translate).
        moves: (K, J) bool, link k (of ``links``) moves with closing joint j.
        stops: (K, J) bool, joint j stops when link k touches
            (:func:`~kinegrasp_env.robot.touch_rule.touch_stops`).
        tree: the finger's links' kinematics from the palm frame: every joint of their
            chains, each movable one an independent coordinate (:func:`palm_tree`).
        net: (J,) or None: for a finger whose closing joints turn about parallel axes, some
            one way and some the other (a linkage whose bar keeps its orientation), each
            joint's rate signed along the first joint's axis; the links' speeds then come
            from the net turning (:func:`net_speeds`), which depends on which joints turn,
            so a step must not pass a joint's limit (:meth:`turning`). None: the sum of
            ``speeds`` (their bound whatever subset of the joints turns).
        levers: (K, J) with ``net``: the weights of :func:`net_speeds` (metres).
    """

    joints: tuple[str, ...]
    rates: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    links: tuple[str, ...]
    chains: dict[str, list]
    speeds: np.ndarray
    translating: bool
    moves: np.ndarray
    stops: np.ndarray
    tree: Kinematics
    net: np.ndarray | None = None
    levers: np.ndarray | None = None

    def limit_times(self, v0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(starts, ends), each (..., J): the t at which each closing joint, from its
        pre-shape values ``v0`` (..., J), comes within its limits and the t at which it
        reaches the limit it closes towards (0 where it is there already). A joint moves
        only between the two: its value is clipped to its limits, and a mimic joint may
        start outside its own."""
        rates = self.rates
        with np.errstate(divide="ignore", invalid="ignore"):
            ends = np.where(rates > 0, (self.upper - v0) / rates,
                            np.where(rates < 0, (self.lower - v0) / rates, 0.0))
            starts = np.where(rates > 0, (self.lower - v0) / rates,
                              np.where(rates < 0, (self.upper - v0) / rates, 0.0))
        return np.maximum(starts, 0.0), np.maximum(ends, 0.0)

    def turning(self, held: np.ndarray, t, starts: np.ndarray, ends: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Which closing joints turn now and for how long the links' speed bound holds, of
        one draw or n: ``held`` (..., J) the t at which each joint stopped (inf: not
        stopped), ``t`` (...) the draws' parameter, ``starts``, ``ends`` (..., J):
        :meth:`limit_times`. Returns (turning (..., J) bool, room (...): how far t may go
        before a joint starts or stops turning; inf where that does not change the bound).
        A staged finger's least step (:data:`~kinegrasp_env.closing.close_rules.STEP`) may
        pass it, as it may pass any bound: a step that leaves a link too deep is halved."""
        turning = np.isinf(held)
        if self.net is None:  # the sum of the joints' bounds holds for any subset
            return turning, np.full(turning.shape[:-1], np.inf)
        t = np.asarray(t)[..., None]
        waiting = turning & (t < starts)
        turning &= (starts <= t) & (t < ends)
        events = np.where(turning, ends - t, np.where(waiting, starts - t, np.inf))
        return turning, np.min(events, axis=-1)

    def speed_bounds(self, turning: np.ndarray) -> np.ndarray:
        """(..., K) bound on the speed (metres per unit t) of any point of each link while
        the joints ``turning`` (..., J) bool turn (and the others stand still)."""
        if self.net is None:
            return turning.astype(float) @ self.speeds.T
        return net_speeds(self.net, self.levers, turning)


def link_speeds(kinds: list[str], rates: np.ndarray, reach: np.ndarray,
                carries: np.ndarray) -> np.ndarray:
    """(K, J) bound (metres per unit t) on the speed closing joint j gives a point of link k.

    Args:
        kinds: per closing joint, its URDF type.
        rates: (J,) d(joint value)/dt of each closing joint (the mimic multiplier times the
            close direction).
        reach: (K, J) metres: a bound on the distance from joint j's origin to any point of
            link k (:func:`finger_paths`).
        carries: (K, J) bool: joint j moves link k (0 speed elsewhere).

    A prismatic joint moves the links it carries at |rate|; a revolute one at |rate| times
    the point's distance from its axis, at most ``reach`` (a bound that holds at every joint
    value: a point's distance from the joint's origin is at most the lengths of the joint
    origins after it and the point's distance from its own link's origin). Each joint adds
    its own velocity to a point's, so the sum over the joints turning bounds its speed.
    """
    prismatic = np.array([kind == "prismatic" for kind in kinds], dtype=bool)
    return np.where(carries, np.abs(rates)[None, :] * np.where(prismatic[None, :], 1.0, reach),
                    0.0)


def net_speeds(net: np.ndarray, levers: np.ndarray, turning: np.ndarray) -> np.ndarray:
    """(..., K) bound (metres per unit t) on the speed of any point of link k of a finger
    whose closing joints turn about parallel axes, the joints ``turning`` (..., J) bool at
    signed rates ``net`` (J,) (each joint's rate times the sign of its axis along the first
    one's), the others still.

    A point p of link k moves at a x sum_j w_j (p - o_j), o_j a point on joint j's axis a
    (the joint's frame origin) and w_j its signed rate: the links turn at the net rate of the
    joints before them. Along the chain o_0, o_1, ..., o_last, c (link k's origin), p,
    sum_j w_j (p - o_j) = sum_i C_i (o_{i+1} - o_i) + C_last (p - o_last), C_i the sum of
    the w_j of the joints up to i; so the speed is at most sum_i |C_i| times the segment's
    length bound, which ``levers`` (K, J) holds (:func:`net_levers`). Where every w_j has
    one sign this is the sum of the joints' own bounds (:func:`link_speeds`); for a
    four-bar linkage whose bar keeps its orientation (w = 1, -1) it is the bar's own
    speed, the crank's length.
    """
    return np.abs(np.cumsum(turning * net, axis=-1)) @ levers.T


def net_levers(reach: np.ndarray, carries: np.ndarray) -> np.ndarray:
    """(K, J) the weights of :func:`net_speeds`: for link k and its carrying joints i (the
    first ones of the finger: its chain is the finger's, palm to tip), the length bound of
    the segment from joint i's axis to the next one's (``reach[k, i] - reach[k, i + 1]``),
    and for the last, the reach from its axis to any point of the link; 0 elsewhere."""
    levers = np.zeros(reach.shape)
    for k, row in enumerate(carries):
        count = int(row.sum())
        levers[k, :count - 1] = reach[k, :count - 1] - reach[k, 1:count]
        levers[k, count - 1] = reach[k, count - 1]
    return levers


def parallel_signs(chain: list, joints: tuple[str, ...]) -> np.ndarray | None:
    """(J,) +1 or -1: each closing joint's axis along the first one's, where every closing
    joint (``joints``) on ``chain`` (the joints from the palm to the finger's last link) is
    revolute about an axis parallel to the first one's and only fixed joints lie between
    them; else None. A closing joint turning about its own axis keeps a parallel axis
    after it parallel, so the check at the zero configuration holds at every one."""
    names = [joint.name for joint in chain]
    if any(name not in names for name in joints):
        return None
    first = names.index(joints[0])
    rotation, axis0, signs = np.eye(3), None, []
    for joint in chain[first:]:
        rotation = rotation @ joint.origin[:3, :3]
        if joint.name in joints:
            if joint.kind not in ("revolute", "continuous"):
                return None
            axis = rotation @ joint.axis
            axis0 = axis if axis0 is None else axis0
            if np.linalg.norm(np.cross(axis, axis0)) > 1e-9:
                return None
            signs.append(1.0 if axis @ axis0 > 0 else -1.0)
        elif joint.movable:
            return None
    return np.array(signs)


def _offset_bound(joint) -> float:
    """A bound (metres) on how far a joint puts its child frame from its parent's: its
    origin's offset, and a prismatic joint's travel (its limits', where finite) besides."""
    offset = float(np.linalg.norm(joint.origin[:3, 3]))
    travel = max(abs(joint.lower), abs(joint.upper))
    if joint.kind == "prismatic" and np.isfinite(travel):
        offset += travel
    return offset


def closing_joints(description: RobotDescription, finger: Finger
                   ) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray]:
    """(kinds, rates (J,), lower (J,), upper (J,)) of a finger's closing joints: each one's
    URDF type, d(value)/dt (the mimic multiplier times its driver's close direction) and
    limits (metres or radians)."""
    model = description.model
    drivers = model.drivers()
    kinds, rates, lower, upper = [], [], [], []
    for name in finger.joints:
        joint = model.joint(name)
        driver, mult, _ = drivers[name]
        kinds.append(joint.kind)
        rates.append(mult * description.close[model.actuated[driver]])
        lower.append(joint.lower)
        upper.append(joint.upper)
    return kinds, np.array(rates), np.array(lower), np.array(upper)


def finger_paths(description: RobotDescription, geometry: dict[str, LinkGeometry],
                 kinematics: Kinematics) -> list[FingerPath]:
    """Every finger's :class:`FingerPath` (its links: those of ``geometry``, link name ->
    collision geometry; ``kinematics``: the robot's, whose chains from the base give those
    from the palm)."""
    model = description.model
    palm = len(kinematics.chain(description.palm_link))
    out = []
    for finger in description.fingers:
        kinds, rates, lower, upper = closing_joints(description, finger)
        links = tuple(link for link in finger.links if link in geometry)
        chains = {link: kinematics.chain(link)[palm:] for link in links}
        reach = np.zeros((len(links), len(finger.joints)))
        carries = np.zeros(reach.shape, dtype=bool)
        for k, link in enumerate(links):  # the largest distance from joint j to link k
            names = [j.name for j in chains[link]]
            extent = float(np.linalg.norm(geometry[link].extent_points, axis=1).max())
            for j, name in enumerate(finger.joints):
                if name in names:
                    carries[k, j] = True
                    reach[k, j] = extent + sum(_offset_bound(joint)
                                               for joint in chains[link][names.index(name) + 1:])
        rows = [finger.links.index(link) for link in links]
        signs = parallel_signs(chains[links[-1]], finger.joints) if links else None
        net = None if signs is None else rates * signs
        mixed = (net is not None and (net > 0).any() and (net < 0).any()
                 and all(row[:row.sum()].all() for row in carries))  # palm to tip
        out.append(FingerPath(tuple(finger.joints), rates, lower, upper, links, chains,
                              link_speeds(kinds, rates, reach, carries),
                              all(kind == "prismatic" for kind in kinds),
                              moved_by(finger)[rows], touch_stops(model, finger)[rows],
                              palm_tree(description, chains),
                              net if mixed else None,
                              net_levers(reach, carries) if mixed else None))
    return out


def palm_tree(description: RobotDescription, chains: dict[str, list]) -> Kinematics:
    """The kinematics of the links of ``chains`` (link -> its joints from the palm) rooted
    at the palm link (:func:`joint_tree`): :meth:`~kinegrasp_env.robot.kinematics.
    Kinematics.forward` of the joint values gives each link's pose in the palm frame in one
    compiled pass."""
    used = {j.name for chain in chains.values() for j in chain}
    return joint_tree(description.model, description.palm_link, used)


def joint_tree(model: RobotModel, root: str, used: set[str] | None = None) -> Kinematics:
    """The kinematics, rooted at link ``root``, of a model of the joints named in ``used``
    (default: every joint; topological order kept) whose every movable joint is an
    independent coordinate (mimic couplings dropped: a closing sets each joint's value
    itself); its coordinates are ``tree.model.actuated``."""
    joints = tuple(dataclasses.replace(j, mimic=None) for j in model.joints
                   if used is None or j.name in used)
    return Kinematics(RobotModel(f"{model.name}:{root}", root, joints,
                                 tuple(j.name for j in joints if j.movable), model.urdf_path))


def tree_poses(tree: Kinematics, palm: np.ndarray, values: dict[str, np.ndarray],
               links: tuple[str, ...]) -> dict[str, np.ndarray]:
    """Object-frame poses (n, 4, 4) of ``links`` from the palm's object-frame poses
    (n, 4, 4) and the joint values (name -> (n,)) of the tree's coordinates
    (:func:`palm_tree`): :func:`link_poses` of each link, from one compiled pass."""
    coordinates = np.stack([values[name] for name in tree.model.actuated], axis=1)
    relative = tree.forward(coordinates, links)
    return {link: palm @ relative[link] for link in links}


def link_poses(palm: np.ndarray, values: dict[str, np.ndarray], chain: list) -> np.ndarray:
    """(n, 4, 4) object-frame pose of the link at the end of ``chain`` (joints from the palm)
    from the palm's (n, 4, 4) object-frame pose and the joint values (name -> (n,))."""
    pose = palm
    for joint in chain:
        step = np.broadcast_to(joint.origin, pose.shape).copy()
        if joint.movable:
            v = values[joint.name]
            if joint.kind == "prismatic":
                step[:, :3, 3] += (joint.origin[:3, :3] @ joint.axis) * v[:, None]
            else:
                step[:, :3, :3] = joint.origin[:3, :3] @ axis_angle_matrix(joint.axis, v)
        pose = pose @ step
    return pose
