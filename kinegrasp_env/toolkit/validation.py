"""Does P(FC) predict holding? ``kinegrasp validate``: per grasp, the same noisy draws through
a kinematic engine (force closure as kinegrasp computes it) and the holding test
(:mod:`~kinegrasp_env.physics.protocol`) in a registered simulator: its closing on the pinned
object (the physics outcome and Q), the grip's own displacement of the object after the
release, and the disturbance phases (six gravity directions, the lift, optionally the shake),
each held or not; the same code for every robot.

The draws are those of ``kinegrasp evaluate`` with that seed and sigma (any engine): joint
noise on the robot's arm joints, the hand at its pre-shape
(:func:`~kinegrasp_env.toolkit.validation_draws.grasp_draws`). The kinematic outcome comes
from the ``fast`` engine by default (it agrees with the ``pybullet`` reference draw by draw,
see ``benchmarks/robot_agreement.py``); ``kinematic="pybullet"`` uses the reference. The settings
and the per-draw records are :mod:`~kinegrasp_env.toolkit.validation_records`'.

Each grasp's per-draw results are cached in ``<out>/cache`` under a key of every setting (and
of the robot, the object's version, the physics, motor and lift settings), so an interrupted
run resumes where it stopped.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

from kinegrasp_env.atomic_files import write_atomic
from kinegrasp_env.montecarlo.execution import LocalExecutor
from kinegrasp_env.physics.protocol import HOLD_OUTCOMES, PHASES
from kinegrasp_env.sampling.stats import wilson_interval
from kinegrasp_env.toolkit.progress import Progress
from kinegrasp_env.toolkit.validation_draws import check_settings, grasp_draws, settings_key
from kinegrasp_env.toolkit.validation_records import (
    ARRAYS,
    KINEMATIC_ENGINES,
    GraspDraws,
    ValidationSettings,
)
from kinegrasp_env.world.grasps import Grasp

__all__ = ["ARRAYS", "KINEMATIC_ENGINES", "GraspDraws", "GraspRow", "ValidationSettings",
           "grasp_draws", "run_validation", "settings_key"]

log = logging.getLogger(__name__)


def summary_text(draws: GraspDraws) -> str:
    return (f"{draws.object} grasp {draws.index}: P(FC) kinematic {draws.kin_fc.mean():.2f}, "
            f"physics {draws.phys_fc.mean():.2f}, P(hold) {draws.held.mean():.2f}")


def run_validation(grasps: list[tuple[int, Grasp]], settings: ValidationSettings,
                   out_dir: str | Path, processes: int = 1,
                   progress: bool = False) -> list[GraspDraws]:
    """Every grasp's draws (``grasps``: (index in its set, grasp) pairs of one robot, on
    ``processes`` worker processes: each grasp's draws the same whichever process runs it),
    in the order given; each grasp is read from ``<out_dir>/cache`` when it is there, else
    run (:func:`~kinegrasp_env.toolkit.validation_draws.grasp_draws`) and cached there at
    once (atomically, under its robot, object, index and
    :func:`~kinegrasp_env.toolkit.validation_draws.settings_key`), so a rerun resumes; a
    cached grasp with fewer draws than ``settings.samples`` runs only the missing ones.

    Raises:
        ValueError: grasps of several robots, or settings the robot's holding test cannot
            honour (:func:`~kinegrasp_env.toolkit.validation_draws.check_settings`).
    """
    robots = {g.robot for _, g in grasps}
    if len(robots) > 1:
        raise ValueError(f"the grasps are of several robots: {', '.join(sorted(robots))}")
    for robot in robots:
        check_settings(robot, settings)
    cache = Path(out_dir) / "cache"
    paths = [cache / f"{g.robot}_{g.object}_{i}_{settings_key(g, settings)}.npz"
             for i, g in grasps]
    results: list[GraspDraws | None] = [
        GraspDraws.from_file(p, settings.samples) if p.exists() else None for p in paths]
    todo = [k for k, r in enumerate(results) if r is None or len(r) < settings.samples]
    done = sum(len(r) for r in results if r is not None)
    if done:
        log.info("validate: %d of %d draws read from %s", done,
                 len(grasps) * settings.samples, cache)
    report = Progress("validate", len(grasps) * settings.samples, len(grasps)) \
        if progress else None
    if report is not None and done:
        report.advance(done)
    with LocalExecutor(processes) as executor:
        tasks = [(*grasps[k], settings, 0 if results[k] is None else len(results[k]))
                 for k in todo]
        for position, new in executor.as_completed(grasp_draws, tasks):
            k = todo[position]
            draws = new if results[k] is None else results[k].extended(new)
            write_atomic(paths[k], draws.to_bytes())
            results[k] = draws
            done += len(new)
            if report is not None:
                report.advance(done)
                report.cell_done(summary_text(draws))
    if report is not None:
        report.close()
    return [r for r in results if r is not None]


def phase_counts(draws: GraspDraws, phases: tuple[str, ...] = PHASES) -> dict[str, dict]:
    """Per phase: ``{"run": draws that ran it, "held": of those, held}``."""
    out = {}
    for name in phases:
        column = draws.phase_held[:, PHASES.index(name)]
        out[name] = {"run": int(np.sum(column >= 0)), "held": int(np.sum(column == 1))}
    return out


def outcome_counts(draws: GraspDraws) -> dict[str, int]:
    """Draws per holding outcome (every name of ``HOLD_OUTCOMES``)."""
    return {name: int(np.sum(draws.hold_outcome == k)) for k, name in enumerate(HOLD_OUTCOMES)}


def millimetres(values: np.ndarray) -> list[float | None]:
    """Metres (n,) as millimetres rounded to 0.01 (None: NaN), for JSON."""
    return [None if not np.isfinite(v) else round(float(v) * 1e3, 2) for v in values]


@dataclass
class GraspRow:
    """Per-grasp estimates: P(FC) of each engine and P(hold), with Wilson 95% intervals;
    the holding outcomes, each phase's counts and the grip's shift per draw."""

    object: str
    index: int
    id: str
    samples: int
    p_fc_kinematic: float
    p_fc_kinematic_ci: tuple[float, float]
    p_fc_physics: float
    p_fc_physics_ci: tuple[float, float]
    p_hold: float
    p_hold_ci: tuple[float, float]
    outcomes: dict[str, int]
    phases: dict[str, dict]
    draw_outcomes: list[str]
    grip_shift_mm: list[float | None]
    grip_turn_deg: list[float | None]
    pin_force_n: list[float | None]

    @classmethod
    def of(cls, draws: GraspDraws, phases: tuple[str, ...] = PHASES) -> GraspRow:
        n = len(draws)
        values = []
        for flags in (draws.kin_fc, draws.phys_fc, draws.held):
            k = int(np.sum(flags))
            values += [k / n, wilson_interval(k, n)]
        turns = [None if not np.isfinite(v) else round(float(np.degrees(v)), 2)
                 for v in draws.grip_turn]
        return cls(draws.object, draws.index, draws.id, n, *values, outcome_counts(draws),
                   phase_counts(draws, phases), [HOLD_OUTCOMES[k] for k in draws.hold_outcome],
                   millimetres(draws.grip_shift), turns,
                   [None if not np.isfinite(v) else round(float(v), 2) for v in draws.pin_force])

    def to_json(self) -> dict:
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}
