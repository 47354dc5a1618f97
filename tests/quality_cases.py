"""Random contact sets on spheres and boxes for the quality tests and benchmarks."""

from __future__ import annotations

import numpy as np


def sphere_contacts(rng: np.random.Generator, batch: int, k: int, radius: float = 0.05,
                    jitter: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(B, k, 3) points on a sphere centred at the origin and their inward normals,
    optionally tilted by ``jitter`` (radians, roughly) away from the surface normal."""
    out = rng.normal(size=(batch, k, 3))
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    normals = -out + jitter * rng.normal(size=out.shape)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    return radius * out, normals


def box_contacts(rng: np.random.Generator, batch: int, k: int,
                 half: tuple[float, float, float] = (0.04, 0.03, 0.08)
                 ) -> tuple[np.ndarray, np.ndarray]:
    """(B, k, 3) points uniformly on the faces of a box centred at the origin, inward normals."""
    half = np.asarray(half)
    face_axis = rng.integers(0, 3, size=(batch, k))
    face_sign = rng.choice([-1.0, 1.0], size=(batch, k))
    points = rng.uniform(-1.0, 1.0, size=(batch, k, 3)) * half
    np.put_along_axis(points, face_axis[..., None], (face_sign * half[face_axis])[..., None],
                      axis=-1)
    normals = np.zeros((batch, k, 3))
    np.put_along_axis(normals, face_axis[..., None], -face_sign[..., None], axis=-1)
    return points, normals


def pad_pinch(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """(8, 3) contacts and inward normals of two flat 18 x 8 mm pads pinching a 50 mm slab
    from both sides (the patch contact model's corners: 4 coplanar contacts per pad), the
    pads turned about the closing axis z by up to 0.2 rad and shifted, from ``seed``."""
    rng = np.random.default_rng(seed)
    turn = rng.uniform(-0.2, 0.2)
    c, s = np.cos(turn), np.sin(turn)
    corners = (np.array([[-0.009, -0.004], [0.009, -0.004], [0.009, 0.004], [-0.009, 0.004]])
               @ np.array([[c, s], [-s, c]]) + rng.uniform(-0.01, 0.01, 2))
    points = np.vstack([np.column_stack([corners + rng.uniform(-0.001, 0.001, 2),
                                         np.full(4, side * 0.025)]) for side in (1, -1)])
    normals = np.repeat([[0.0, 0.0, -1.0], [0.0, 0.0, 1.0]], 4, axis=0)
    return points, normals
