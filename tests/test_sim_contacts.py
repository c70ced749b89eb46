"""ias_gym.sim.contacts: the point-contact pieces the pen-hand and glove scenes share."""

from __future__ import annotations

import numpy as np

from ias_gym.grasp.wrench_matrix import wrench_matrix
from ias_gym.sim.contacts import (
    PointContacts,
    axis_normals,
    contact_frames,
    contact_intensities,
    cross,
    masked_wrench_matrix,
)
from ias_gym.sim.pen_hand import FingertipContacts
from ias_gym.sim.soft_finger import FingerContacts


def test_both_scenes_contacts_are_point_contacts() -> None:
    """W and c are computed once, for either scene's contacts."""
    assert issubclass(FingertipContacts, PointContacts)
    assert issubclass(FingerContacts, PointContacts)


def test_cross_is_np_cross_to_the_last_bit() -> None:
    """The written-out cross product gives np.cross's numbers exactly (the pen hand's
    frames must not change by its use)."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(50, 3)), rng.normal(size=(50, 3))
    np.testing.assert_array_equal(cross(a, b), np.cross(a, b))
    np.testing.assert_array_equal(cross(a[0], b[0]), np.cross(a[0], b[0]))


def test_frames_normals_and_masked_wrench_matrix() -> None:
    """Frames are orthonormal with t1 along the axis and t2 = sign (t1 x n); the normal of
    an idle finger points at the axis segment; W has zero columns for it and c is each
    finger's force along its frame."""
    axis = np.array([1.0, 0.0, 0.0])
    normals = np.array([[0.0, -1.0, 0.0], [0.0, 0.6, 0.8]])
    sign = np.array([-1.0, 1.0])
    frames = contact_frames(normals, axis, sign)
    eye = np.eye(3)[None].repeat(2, 0)
    np.testing.assert_allclose(frames @ frames.transpose(0, 2, 1), eye, atol=1e-15)
    np.testing.assert_allclose(frames[:, 1], axis[None].repeat(2, 0))
    np.testing.assert_allclose(frames[:, 2], sign[:, None] * np.cross(frames[:, 1], normals))
    # A tip beyond the segment's end: towards the end point, not the infinite line.
    tip = np.array([[0.08, 0.0, 0.04]])
    np.testing.assert_allclose(axis_normals(tip, np.zeros(3), axis, 0.05), [[-0.6, 0.0, -0.8]])

    points = np.array([[0.0, 0.01, 0.0], [0.02, -0.006, -0.008]])
    force = np.array([[0.0, -2.0, 0.1], [0.3, 0.0, 0.0]])
    contacts = PointContacts(np.array([True, False]), points, frames, force)
    W = masked_wrench_matrix(contacts, np.zeros(3))
    np.testing.assert_array_equal(W[:, 3:], 0.0)
    np.testing.assert_allclose(W[:, :3], wrench_matrix(points, frames)[:, :3])
    c = contact_intensities(contacts)
    np.testing.assert_allclose(c[:3], frames[0] @ force[0])
