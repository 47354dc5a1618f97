"""A physics closing's contact by finger and phalanx, in the object's frame (:class:`Contact`:
what :func:`~kinegrasp_env.physics.hold_runner.in_object_frame` gives)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Contact:
    """One finger-object contact (object frame).

    Attributes:
        finger: the finger's index in the description.
        link: the link's index along the finger (0: the one nearest the palm).
        point: (3,) on the object's surface, metres.
        normal: (3,) inward unit surface normal.
    """

    finger: int
    link: int
    point: np.ndarray
    normal: np.ndarray
