"""The sliding schedule of eq. (17) and the pen geometry of eq. (16)."""

from __future__ import annotations

import numpy as np
import pytest

from ias_gym.grasp.pen_skill import (
    OUTWARD,
    PenSkillParams,
    contact_points,
    finger_distances,
    finger_velocities,
    sliding_directions,
    sliding_finger,
)

P = PenSkillParams()


def test_schedule_moves_each_finger_one_cm_in_its_own_phase() -> None:
    ts = np.array(P.phase_times)
    phi = finger_distances(ts, P)
    np.testing.assert_allclose(phi[0], [0.03, 0.02, 0.02, 0.03])
    np.testing.assert_allclose(phi[-1], [0.04, 0.03, 0.03, 0.04])
    for i in range(4):
        moved = phi[i + 1] - phi[i]
        expected = np.zeros(4)
        expected[i] = 0.01
        np.testing.assert_allclose(moved, expected, atol=1e-15)


def test_schedule_is_continuous_and_its_velocity_is_its_derivative() -> None:
    t = np.linspace(-0.5, 4.5, 5001)
    phi = finger_distances(t, P)
    assert np.abs(np.diff(phi, axis=0)).max() <= 0.01 * (t[1] - t[0]) + 1e-12  # no jumps
    numeric = np.gradient(phi, t, axis=0)
    analytic = finger_velocities(t, P)
    away_from_kinks = np.min(np.abs(t[:, None] - np.array(P.phase_times)), axis=1) > 2e-3
    np.testing.assert_allclose(numeric[away_from_kinks], analytic[away_from_kinks], atol=1e-9)


@pytest.mark.parametrize(("t", "finger"), [(0.0, 0), (0.99, 0), (1.0, 1), (3.5, 3), (4.0, None)])
def test_sliding_finger(t: float, finger: int | None) -> None:
    assert sliding_finger(t, P) == finger
    dirs = sliding_directions(t, P)
    if finger is None:
        assert dirs == {}
    else:
        np.testing.assert_array_equal(dirs[finger], [OUTWARD[finger], 0.0])


def test_contacts_slide_outward() -> None:
    """Fingers 1, 2 move to -x and 3, 4 to +x (eq. 17; docs/NOTES.md)."""
    start = contact_points(finger_distances(0.0, P), P.radius)
    end = contact_points(finger_distances(4.0, P), P.radius)
    np.testing.assert_allclose(end[:, 0] - start[:, 0], [-0.01, -0.01, 0.01, 0.01])
    np.testing.assert_allclose(start[:, 1], [0.01, -0.01, -0.01, 0.01])


def test_bad_parameters_are_refused() -> None:
    with pytest.raises(ValueError, match="increasing"):
        PenSkillParams(phase_times=(0, 2, 1, 3, 4))
    with pytest.raises(ValueError, match="one entry per finger"):
        PenSkillParams(speeds=(0.01, 0.01))
