"""Which closing joints of a finger stop when one of its links touches the object: the rule
of GraspIt's auto-close, for any hand.

A finger's closing joints (:attr:`~kinegrasp_env.robot.description.Finger.joints`, palm to
tip) move its links (link k, the child of joint k, by joints 0..k). When link k touches, the
actuated degrees of freedom that drive joints 0..k stop (the link is held where it touched),
and with them every closing joint of the finger they drive (a mimic joint with its driver);
the joints driven by other degrees of freedom go on closing. So a proximal phalanx that
touches stops its own joint while the distal one keeps closing (the paper's hand), a distal
contact ends the finger, and a finger moved by one degree of freedom (a parallel jaw, a
linkage through mimic joints) stops whole at its first contact.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env.robot.description import Finger
from kinegrasp_env.robot.model import RobotModel

__all__ = ["moved_by", "touch_stops"]


def moved_by(finger: Finger) -> np.ndarray:
    """(K, J) bool: link k of the finger moves with closing joint j (j <= k)."""
    count = len(finger.joints)
    return np.tril(np.ones((len(finger.links), count), dtype=bool))


def touch_stops(model: RobotModel, finger: Finger) -> np.ndarray:
    """(K, J) bool: the closing joints j that stop when link k touches (module docstring)."""
    drivers = model.drivers()
    driver = np.array([drivers[name][0] for name in finger.joints])
    held = moved_by(finger)
    return np.array([np.isin(driver, driver[row]) for row in held], dtype=bool)
