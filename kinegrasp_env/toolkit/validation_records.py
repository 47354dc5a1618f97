"""What a validation run draws and keeps: its settings (:class:`ValidationSettings`) and
one grasp's per-draw results (:class:`GraspDraws`: the kinematic and the physics closing's
outcomes and Q, the holding test's outcome, phases and the grip's shift), cached as ``.npz``
files by :func:`~kinegrasp_env.toolkit.validation.run_validation`."""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from kinegrasp_env.montecarlo.draws import FORCE_CLOSURE
from kinegrasp_env.montecarlo.hold_batch import HoldBatch
from kinegrasp_env.physics.protocol import HELD, HoldProtocol
from kinegrasp_env.physics.simulators import check_simulator

KINEMATIC_ENGINES = ("fast", "pybullet")


@dataclass(frozen=True)
class ValidationSettings:
    """What a validation run draws and scores.

    Attributes:
        sigma: joint noise on the robot's arm joints, radians; samples: draws per grasp.
        seed: the draws' seed (the same draws as ``evaluate`` with this seed).
        friction, num_edges: the quality's friction cone (also the simulated mu).
        kinematic: the kinematic engine, ``fast`` (default) or ``pybullet``.
        simulator: the simulator of the holding test (registered names:
            :data:`~kinegrasp_env.physics.simulators.SIMULATORS`).
        torque_scale: multiplies the torque limits of the hand's joints (the holding
            test's).
        shake: run the shake phase after the lift.
    """

    sigma: float
    samples: int
    seed: int = 0
    friction: float = 0.5
    num_edges: int = 8
    kinematic: str = "fast"
    simulator: str = "pybullet"
    torque_scale: float = 1.0
    shake: bool = False

    def __post_init__(self) -> None:
        if not (np.isfinite(self.sigma) and 0 <= self.sigma <= np.pi):
            raise ValueError(f"sigma must be in [0, pi] radians, got {self.sigma!r}")
        if int(self.samples) != self.samples or self.samples < 1:
            raise ValueError(f"samples must be an integer >= 1, got {self.samples!r}")
        if self.kinematic not in KINEMATIC_ENGINES:
            raise ValueError(f"kinematic engine must be one of {', '.join(KINEMATIC_ENGINES)}, "
                             f"got {self.kinematic!r}")
        check_simulator(self.simulator)
        self.protocol  # noqa: B018 - checks torque_scale

    @property
    def protocol(self) -> HoldProtocol:
        """The holding protocol of these settings."""
        return HoldProtocol(shake=bool(self.shake), torque_scale=float(self.torque_scale))


#: The kinematic and physics closing's arrays of :class:`GraspDraws`.
CLOSING_ARRAYS = ("kin_outcome", "kin_quality", "phys_outcome", "phys_quality")
#: The holding test's arrays of :class:`GraspDraws`: name -> the field of
#: :class:`~kinegrasp_env.montecarlo.hold_batch.HoldBatch` it is.
HOLD_ARRAYS = {("hold_outcome" if f == "outcome" else f): f for f in HoldBatch.FIELDS}
#: Every array of :class:`GraspDraws`, in the order :meth:`GraspDraws.from_arrays` takes them.
ARRAYS = CLOSING_ARRAYS + tuple(HOLD_ARRAYS)


@dataclass
class GraspDraws:
    """One grasp's draws.

    Attributes:
        object, index, id: the grasp (index in its set, id in its file).
        kin_outcome, phys_outcome: (n,) int8 outcome indices (``OUTCOMES``) of the kinematic
            and the physics closing (the holding test's, object pinned); kin_quality,
            phys_quality: (n,) their Q.
        hold: the holding test (outcome index into ``HOLD_OUTCOMES``; phases in ``PHASES``
            order, 1 held, 0 failed, -1 not run); its arrays are attributes of the draws too
            (:data:`HOLD_ARRAYS`: ``hold_outcome`` is ``hold.outcome``, ``grip_shift`` ...
            ``phase_turn`` the same names).
    """

    object: str
    index: int
    id: str
    kin_outcome: np.ndarray
    kin_quality: np.ndarray
    phys_outcome: np.ndarray
    phys_quality: np.ndarray
    hold: HoldBatch

    @classmethod
    def from_arrays(cls, object: str, index: int, id: str, *arrays: np.ndarray) -> GraspDraws:
        """The draws of a grasp from its arrays in :data:`ARRAYS` order."""
        if len(arrays) != len(ARRAYS):
            raise ValueError(f"expected {len(ARRAYS)} arrays ({', '.join(ARRAYS)}), "
                             f"got {len(arrays)}")
        closing = len(CLOSING_ARRAYS)
        return cls(object, index, id, *arrays[:closing], HoldBatch(*arrays[closing:]))

    def __getattr__(self, name: str):
        if name in HOLD_ARRAYS:  # only names of the holding test (no recursion on "hold")
            return getattr(self.hold, HOLD_ARRAYS[name])
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def held(self) -> np.ndarray:
        """(n,) bool: the draw's holding outcome is ``held`` (grip stood, every phase run
        held)."""
        return self.hold_outcome == HELD

    @property
    def kin_fc(self) -> np.ndarray:
        return self.kin_outcome == FORCE_CLOSURE

    @property
    def phys_fc(self) -> np.ndarray:
        return self.phys_outcome == FORCE_CLOSURE

    def to_bytes(self) -> bytes:
        buffer = io.BytesIO()
        np.savez(buffer, object=self.object, index=self.index, id=self.id,
                 **{name: getattr(self, name) for name in ARRAYS})
        return buffer.getvalue()

    def __len__(self) -> int:
        return int(self.hold_outcome.size)

    @classmethod
    def from_file(cls, path: Path, samples: int) -> GraspDraws:
        """The first ``samples`` draws cached in ``path`` (all of them if it holds fewer)."""
        with np.load(path) as data:
            return cls.from_arrays(str(data["object"]), int(data["index"]), str(data["id"]),
                                   *(data[name][:samples] for name in ARRAYS))

    def extended(self, more: GraspDraws) -> GraspDraws:
        """These draws followed by ``more`` (the next draws of the same grasp)."""
        return GraspDraws.from_arrays(
            self.object, self.index, self.id,
            *(np.concatenate([getattr(self, n), getattr(more, n)]) for n in ARRAYS))
