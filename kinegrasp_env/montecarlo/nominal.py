"""A grasp's nominal contacts and Q: the hand closed once, without noise, at its nominal
configuration q0 (what the planner, the palm-pose candidates and the envs' own tasks record).
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.montecarlo.draws import OUTCOMES, DrawBatch
from kinegrasp_env.world.grasps import DEFAULT_ROBOT, Grasp

#: What a nominal closing that does not reach force closure means, by outcome name.
OUTCOME_DETAILS = {"start_collision": "the open hand intersects the object (or the hand or "
                                      "the arm meets its support table)",
                   "missed": "fewer than 2 contacts, or a finger closes on nothing",
                   "no_force_closure": "the closed hand's contacts are not in force closure"}


def outcome_detail(outcome: int) -> str:
    """(name: what it means) of a draw outcome (an index into ``OUTCOMES``)."""
    name = OUTCOMES[int(outcome)]
    return f"{name}: {OUTCOME_DETAILS.get(name, name)}"


def grasp_from_draw(draw: DrawBatch, object_name: str, q0: np.ndarray,
                    palm_pose: np.ndarray, *, grasp_id: str = "0", meta: dict | None = None,
                    row: int = 0, robot: str = DEFAULT_ROBOT) -> Grasp:
    """The grasp whose nominal contacts and Q are draw ``row`` of ``draw``.

    Args:
        draw: the closing of the hand at q0 (an engine's ``run(q0[None])``, any robot's).
        object_name: the object the draw closed on.
        q0: (dof,) the nominal configuration, radians (metres for a prismatic joint).
        palm_pose: (4, 4) the palm frame at q0, world frame.
        grasp_id, meta: the grasp's id and extra information.
        row: which draw of the batch.
        robot: the robot that closed.
    """
    k = int(draw.n_contacts[row])
    return Grasp(object_name, np.asarray(q0, dtype=float).copy(),
                 np.ascontiguousarray(palm_pose), draw.points[row, :k].copy(),
                 draw.normals[row, :k].copy(), draw.finger[row, :k].astype(int),
                 draw.link[row, :k].astype(int), float(draw.quality[row]), id=grasp_id,
                 meta=dict(meta or {}), robot=robot)
