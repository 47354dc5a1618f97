"""The holding test, simulator-independent: its phases, thresholds, assumptions and results.

Every simulator runs the same protocol on one draw (the hand at the draw's flange pose, the
fingers at the grasp's pre-shape), step by step:

1. **closing**, the object held fixed (a constraint pins it where the catalog places it): the
   finger motors close the hand until the joints stall (the simulator's closing controller);
   the contacts give the draw's physics outcome and Q, as in the kinematic closing, whose
   object never moves either;
2. **grip**, the object still fixed, gravity off: the fingers press with contact forces in
   equilibrium (:mod:`~kinegrasp_env.physics.grip_forces`). From the closing's contacts one
   linear programme gives contact forces inside the friction cones (mu times the smallest
   of 0.2, 0.3, ..., 1 that allows a solution) whose net force and torque on the object are
   zero, with joint torques tau = J^T f between zero and the torque limits, the smallest
   normal force as large as possible; none (or fewer than two fingers touching): the draw
   ends as ``no_grip``. The spread joints stay held as the closing held them. Each flexion joint
   with a contact on its link or beyond is then a spring towards its stall angle plus the
   angle that moves its finger's tip by ``grip_advance``, as stiff as makes it press with its
   balanced torque at the stall angle, capped at its torque limit; the other joints are held
   where they stalled. The object held by internal forces alone, releasing the pin should
   not move it; a finger it gives way to follows it for ``grip_advance``, pressing less.
   The grip runs until the contact forces are steady (each finger's total normal force
   changes by less than ``steady_change`` relative, or ``steady_floor`` newtons, over
   ``steady_window``, twice in a row; at least ``grip_min_time``, at most
   ``grip_max_time``). A finger *presses* when its links' normal forces sum to more than
   ``contact_force``; with fewer than two pressing fingers the draw ends as ``no_grip``;
3. **release**: the pin goes (and any support table with it), gravity still off, and the
   object moves under the grip's own forces only, for ``settle_time``. Its displacement in
   the palm frame from the last pinned instant is the draw's ``grip_shift_mm`` (centre of
   mass, millimetres) and ``grip_turn_deg`` (rotation angle). If fewer than two fingers press
   now, or a finger that pressed at the end of the grip carries ``contact_force`` or less,
   the grip lost a contact: ``grip_lost`` (the grip itself failed; nothing was dropped);
4. **phases**, each from the same post-release state (the reference pose: the object in
   the palm frame then), the grip's joint rule still on:

   * ``rest``: the control, no disturbance (gravity off, the hand still) for ``gravity_time``:
     does the grip alone keep the object where it is? If not, the draw is ``grip_unsteady``
     (the grip, not a disturbance, moved it; the other phases still run and are reported);
   * ``gravity_+x`` ... ``gravity_-z``: gravity of ``gravity`` m/s^2 along each world axis in
     turn (the six-direction test of DexGraspNet and BODex), for ``gravity_time`` each, the
     hand still;
   * ``lift``: gravity along world -z, the hand lifted by ``lift_height`` in ``lift_time``
     (minimum-jerk), then still for ``hold_time`` (:mod:`~kinegrasp_env.physics.motion`);
   * ``shake`` (only with ``shake=True``, right after a held lift): ``shake_time`` at
     ``shake_frequency``, a translation of ``shake_amplitude`` along (0, 1, 1)/sqrt(2) and a
     rotation of ``shake_angle`` about world x through the palm centre, ramped over
     ``ramp_time``.

   A phase *holds* when, at every check (every ``check_interval`` and at its end), the
   object's centre of mass is within ``max_shift`` of the reference and its rotation from
   the reference is within ``max_turn`` (palm frame); a phase stops at its first failed check.

**The quick test** (:data:`QUICK_PROTOCOL`, a score to rank with): the same sequence with
short settle, grip and lift (the lift's peak acceleration kept: its height shrinks with the
square of its time), checks every 5 ms, and ``early_exit``: the test stops at the first failed
phase (the draw is not held), and a phase ends as held once, two checks in a row after 20 ms,
the object moving on at twice its present rate would stay within the criterion to the
phase's end (:func:`~kinegrasp_env.physics.hold_runner.projected_verdict`). A phase still
fails only by the criterion itself. ``benchmarks/quick_hold.py`` measures its agreement with
the full protocol on the same draws and its speed.

The draw's outcome (:data:`HOLD_OUTCOMES`): ``start_collision`` (the closing's), ``no_grip``,
``grip_lost``, ``grip_unsteady`` (the rest phase failed), ``dropped`` (the rest phase held, a
disturbance phase failed), ``held`` (every phase run held).

The hand's motor efforts are its description's (the URDF's ``<limit effort>`` or the
description's ``efforts``: :func:`~kinegrasp_env.physics.hand_motors.motor_efforts`; the
built-in SDH's are stated assumptions, not a data sheet's); ``torque_scale`` multiplies all
of them, so a reader can see how much a conclusion depends on them
(``benchmarks/hold_torque_sensitivity.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: The six gravity phases: name -> unit direction of gravity (world frame).
GRAVITY_PHASES: dict[str, tuple[float, float, float]] = {
    "gravity_+x": (1.0, 0.0, 0.0), "gravity_-x": (-1.0, 0.0, 0.0),
    "gravity_+y": (0.0, 1.0, 0.0), "gravity_-y": (0.0, -1.0, 0.0),
    "gravity_+z": (0.0, 0.0, 1.0), "gravity_-z": (0.0, 0.0, -1.0),
}
#: The control phase: no disturbance.
REST_PHASE = "rest"
#: Every phase, in the order they run.
PHASES: tuple[str, ...] = (REST_PHASE, *GRAVITY_PHASES, "lift", "shake")
#: The outcomes of a draw's holding test.
HOLD_OUTCOMES: tuple[str, ...] = ("start_collision", "no_grip", "grip_lost", "grip_unsteady",
                                  "dropped", "held")
START_COLLISION, NO_GRIP, GRIP_LOST, GRIP_UNSTEADY, DROPPED, HELD = range(len(HOLD_OUTCOMES))


def check_number(name: str, value: float, *, positive: bool) -> None:
    """Raise ValueError unless ``value`` is a finite number > 0 (``positive``) or >= 0."""
    if not (np.isfinite(value) and (value > 0 if positive else value >= 0)):
        rule = "a positive number" if positive else "a number >= 0"
        raise ValueError(f"{name} must be {rule}, got {value!r}")


def check_simulated_friction(friction: float) -> None:
    """ValueError (one line) unless the simulated finger-object mu is a finite number > 0 (at
    mu 0 a simulated grip cannot hold; every physics world refuses it)."""
    check_number("friction", friction, positive=True)


@dataclass(frozen=True)
class HoldProtocol:
    """The holding test's settings (module docstring; metres, seconds, radians, newtons,
    hertz). Frozen: a protocol is a value, hashed into result caches."""

    grip_min_time: float = 0.05
    grip_max_time: float = 0.5
    steady_window: float = 0.02
    steady_change: float = 0.02
    steady_floor: float = 0.02
    contact_force: float = 0.05
    grip_advance: float = 0.0015
    settle_time: float = 0.2
    max_shift: float = 0.02
    max_turn: float = float(np.radians(10.0))
    check_interval: float = 0.01
    gravity: float = 9.81
    gravity_time: float = 0.5
    lift_height: float = 0.10
    lift_time: float = 1.0
    hold_time: float = 1.0
    shake: bool = False
    shake_time: float = 1.5
    shake_frequency: float = 2.0
    shake_amplitude: float = 0.03
    shake_angle: float = float(np.radians(20.0))
    ramp_time: float = 0.25
    torque_scale: float = 1.0
    early_exit: bool = False

    def __post_init__(self) -> None:
        for name in ("grip_max_time", "steady_window", "contact_force", "grip_advance",
                     "max_shift", "max_turn", "check_interval", "gravity_time", "lift_time",
                     "torque_scale"):
            check_number(name, getattr(self, name), positive=True)
        for name in ("grip_min_time", "steady_change", "steady_floor", "settle_time",
                     "gravity", "lift_height", "hold_time", "shake_time", "shake_frequency",
                     "shake_amplitude", "shake_angle", "ramp_time"):
            check_number(name, getattr(self, name), positive=False)
        if self.grip_min_time > self.grip_max_time:
            raise ValueError(f"grip_min_time {self.grip_min_time!r} exceeds grip_max_time "
                             f"{self.grip_max_time!r}")

    @property
    def phases(self) -> tuple[str, ...]:
        """The phases this protocol runs (``shake`` only with ``shake=True``)."""
        return PHASES if self.shake else PHASES[:-1]


#: The quick holding test (module docstring): a ranking score, not the reference protocol.
QUICK_PROTOCOL = HoldProtocol(settle_time=0.02, grip_min_time=0.02, steady_window=0.01,
                              lift_time=0.07, lift_height=0.10 * 0.07 ** 2, hold_time=0.03,
                              grip_max_time=0.25, check_interval=0.005, early_exit=True)


def pose_change(reference: np.ndarray, current: np.ndarray,
                center_of_mass: np.ndarray) -> tuple[float, float]:
    """How far an object moved between two of its poses (4, 4) in one frame (the palm's):
    (distance its centre of mass ``center_of_mass`` (3,) (object frame) moved, metres; the
    angle of the rotation between the two poses, radians)."""
    com = np.append(np.asarray(center_of_mass, dtype=float), 1.0)
    distance = float(np.linalg.norm((current @ com - reference @ com)[:3]))
    relative = reference[:3, :3].T @ current[:3, :3]
    cosine = np.clip((np.trace(relative) - 1.0) / 2.0, -1.0, 1.0)
    return distance, float(np.arccos(cosine))


def within(protocol: HoldProtocol, distance: float, angle: float) -> bool:
    """The holding criterion: moved at most ``max_shift`` metres and ``max_turn`` radians."""
    return distance <= protocol.max_shift and angle <= protocol.max_turn


def pressing(forces: np.ndarray, protocol: HoldProtocol) -> np.ndarray:
    """(3,) bool: the fingers whose total normal force (3,) (newtons) exceeds
    ``contact_force``."""
    return np.asarray(forces, dtype=float) > protocol.contact_force


def grip_verdict(before: np.ndarray, after: np.ndarray, protocol: HoldProtocol) -> int:
    """The grip's outcome from the fingers' total normal forces (3,) (newtons) at the end of
    the pinned grip (``before``) and after the release (``after``): :data:`NO_GRIP` (fewer
    than two pressed before), :data:`GRIP_LOST` (fewer than two press after, or a finger that
    pressed before carries ``contact_force`` or less), else :data:`HELD` (the grip stands;
    the phases decide)."""
    was, now = pressing(before, protocol), pressing(after, protocol)
    if was.sum() < 2:
        return NO_GRIP
    if now.sum() < 2 or np.any(was & ~now):
        return GRIP_LOST
    return HELD


def steady(previous: np.ndarray, current: np.ndarray, protocol: HoldProtocol) -> bool:
    """Whether the fingers' total normal forces (3,) changed by at most ``steady_change``
    (relative) or ``steady_floor`` newtons, whichever is larger, over one window."""
    previous, current = np.asarray(previous, float), np.asarray(current, float)
    bound = np.maximum(protocol.steady_change * np.abs(current), protocol.steady_floor)
    return bool(np.all(np.abs(current - previous) <= bound))


@dataclass
class HoldResult:
    """One draw's holding test.

    Attributes:
        outcome: index into :data:`HOLD_OUTCOMES`.
        grip_shift: the object's displacement by the grip after the release, metres (NaN:
            no release: start collision or no grip); grip_turn: its rotation, radians.
        forces_gripped, forces_released: (3,) each finger's total normal force at the end of
            the pinned grip and after the release, newtons (NaN: not reached).
        grip_time: how long the pinned grip ran until steady, seconds (NaN: not reached).
        pin_force, pin_torque: the net force (N) and torque (N m) the grip puts on the
            pinned object at the end of the grip (what the pin holds; not zero even for
            balanced joint torques: the force components the joints do not move, along
            their axes, are the structure's and the pin's to share; NaN: not reached).
        phase_held: phase name -> held, for the phases run (none unless the grip stood).
        phase_shift, phase_turn: phase name -> the largest displacement (m) and rotation (rad)
            from the reference seen in that phase (up to its first failed check).
    """

    outcome: int
    grip_shift: float = float("nan")
    grip_turn: float = float("nan")
    forces_gripped: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    forces_released: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    grip_time: float = float("nan")
    pin_force: float = float("nan")
    pin_torque: float = float("nan")
    phase_held: dict[str, bool] = field(default_factory=dict)
    phase_shift: dict[str, float] = field(default_factory=dict)
    phase_turn: dict[str, float] = field(default_factory=dict)

    @property
    def grip_shift_mm(self) -> float:
        return self.grip_shift * 1e3

    @property
    def held(self) -> bool:
        return self.outcome == HELD


def final_outcome(grip: int, phase_held: dict[str, bool]) -> int:
    """A draw's outcome from its grip verdict (:func:`grip_verdict`) and its phases:
    the grip's failure if it failed, else :data:`GRIP_UNSTEADY` if the rest phase failed,
    else :data:`DROPPED` if any phase failed, else :data:`HELD`."""
    if grip != HELD:
        return grip
    if not phase_held.get(REST_PHASE, True):
        return GRIP_UNSTEADY
    return HELD if all(phase_held.values()) else DROPPED


def hold_margin(phase_held: np.ndarray, phase_shift: np.ndarray, phase_turn: np.ndarray,
                protocol: HoldProtocol) -> np.ndarray:
    """How far each draw got through the holding test, in [0, 1]: a graded holding score.

    ``(k + s) / (P + 1)`` for the P phases the protocol runs (:attr:`HoldProtocol.phases`,
    in :data:`PHASES` order), where k is how many of them the draw held in a row from the
    first, and s = 1 - the largest movement seen in the phases run as a share of its limit
    (displacement over ``max_shift``, rotation over ``max_turn``, whichever is larger),
    clipped to [0, 1]; a movement not recorded (NaN) in a phase that ran counts as past its
    limit. A draw whose grip never stood (no phase ran) scores 0. So every draw that held
    scores at least P / (P + 1) and every other draw at most that: the margin ranks as the
    verdict does and orders the draws within a verdict (held: by how little the object moved;
    not held: by how late it failed, k / (P + 1), as a failed phase's movement passed its
    limit).

    Args:
        phase_held: (n, len(PHASES)) int: 1 held, 0 failed, -1 not run
            (:class:`~kinegrasp_env.montecarlo.hold_batch.HoldBatch`'s).
        phase_shift, phase_turn: (n, len(PHASES)) the largest displacement (metres) and
            rotation (radians) in each phase, NaN where not run.
        protocol: the protocol the draws ran (its phases and limits).

    Returns:
        (n,) the margins.
    """
    count = len(protocol.phases)
    held = np.asarray(phase_held)[:, :count]
    ran = held >= 0
    in_a_row = np.cumprod(held == 1, axis=1).sum(axis=1)
    shift = np.where(ran, np.nan_to_num(np.asarray(phase_shift)[:, :count], nan=np.inf), 0.0)
    turn = np.where(ran, np.nan_to_num(np.asarray(phase_turn)[:, :count], nan=np.inf), 0.0)
    worst = np.maximum(shift.max(axis=1, initial=0.0) / protocol.max_shift,
                       turn.max(axis=1, initial=0.0) / protocol.max_turn)
    margin = (in_a_row + np.clip(1.0 - worst, 0.0, 1.0)) / (count + 1)
    return np.where(ran.any(axis=1), margin, 0.0)
