"""A hand's frame in words: where its fingertips are and how they close, in the palm frame.

A grasp from a data set or another planner is a pose of *its* gripper frame; to use it with a
catalog robot that pose must be mapped to the robot's palm frame (the description's
``palm_link``). What the mapping needs, at the open pre-shape (:func:`hand_frame`):

* the **fingertip centre**: the mean of the fingertip links' centres, each the centre of the
  bounding box, in the palm frame, of its collision shapes' vertices (else its visual ones),
  metres (the antipodal planner puts this centre between a pair of contact points);
* the **approach axis**: the unit vector from the palm frame's origin to that centre, and the
  centre's **depth** along it;
* each finger's **closing direction**: the unit displacement of its tip centre as the hand's
  closing joints move a little in their closing direction (``close`` of the description);
* for two fingers, the **opening**: the distance between the two tip centres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kinegrasp_env.robot.description import RobotDescription
from kinegrasp_env.wording import fixed

#: The closing joints' step for the closing directions (radians or metres): pybullet's link
#: frames are good to ~1e-8 m, so directions to ~1e-5.
CLOSING_STEP = 1e-3


@dataclass(frozen=True)
class HandFrame:
    """A hand's palm frame and fingertips (module docstring); vectors in the palm frame.

    Attributes:
        palm_link: the frame's link.
        centre: (3,) the fingertip centre, metres.
        approach: (3,) unit vector from the origin to the centre; depth: its distance, metres.
        tips: the fingertip links; tip_centres: (F, 3) each one's bounding-box centre, metres;
            closing: (F, 3) each one's unit closing direction.
        opening: the two tip centres' distance (None unless two fingers), metres.
    """

    palm_link: str
    centre: np.ndarray
    approach: np.ndarray
    depth: float
    tips: tuple[str, ...]
    tip_centres: np.ndarray
    closing: np.ndarray
    opening: float | None

    def lines(self) -> list[str]:
        """The frame in words, one fact a line."""
        def vec(v):
            return "(" + ", ".join(fixed(x, 3, "+") for x in v) + ")"

        out = [f"palm frame: link {self.palm_link} (a pose of the hand is this link's pose)",
               f"  fingertip centre {vec(self.centre)} m: approach axis {vec(self.approach)}, "
               f"depth {self.depth:.4f} m"]
        out += [f"  {tip} closes along {vec(d)}"
                for tip, d in zip(self.tips, self.closing, strict=True)]
        if self.opening is not None:
            out.append(f"  opening between the two tips {self.opening:.4f} m")
        return out


def _centre(shapes, link: str, to_palm: np.ndarray) -> np.ndarray:
    """(3,) the centre of the bounding box, in the palm frame, of a link's collision shapes'
    vertices (else its visual ones); ``to_palm`` (4, 4) the link's pose in the palm frame."""
    mine = [s for s in shapes if s.link == link]
    chosen = [s for s in mine if s.source == "collision"] or mine
    if not chosen:
        return to_palm[:3, 3].copy()
    vertices = np.vstack([s.vertices for s in chosen]) @ to_palm[:3, :3].T + to_palm[:3, 3]
    return 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))


def hand_frame(description: RobotDescription) -> HandFrame:
    """The :class:`HandFrame` of a robot at its open pre-shape (pybullet's kinematics)."""
    from kinegrasp_env.robot.picture import robot_geometry

    model = description.model
    q_open = np.asarray(description.open_configuration(), dtype=float)
    q_step = q_open.copy()
    for joint, direction in description.close.items():
        i = int(model.index([joint])[0])
        q_step[i] = np.clip(q_step[i] + CLOSING_STEP * direction, model.lower[i], model.upper[i])
    geometry = robot_geometry(description, [model.expand(q_open), model.expand(q_step)])
    palm_inverse = np.linalg.inv(geometry.frames[0][description.palm_link])
    tips = tuple(description.fingertip_links)
    centres, moves = [], []
    for tip in tips:
        at = [_centre(geometry.shapes, tip, palm_inverse @ frames[tip])
              for frames in geometry.frames]
        centres.append(at[0])
        move = at[1] - at[0]
        norm = np.linalg.norm(move)
        moves.append(move / norm if norm > 0 else move)
    centres = np.array(centres)
    centre = centres.mean(axis=0)
    depth = float(np.linalg.norm(centre))
    approach = centre / depth if depth > 0 else np.zeros(3)
    opening = float(np.linalg.norm(centres[0] - centres[1])) if len(tips) == 2 else None
    return HandFrame(description.palm_link, centre, approach, depth, tips, centres,
                     np.array(moves), opening)
