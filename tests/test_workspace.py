"""The workspace a transferred skill is scaled into: reach per direction and tilt, diagonals,
both ways along an axis, the tilt rate and the speed (``ias_gym.skills.workspace``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from transfer_fixtures import synthetic_skill

from ias_gym.errors import SkillTransferError
from ias_gym.sim.hands import REACH_DIRECTIONS
from ias_gym.skills.transfer import skill_motion, transfer_reference
from ias_gym.skills.workspace import HandWorkspace


def _workspace(**reach_mm: float) -> Any:
    """A workspace with one tilt, 10 mm every way but the directions given ('-y' as m_y)."""
    named = {k.replace("p_", "+").replace("m_", "-"): v for k, v in reach_mm.items()}
    limits = tuple(named.get(d.replace("_", ""), 10.0) / 1000.0 for d in REACH_DIRECTIONS)
    return HandWorkspace(0.01, 0.3, axes=(limits,), tilt_shares=(1.0,))


def test_a_diagonal_is_limited_by_its_own_reach() -> None:
    ws = _workspace(p_xp_y=5.0)  # +x+y: 5 mm
    line = np.linspace(0.0, 1.0, 50)[:, None]
    assert ws.translation_scale(line * [0.0, 0.01, 0.0]) == pytest.approx(1.0)
    assert ws.translation_scale(line * [0.01, 0.01, 0.0]) == pytest.approx(
        0.005 / math.hypot(0.01, 0.01)
    )
    # between an axis and the diagonal the limit is linear in the angle: 7.5 mm at 22.5 deg
    d = 0.02 * np.array([math.cos(math.pi / 8), math.sin(math.pi / 8), 0.0])
    assert ws.translation_scale(line * d) == pytest.approx(0.0075 / 0.02)
    # the other quadrants of the plane, and the same motion in the yz plane, are held by
    # the 10 mm of their own
    for flipped in (d * [-1, 1, 1], d * [1, -1, 1], d[[2, 0, 1]]):
        assert ws.translation_scale(line * flipped) == pytest.approx(0.01 / 0.02)


def test_the_reach_differs_by_the_way_along_an_axis() -> None:
    ws = _workspace(m_y=4.0)  # 4 mm down, 10 mm up
    line = np.linspace(0.0, 1.0, 50)[:, None]
    assert ws.translation_scale(line * [0.0, 0.01, 0.0]) == pytest.approx(1.0)
    assert ws.translation_scale(line * [0.0, -0.01, 0.0]) == pytest.approx(0.4)
    # a motion that goes up 8 mm and then down 8 mm is held by the way down
    both = np.concatenate([line * [0.0, 0.008, 0.0], line * [0.0, -0.008, 0.0]])
    assert ws.translation_scale(both) == pytest.approx(0.5)


def test_a_fast_turn_is_slowed_to_the_hand_s_tilt_rate() -> None:
    skill = synthetic_skill(lift=0.0, tilt=0.15)
    free = transfer_reference(skill, workspace=HandWorkspace(0.005, 1.0))
    fastest = float(np.linalg.norm(free.omega, axis=1).max())
    assert free.scale_rotation == 1.0 and fastest > 0.3
    slow = transfer_reference(skill, workspace=HandWorkspace(0.005, 1.0, tilt_rate=0.5 * fastest))
    assert slow.scale_rotation == pytest.approx(0.5, rel=0.05)
    assert float(np.linalg.norm(slow.omega, axis=1).max()) <= 0.5 * fastest * 1.05


def test_a_transfer_scales_a_lift_into_the_reach_at_its_tilt() -> None:
    # 30 mm up and 6 mm along the pen, no turn: limited by the length, 12 mm at most (the
    # largest reach at the least probed tilt), and by y
    ws = HandWorkspace(
        0.006,
        0.3,
        axes=((0.01, 0.012, 0.01), (0.01, 0.008, 0.01), (0.01, 0.002, 0.01)),
        tilt_shares=(0.25, 0.5, 1.0),
    )
    assert ws.limits(0.0) == ws.limits(0.075) == (0.01, 0.012, 0.01)
    assert ws.limits(0.1) == (0.01, 0.008, 0.01) and ws.limits(0.3) == (0.01, 0.002, 0.01)
    ref = transfer_reference(synthetic_skill(lift=0.03, tilt=0.0), workspace=ws)
    assert ref.scale == pytest.approx(0.012 / (0.03 * math.hypot(1.0, 0.2)), rel=1e-6)
    assert np.abs(ref.position[:, 1]).max() == pytest.approx(0.03 * ref.scale, rel=0.01)
    # a turn beyond the probed tilts: at the hand's full tilt (rotation x0.6) the lift would
    # be held to 2 mm (x0.067, a product of 0.04); held down to half of it (rotation x0.3),
    # the lift shows 8 mm (x0.27, a product of 0.08)
    tilted = transfer_reference(synthetic_skill(lift=0.03, tilt=0.5), workspace=ws)
    assert tilted.scale_rotation == pytest.approx(0.15 / 0.5, rel=0.02)
    assert tilted.scale == pytest.approx(0.008 / 0.03, rel=1e-3)


def test_a_tilt_is_held_down_where_the_hand_could_not_carry_the_pen_at_it() -> None:
    # a hand that carries the pen 10 mm every way at half its tilt and not up at all at its
    # full tilt: a lift at 0.25 rad is shown at half the hand's tilt, not left on the table
    ws = HandWorkspace(
        0.005, 0.3, axes=((0.01, 0.01, 0.01), (0.01, 0.0, 0.01)), tilt_shares=(0.5, 1.0)
    )
    skill = synthetic_skill(lift=0.02, tilt=0.25)
    _, turns = skill_motion(skill)
    turn = float(np.hypot(turns[:, 0], turns[:, 1]).max())
    assert 0.15 < turn <= 0.3
    ref = transfer_reference(skill, workspace=ws)
    assert ref.scale_rotation == pytest.approx(0.15 / turn, rel=1e-6)
    assert ref.scale == pytest.approx(0.01 / (0.02 * math.hypot(1.0, 0.2)), rel=1e-3)
    # where holding the tilt down gains little translation, the rotation is kept: 9 mm up
    # at the full tilt (x0.44 for the whole turn) against 10 mm at half of it (x0.49, but
    # rotation x0.6)
    near = HandWorkspace(
        0.005, 0.3, axes=((0.01, 0.01, 0.01), (0.01, 0.009, 0.01)), tilt_shares=(0.5, 1.0)
    )
    kept = transfer_reference(skill, workspace=near)
    assert kept.scale_rotation == 1.0
    assert kept.scale == pytest.approx(0.009 / 0.02, rel=1e-3)
    # a hand that cannot carry it at any tilt is an error, not a reference without motion
    stuck = HandWorkspace(0.005, 0.3, axes=((0.01, 0.0, 0.01),), tilt_shares=(1.0,))
    with pytest.raises(SkillTransferError, match="carries the pen nowhere"):
        transfer_reference(skill, workspace=stuck)


def test_a_fast_move_is_slowed_to_the_hand_s_speed() -> None:
    skill = synthetic_skill(lift=0.01, tilt=0.0)
    free = transfer_reference(skill, workspace=HandWorkspace(0.05, 1.0))
    fastest = float(np.linalg.norm(free.velocity, axis=1).max())
    assert free.scale == 1.0 and fastest > 0.005
    slow = transfer_reference(skill, workspace=HandWorkspace(0.05, 1.0, speed=0.4 * fastest))
    assert slow.scale == pytest.approx(0.4, rel=0.02) and slow.scale_rotation == 1.0
    assert float(np.linalg.norm(slow.velocity, axis=1).max()) <= 0.4 * fastest * 1.02
