"""Contact wrench bases and the wrench matrix W of eq. (3).

A contact contributes one column per wrench it can transmit: a unit wrench direction
``[u; p x u]`` for a force along ``u`` applied at point ``p`` (moments about the reference
point), or ``[0; n]`` for a torsional moment about the normal. ``W`` stacks those columns
for all contacts, so that ``W c`` is the net wrench the contacts apply to the object for the
wrench intensities ``c`` (eq. 3). The modern literature calls the paper's ``W`` the *grasp
matrix*.

Conventions: the normal ``n`` is the direction in which the finger pushes on the object (into
the object), so a compressive contact has a positive normal intensity. Units are SI (m, N).
"""

from __future__ import annotations

from enum import Enum

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


class ContactModel(str, Enum):
    """What a contact can transmit (number of wrench columns in brackets)."""

    FRICTIONLESS = "frictionless"  # normal force only (1)
    POINT_WITH_FRICTION = "pcwf"  # normal + two tangential forces, "hard finger" (3)
    SOFT_FINGER = "soft"  # point with friction + torsion about the normal (4)

    @property
    def n_wrenches(self) -> int:
        """Number of wrench columns a contact of this model contributes."""
        return {"frictionless": 1, "pcwf": 3, "soft": 4}[self.value]


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """The cross product ``a x b`` of two 3-vectors (same units as their product).

    Written out: ``np.cross`` on 3-vectors costs tens of microseconds each (measured 30 us
    against 1.8 us here, numpy 2.4; docs/DESIGN.md, "Speed"), and the controller calls it
    every control step.
    """
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def cross_last(a: FloatArray, b: FloatArray) -> FloatArray:
    """``a x b`` along the last axis of ``(..., 3)`` arrays (a batch of :func:`cross3`).

    The same products and differences as :func:`cross3`, so each row has its bits.
    """
    result: FloatArray = a[..., _YZX] * b[..., _ZXY] - a[..., _ZXY] * b[..., _YZX]
    return result


# Index permutations of the written-out cross product.
_YZX = np.array([1, 2, 0])
_ZXY = np.array([2, 0, 1])


def contact_wrench_basis(
    point: ArrayLike,
    normal: ArrayLike,
    t1: ArrayLike | None = None,
    t2: ArrayLike | None = None,
    model: ContactModel | str = ContactModel.POINT_WITH_FRICTION,
    reference: ArrayLike = (0.0, 0.0, 0.0),
) -> FloatArray:
    """Wrench directions one contact can apply to the object, as columns.

    Args:
        point: contact point [m], in the object's reference frame.
        normal: unit direction in which the finger pushes on the object.
        t1: first unit tangent (needed unless ``model`` is frictionless).
        t2: second unit tangent (needed unless ``model`` is frictionless).
        model: a :class:`ContactModel` or its value (``"frictionless"``, ``"pcwf"``, ``"soft"``).
        reference: point [m] about which moments are taken (the object's centre of mass).

    Returns:
        ``(6, k)`` array, columns in the order normal, t1, t2 (, torsion); ``k`` from the model.
    """
    model = ContactModel(model)
    p = np.asarray(point, dtype=float) - np.asarray(reference, dtype=float)
    dirs = [np.asarray(normal, dtype=float)]
    if model is not ContactModel.FRICTIONLESS:
        if t1 is None or t2 is None:
            raise ValueError(f"contact model {model.value!r} needs both tangents t1 and t2")
        dirs += [np.asarray(t1, dtype=float), np.asarray(t2, dtype=float)]
    cols = [np.concatenate([u, cross3(p, u)]) for u in dirs]
    if model is ContactModel.SOFT_FINGER:
        cols.append(np.concatenate([np.zeros(3), dirs[0]]))
    return np.stack(cols, axis=1)


def wrench_matrix(
    points: ArrayLike,
    frames: ArrayLike,
    model: ContactModel | str = ContactModel.POINT_WITH_FRICTION,
    reference: ArrayLike = (0.0, 0.0, 0.0),
) -> FloatArray:
    """The wrench matrix W of eq. (3) for a set of contacts of one model.

    Args:
        points: ``(m, 3)`` contact points [m].
        frames: ``(m, 3, 3)`` contact frames; row 0 the normal (finger pushes along it),
            rows 1 and 2 the tangents t1, t2.
        model: contact model shared by all contacts.
        reference: point [m] about which moments are taken.

    Returns:
        ``(6, m * k)`` array: the columns of contact 1, then contact 2, ...
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    frs = np.asarray(frames, dtype=float).reshape(-1, 3, 3)
    if len(pts) != len(frs):
        raise ValueError(f"got {len(pts)} contact points but {len(frs)} contact frames")
    model = ContactModel(model)
    m = len(pts)
    # All columns at once (this runs every control step): force directions u and p x u.
    dirs = frs[:, :1] if model is ContactModel.FRICTIONLESS else frs  # (m, k, 3)
    p = (pts - np.asarray(reference, dtype=float))[:, None, :]
    moments = np.empty_like(dirs)
    moments[..., 0] = p[..., 1] * dirs[..., 2] - p[..., 2] * dirs[..., 1]
    moments[..., 1] = p[..., 2] * dirs[..., 0] - p[..., 0] * dirs[..., 2]
    moments[..., 2] = p[..., 0] * dirs[..., 1] - p[..., 1] * dirs[..., 0]
    cols = np.concatenate([dirs, moments], axis=2)  # (m, k, 6)
    if model is ContactModel.SOFT_FINGER:
        torsion = np.concatenate([np.zeros((m, 1, 3)), frs[:, :1]], axis=2)
        cols = np.concatenate([cols, torsion], axis=1)
    return cols.reshape(-1, 6).T.copy()


def wrench_matrices(points: FloatArray, frames: FloatArray, reference: FloatArray) -> FloatArray:
    """:func:`wrench_matrix` of hard-finger contacts for a batch of grasps (same bits per grasp).

    Args:
        points: ``(..., m, 3)`` contact points [m].
        frames: ``(..., m, 3, 3)`` contact frames, rows normal, t1, t2.
        reference: ``(..., 3)`` points [m] about which moments are taken.

    Returns:
        ``(..., 6, 3 m)``: per grasp the columns of contact 1, then contact 2, ...
    """
    p = (points - reference[..., None, :])[..., None, :]  # (..., m, 1, 3)
    dirs = frames
    cols = np.empty((*frames.shape[:-1], 6))  # (..., m, 3, 6)
    cols[..., :3] = dirs
    cols[..., 3] = p[..., 1] * dirs[..., 2] - p[..., 2] * dirs[..., 1]
    cols[..., 4] = p[..., 2] * dirs[..., 0] - p[..., 0] * dirs[..., 2]
    cols[..., 5] = p[..., 0] * dirs[..., 1] - p[..., 1] * dirs[..., 0]
    m = frames.shape[-3]
    # A C-contiguous copy, as wrench_matrix's: a product with the transposed view sums in
    # another order (other last bits)
    cols = cols.reshape(*frames.shape[:-3], 3 * m, 6)
    result: FloatArray = np.ascontiguousarray(cols.swapaxes(-1, -2))
    return result
