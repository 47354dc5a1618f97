"""A noise model's draws for a robot: joints, hand, palm, object and friction.

Draw i of a run with seed s is row i of each source's own rows in the run's chunked streams
(:func:`~kinegrasp_env.sampling.noise_model.stream_rows`; docs/conventions.md): a
joints-only model draws exactly what ``--sigma``/``--noise`` draw, adding or removing a
source never changes another's draws, and a chunk of rows is the same whichever process
draws it.

What each source does (:mod:`~kinegrasp_env.sampling.noise_model`): joint errors on the arm
joints; a hand error offsets the hand's pre-shape (:func:`hand_rows`); a palm error moves
the palm link and every link below it relative to the flange; an object error moves the
object about its centre of mass; friction sets each draw's mu.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.sampling.noise_model import NoiseModel, offset_transforms, stream_rows
from kinegrasp_env.sampling.noise_sources import JOINTS_FIX, HandSource, broadcast


def check_robot_noise(model: NoiseModel, robot: str | RobotDescription, arm_dof: int,
                      engine: str, static_hold: bool = False) -> None:
    """ValueError (one line) for what a robot's run cannot take: a hand source its hand
    cannot take (:func:`check_hand`), a joints source whose per-joint values describe
    another arm than its, palm, object or friction errors in the physics engine, a per-draw
    mu beside the static hold check. ``robot``: the robot, or its catalog name."""
    if model.hand is not None:
        check_hand(model.hand, robot)
    robot = robot if isinstance(robot, str) else robot.name
    joints = model.joints
    if joints is not None and not joints.fits(arm_dof):
        raise ValueError(f"robot {robot!r} has {arm_dof} arm joints; the spec's joints "
                         f"describe {joints.count} ({JOINTS_FIX})")
    check_engine_noise(model, engine)
    if static_hold:
        check_static_hold_noise(model)


def check_engine_noise(model: NoiseModel, engine: str) -> None:
    """ValueError (one line) for palm, object or friction errors given to an engine that
    does not take them (its class's ``takes_errors``: the physics engine simulates at one mu
    and does not split the robot's body), the same for every robot."""
    from kinegrasp_env.montecarlo.engines import engine_class, error_engines

    engine_class(engine)  # an unknown name: its one-line error
    other = [s for s in ("palm", "object", "friction") if getattr(model, s) is not None]
    takers = error_engines()
    if other and engine not in takers:
        raise ValueError(f"the {engine} engine takes joint and hand noise only (it "
                         f"simulates at one mu), not {', '.join(other)} errors (use "
                         f"{' or '.join(takers)})")


def check_static_hold_noise(noise) -> None:
    """ValueError (one line) for a noise model with a friction source beside the static hold
    check (any robot's): the check holds at one mu. Every other source it takes."""
    if isinstance(noise, NoiseModel) and noise.friction is not None:
        raise ValueError("the static hold check holds at one mu (the run's friction, "
                         "--friction); a noise model's friction source sets mu for every "
                         "draw: drop one of them")


def hand_layout(description: RobotDescription) -> np.ndarray:
    """(H,) for each actuated hand joint (the entries of q after the arm's): the finger whose
    closing joints it drives (the first such finger, where one motor drives several), or -1
    where it drives no finger's closing joint (a pre-shape joint such as a spread)."""
    drivers = description.model.drivers()
    arm = description.arm_dof
    out = np.full(description.model.dof - arm, -1)
    for f in reversed(range(len(description.fingers))):  # the first finger's wins
        for name in description.fingers[f].joints:
            out[drivers[name][0] - arm] = f
    return out


def check_hand(hand: HandSource, robot: str | RobotDescription) -> None:
    """ValueError (one line) for a hand source that ``robot``'s hand (the robot, or its
    catalog name) cannot take: a spread sigma where every hand joint closes a finger,
    per-finger closing sigmas of another number than the hand's fingers."""
    if isinstance(robot, str):
        from kinegrasp_env.robot.catalog import load_robot

        description = load_robot(robot)
    else:
        description = robot
    robot = description.name
    layout = hand_layout(description)
    fingers = len(description.fingers)
    if hand.spread_sigma > 0 and not np.any(layout < 0):
        raise ValueError(f"the hand of robot {robot!r} has no pre-shape joint besides its fingers' "
                         "closing joints: drop hand.spread_sigma")
    if np.ndim(hand.closing_sigma) == 1 and len(hand.closing_sigma) not in (1, fingers):
        tips = ", ".join(f.tip for f in description.fingers)
        raise ValueError(f"hand.closing_sigma has {len(hand.closing_sigma)} values; robot "
                         f"{robot!r} has {fingers} fingers ({tips}): give one sigma for them "
                         "all, or one per finger in that order")


def hand_offsets(z: np.ndarray, hand: HandSource, description: RobotDescription
                 ) -> np.ndarray:
    """(n, H) offsets of the actuated hand joints' pre-shape (radians or metres, each joint's
    unit) from standard normals z (n, 1 + fingers): column 0 the spread's, column 1 + f
    finger f's. A joint that drives finger f's closing joints takes ``closing_sigma`` (f's)
    times column 1 + f, every other hand joint ``spread_sigma`` times column 0
    (:func:`hand_layout`)."""
    layout = hand_layout(description)
    scale = np.concatenate([[hand.spread_sigma],
                            broadcast(hand.closing_sigma, len(description.fingers))])
    return z[:, layout + 1] * scale[layout + 1]


def hand_rows(model: NoiseModel, description: RobotDescription, seed: int, offset: int,
              size: int) -> np.ndarray:
    """(size, H) :func:`hand_offsets` of rows ``offset .. offset + size`` of the hand's
    stream (each row 1 + fingers standard normals); zeros without a hand source."""
    hand = model.hand
    if hand is None or hand.exact:
        return np.zeros((size, description.model.dof - description.arm_dof))
    fingers = len(description.fingers)
    z = stream_rows(seed, "hand", offset, size,
                    lambda generator, rows: generator.standard_normal((rows, 1 + fingers)))
    return hand_offsets(z, hand, description)


def with_hand(q: np.ndarray, offsets: np.ndarray, description: RobotDescription
              ) -> np.ndarray:
    """Configurations q (n, dof) with the hand's pre-shape offset by ``offsets`` (n, H),
    clipped to the hand joints' limits (a new array)."""
    arm, model = description.arm_dof, description.model
    out = np.array(q, dtype=float)
    out[:, arm:] = np.clip(out[:, arm:] + offsets, model.lower[arm:], model.upper[arm:])
    return out


def joint_rows(model: NoiseModel, arm_dof: int, seed: int, offset: int,
               size: int, method: str = "mc") -> np.ndarray:
    """(size, arm_dof) joint errors (radians): rows ``offset .. offset + size`` of the run's
    joint stream, each chunk sampled by ``method`` (zeros without joint noise)."""
    joints = model.joints
    if joints is None or joints.exact:
        return np.zeros((size, arm_dof))
    return stream_rows(seed, "joints", offset, size,
                       lambda generator, rows: joints.sample(generator, rows, arm_dof,
                                                            method))


def model_rows(model: NoiseModel, q0: np.ndarray, description: RobotDescription, seed: int,
               offset: int, size: int, center: np.ndarray, method: str = "mc"
               ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """(configurations (size, dof): q0 (dof,) with :func:`joint_rows` on its arm joints and
    :func:`hand_rows` on its hand's pre-shape (clipped to the joints' limits),
    :func:`error_rows`) of rows ``offset .. offset + size``; ``method`` samples the joints
    (the other sources are plain Monte Carlo)."""
    arm = description.arm_dof
    q = np.repeat(np.asarray(q0, dtype=float)[None], size, axis=0)
    q[:, :arm] += joint_rows(model, arm, seed, offset, size, method)
    if model.hand is not None:
        q = with_hand(q, hand_rows(model, description, seed, offset, size), description)
    return q, error_rows(model, seed, offset, size, center)


def error_rows(model: NoiseModel, seed: int, offset: int, size: int,
               center: np.ndarray) -> dict[str, np.ndarray]:
    """The per-draw errors of rows ``offset .. offset + size`` as a robot engine's ``run``
    takes them: ``palm`` and ``object_offset`` (size, 4, 4) (the object's rotating about
    ``center`` (3,), its centre of mass), ``friction`` (size,); only the sources present."""
    out = {}
    for source, key in (("palm", "palm"), ("object", "object_offset")):
        pose = getattr(model, source)
        if pose is not None and not pose.exact:
            rows = stream_rows(seed, source, offset, size, pose.sample)
            out[key] = offset_transforms(rows, center if source == "object" else (0, 0, 0))
    if model.friction is not None:
        out["friction"] = stream_rows(seed, "friction", offset, size, model.friction.sample)
    return out
