"""What the pen-hand and the glove scenes' contacts share: point contacts with friction.

Both scenes resolve their finger-pen contacts into one point contact with friction per
finger (paper sec. 3, eqs. 3 and 16): :class:`PointContacts` holds them in the paper frame,
:func:`contact_frames` builds the paper's contact frame [normal, t1 = pen axis, t2],
:func:`axis_normals` gives a finger that does not touch the normal towards the pen's axis,
:func:`masked_wrench_matrix` and :func:`contact_intensities` are W and c of eq. (3).
:func:`cross` is ``np.cross`` written out (``np.cross`` costs ~10 us on 3-vectors; these run
every control step).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ias_gym.grasp.wrench_matrix import wrench_matrix

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

# Index permutations for a written-out cross product.
_YZX = np.array([1, 2, 0])
_ZXY = np.array([2, 0, 1])


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a x b`` along the last axis of ``(..., 3)`` arrays, as ``np.cross`` computes it."""
    return a[..., _YZX] * b[..., _ZXY] - a[..., _ZXY] * b[..., _YZX]


@dataclass(frozen=True)
class PointContacts:
    """One point contact with friction per finger (paper frame, SI units).

    Attributes:
        active: ``(k,)`` bool, finger i touches the pen.
        points: ``(k, 3)`` contact points [m], origin at the nominal pen centre.
        frames: ``(k, 3, 3)`` rows normal (the finger pushes along it), t1, t2.
        force: ``(k, 3)`` force of finger i on the pen [N] (zero when not touching).
    """

    active: BoolArray
    points: FloatArray
    frames: FloatArray
    force: FloatArray


def contact_frames(normals: FloatArray, axis: FloatArray, t2_sign: FloatArray) -> FloatArray:
    """Contact frames ``(k, 3, 3)``, rows [n, t1, t2], in the frame of the inputs.

    Args:
        normals: ``(k, 3)`` unit normals (the direction each finger pushes).
        axis: ``(3,)`` unit vector along the pen's axis.
        t2_sign: ``(k,)`` +-1: ``t2 = sign (t1 x n)``, fixed per finger (not from the
            normal's direction, or a finger pushing sideways flips its frame with every
            wobble).

    Returns:
        t1 is the pen's axis made orthogonal to n, so that t2 = +-paper z for the untilted
        pen (eq. 16).
    """
    k = len(normals)
    frames = np.empty((k, 3, 3))
    n, t1, t2 = frames[:, 0], frames[:, 1], frames[:, 2]
    n[:] = normals
    np.subtract(axis, (n @ axis)[:, None] * n, out=t1)
    t1 /= np.sqrt(np.einsum("ij,ij->i", t1, t1))[:, None]
    t2[:] = cross(t1, n)
    t2 *= t2_sign[:, None]
    return frames


def axis_normals(
    points: FloatArray, centre: FloatArray, axis: FloatArray, half_length: float
) -> FloatArray:
    """Unit normals ``(k, 3)`` from ``points`` to the nearest points of the pen's axis segment.

    Args:
        points: ``(k, 3)`` e.g. fingertips that do not touch [m].
        centre: ``(3,)`` the pen's centre [m].
        axis: ``(3,)`` unit vector along the pen's axis.
        half_length: half-length of the segment [m] (the capsule's cylinder).
    """
    rel = points - centre
    u = np.clip(rel @ axis, -half_length, half_length)
    geometric = np.multiply.outer(u, axis) - rel
    normals: FloatArray = geometric / np.linalg.norm(geometric, axis=1, keepdims=True)
    return normals


def masked_wrench_matrix(contacts: PointContacts, reference: FloatArray) -> FloatArray:
    """W of eqs. (3)/(16), ``(6, 3k)``, moments about ``reference`` [m]; zero columns for a
    finger not touching."""
    w = wrench_matrix(contacts.points, contacts.frames, reference=reference)
    if not contacts.active.all():
        w[:, np.repeat(~contacts.active, 3)] = 0.0
    return w


def contact_intensities(contacts: PointContacts) -> FloatArray:
    """Wrench intensities c of eq. (3), ``(3k,)`` [N]: each finger's force on the pen along
    its [normal, t1, t2] (normal >= 0 pushes); zeros for a finger not touching."""
    return np.einsum("kij,kj->ki", contacts.frames, contacts.force).reshape(-1)
