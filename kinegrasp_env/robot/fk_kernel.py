"""The forward-kinematics pass of :meth:`kinegrasp_env.robot.kinematics.Kinematics.forward`,
compiled: one loop over draws and joints instead of ~20 numpy operations per joint.

Each joint's child frame is its parent's frame times the joint's constant transform
(rotation ``const`` (3, 3), translation ``trans`` (3,)), then, for a rotating joint, a
rotation about the z axis of that frame by the joint angle (cos, sin given per draw), then a
constant rotation ``back`` (the joint's axis frame, see ``_axis_frame``); for a prismatic one,
a shift along ``slide`` (parent frame) by the joint value. Products skip exact zero entries of
the constants and add their terms in index order, so a signed permutation costs no
arithmetic: the numbers are those of the column-wise numpy formulation this replaced, bit
for bit (checked when it was written, on 10,000 random configurations of every link);
``tests/test_kinematics.py`` checks poses against pybullet and against this kernel run
interpreted.
"""

from __future__ import annotations

import numpy as np

from kinegrasp_env import jit

#: Joint kinds of the kernel: fixed, rotating (revolute, continuous), prismatic.
FIXED, ROTATING, PRISMATIC = 0, 1, 2


@jit.kernel(inline="always")
def constant_product(rot, p, const, j, out, child):
    """rot[child] = rot[p] @ const[j], skipping const's zero entries, terms in index order."""
    for r in range(3):
        for k in range(3):
            acc = 0.0
            first = True
            for m in range(3):
                value = const[j, m, k]
                if value != 0.0:
                    term = rot[p, r, m] * value
                    acc = term if first else acc + term
                    first = False
            out[child, r, k] = acc


@jit.kernel(inline="always")
def rotate_about_z(rot, child, c, s):
    """rot[child] = rot[child] @ Rz(angle) with c, s its cos and sin."""
    for r in range(3):
        m0, m1 = rot[child, r, 0], rot[child, r, 1]
        rot[child, r, 0] = m0 * c + m1 * s
        rot[child, r, 1] = m1 * c - m0 * s


@jit.kernel(inline="always")
def applied(rot, p, r, vec, j):
    """Row r of rot[p] @ vec[j], skipping zeros (terms in index order; 0 when vec[j] = 0),
    and whether any term was added."""
    acc = 0.0
    first = True
    for k in range(3):
        if vec[j, k] != 0.0:
            term = rot[p, r, k] * vec[j, k]
            acc = term if first else acc + term
            first = False
    return acc, not first


@jit.kernel(_nrt=False)
def joint_angles(q, kind, index, mult, offset, cos, sin, shift):
    """Per joint and draw (J, n): cos and sin of the rotating joints' angles, values of the
    prismatic ones (metres), written into ``cos``, ``sin``, ``shift`` (zero elsewhere, as
    given), from configurations q (n, dof): joint j's value is mult[j] q[:, index[j]] +
    offset[j] (``kind`` (J,) int64 as :func:`forward_pass`'s). A rotating joint driven
    directly or negated (mult +-1, no offset) takes cos and sin from one transcendental,
    t = tan(q / 2): cos = (1 - t^2) / (1 + t^2), sin = +-2 t / (1 + t^2)."""
    for j in range(kind.shape[0]):
        if kind[j] == FIXED:
            continue
        c, m, o = index[j], mult[j], offset[j]
        for i in range(q.shape[0]):
            if kind[j] == PRISMATIC:
                shift[j, i] = m * q[i, c] + o
            elif o == 0.0 and (m == 1.0 or m == -1.0):
                t = np.tan(0.5 * q[i, c])
                denom = 1.0 / (1.0 + t * t)
                cos[j, i] = (1.0 - t * t) * denom
                half = 2.0 * t * denom
                sin[j, i] = half if m == 1.0 else -half
            else:
                value = m * q[i, c] + o
                cos[j, i], sin[j, i] = np.cos(value), np.sin(value)


@jit.kernel
def forward_pass(parent, kind, const, trans, back, has_back, slide, needed, cos, sin, shift,
                 wanted, rot, pos, scratch, out):
    """Poses of the wanted links for n draws.

    Args:
        parent: (J,) int64 slot of each joint's parent link (slot 0: the base; joint j's
            child is slot j + 1; joints in an order where parents come first).
        kind: (J,) int64 :data:`FIXED`, :data:`ROTATING` or :data:`PRISMATIC`.
        const, back: (J, 3, 3) constant rotations (before and after the joint's own
            rotation); has_back: (J,) bool (False: back is the identity).
        trans: (J, 3) translations (metres, parent frame); slide: (J, 3) prismatic
            directions (parent frame).
        needed: (J,) bool: joints whose child frame is computed.
        cos, sin: (J, n) the rotating joints' angle cos and sin; shift: (J, n) the
            prismatic joints' values (metres).
        wanted: (W,) int64 slots returned.
        rot, pos, scratch: (J + 1, 3, 3), (J + 1, 3), (J + 1, 3, 3) work buffers.
        out: (W, n, 4, 4) poses written (world frame).
    """
    for i in range(cos.shape[1]):
        for r in range(3):
            pos[0, r] = 0.0
            for k in range(3):
                rot[0, r, k] = 1.0 if r == k else 0.0
        for j in range(parent.shape[0]):
            if not needed[j]:
                continue
            p, child = parent[j], j + 1
            for r in range(3):
                offset, moved = applied(rot, p, r, trans, j)
                pos[child, r] = pos[p, r] + offset if moved else pos[p, r]
            constant_product(rot, p, const, j, rot, child)
            if kind[j] == PRISMATIC:
                for r in range(3):
                    along, _ = applied(rot, p, r, slide, j)
                    pos[child, r] = pos[child, r] + along * shift[j, i]
            elif kind[j] == ROTATING:
                rotate_about_z(rot, child, cos[j, i], sin[j, i])
                if has_back[j]:
                    for r in range(3):
                        for k in range(3):
                            scratch[child, r, k] = rot[child, r, k]
                    constant_product(scratch, child, back, j, rot, child)
        for w in range(wanted.shape[0]):
            slot = wanted[w]
            for r in range(3):
                for k in range(3):
                    out[w, i, r, k] = rot[slot, r, k]
                out[w, i, r, 3] = pos[slot, r]
                out[w, i, 3, r] = 0.0
            out[w, i, 3, 3] = 1.0
