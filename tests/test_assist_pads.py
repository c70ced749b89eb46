"""Both pads kept on the pen from the force display (:mod:`ias_gym.assist.pad_contact`)."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from ias_gym.assist.pad_contact import (
    PINCH_JOINTS_OF,
    TORQUE_COLUMNS,
    PadKeeper,
    PinchClosing,
    pad_arrivals,
    pinch_closing,
)
from ias_gym.assist.policy import make_assistant
from ias_gym.envs.glove_assist import OBSERVATION_PARTS
from ias_gym.envs.glove_world import OBSERVATION
from ias_gym.envs.layout import observation_layout
from ias_gym.errors import InputError
from ias_gym.glove.hand import N_JOINTS, joint_index
from ias_gym.skills.db import SkillDB
from ias_gym.skills.transfer import shipped_skill_db

DT = 0.01


def _torques(index: bool, thumb: bool) -> np.ndarray:
    """A force display with the index's and the thumb's pads on the pen or not."""
    out = np.zeros(5)
    if index:
        out[list(TORQUE_COLUMNS["index"])] = [-0.05, -0.03, -0.01]
    if thumb:
        out[list(TORQUE_COLUMNS["thumb"])] = [0.1, -0.03]
    return out


def test_the_library_closes_each_finger_on_its_own_joints() -> None:
    closing = pinch_closing(shipped_skill_db())
    for finger, direction in closing.directions.items():
        mine = np.zeros(N_JOINTS, dtype=bool)
        mine[list(PINCH_JOINTS_OF[finger])] = True
        assert not direction[~mine].any()
        assert np.max(np.abs(direction)) == pytest.approx(1.0)
    # flexion closes the pinch: the index's MCP and the thumb's flexion lead
    assert closing.directions["index"][joint_index("index_mcp")] == pytest.approx(1.0)
    assert closing.directions["thumb"][joint_index("thumb_flexion")] == pytest.approx(1.0)
    # the library's pads meet within a few steps of each other, in the close
    assert 0.0 < closing.meet_s < 0.3
    assert 0.1 < closing.touch_from_s < 1.0


def test_a_pad_comes_to_the_pen_from_off_it() -> None:
    off, on = np.zeros(6, dtype=bool), np.ones(6, dtype=bool)
    came_at_3 = np.array([0, 0, 0, 1, 1, 1], dtype=bool)
    assert pad_arrivals({"index": came_at_3, "thumb": off}) == {"index": 3}
    # a thumb on the pen from the first step rests there; it comes once it left and returned
    assert pad_arrivals({"index": came_at_3, "thumb": on}) == {"index": 3}
    back_at_4 = np.array([1, 1, 0, 0, 1, 1], dtype=bool)
    assert pad_arrivals({"index": came_at_3, "thumb": back_at_4}) == {"index": 3, "thumb": 4}


def test_a_demonstrator_resting_a_pad_on_the_pen_moves_no_statistic(tmp_path: Path) -> None:
    """A demonstration whose thumb rests on the pen from the session's first step has no
    first touch at 0 s: the library's statistics stay those of its pinches."""
    path = tmp_path / "library.db"
    shutil.copy(shipped_skill_db(), path)
    before = pinch_closing(path)
    with SkillDB(path) as db:
        skill = db.get(db.ids()[0])
        demo = skill.demonstration
        obs = np.array(demo.observations, dtype=np.float64)
        thumb = [OBSERVATION["feedback_torques"].start + c for c in TORQUE_COLUMNS["thumb"]]
        touching = np.flatnonzero(np.any(obs[:, thumb] != 0.0, axis=1))
        obs[: touching[0], thumb[0]] = 0.01  # resting from the start until the pinch
        resting = dataclasses.replace(demo, observations=obs)
        db.add(dataclasses.replace(skill, demonstration=resting))
    after = pinch_closing(path)
    assert after.touch_from_s == pytest.approx(before.touch_from_s)
    assert after.meet_s == pytest.approx(before.meet_s)


def _closing(touch_from_s: float = 0.5) -> PinchClosing:
    """A library whose index closes on joint 3 and thumb on joint 7, its first pads on the
    pen from ``touch_from_s`` and the second within 0.05 s."""
    return PinchClosing(
        {"index": np.eye(N_JOINTS)[3], "thumb": np.eye(N_JOINTS)[7]},
        meet_s=0.05,
        touch_from_s=touch_from_s,
    )


def test_a_pad_alone_on_the_pen_brings_the_other_finger_and_keeps_it() -> None:
    keeper = PadKeeper(_closing(), rate=0.5, limit=0.2, control_dt=DT)
    t = 0.5  # a demonstrator's pad has come to the pen
    # nothing touches, then both pads: nothing to do
    for index, thumb in ((False, False), (True, True)):
        for _ in range(50):
            assert not keeper.update(_torques(index, thumb), t).any()
    # the index alone for as long as the library's pads take to meet: still nothing
    for _ in range(5):
        assert not keeper.update(_torques(True, False), t).any()
    # longer: the thumb closes at the rate, the index is left as it is
    offsets = [keeper.update(_torques(True, False), t) for _ in range(10)]
    assert offsets[-1][7] == pytest.approx(10 * 0.5 * DT)
    assert np.all(np.diff([o[7] for o in offsets]) > 0)
    assert not np.delete(offsets[-1], 7).any()
    # the thumb on the pen again: what was added stays (a grip is never opened) ...
    held = keeper.update(_torques(True, True), t)
    np.testing.assert_allclose(held, offsets[-1])
    # ... and never beyond the limit
    for _ in range(1000):
        out = keeper.update(_torques(False, True), t)
    assert out[3] == pytest.approx(0.2) and out[7] == pytest.approx(offsets[-1][7])
    keeper.reset()
    assert not keeper.update(_torques(True, True), t).any()


def test_a_pad_resting_on_the_pen_before_the_pinch_is_left_alone() -> None:
    """A thumb on the pen from the start while the index is still on its way: it rests on
    the pen until a demonstrator's first pad came to it; from then on it counts."""
    keeper = PadKeeper(_closing(touch_from_s=0.5), rate=0.5, limit=0.2, control_dt=DT)
    steps = np.arange(60) * DT
    out = [keeper.update(_torques(False, True), float(t)) for t in steps]
    # counted from the library's first touch, as long as its pads take to meet
    before = steps < 0.5 + 0.05 - 0.5 * DT
    assert not np.any([o.any() for o, b in zip(out, before, strict=True) if b])
    # then the index (joint 3) is brought to the pen
    assert out[-1][3] == pytest.approx((~before).sum() * 0.5 * DT)
    assert not np.delete(out[-1], 3).any()


def test_the_assistant_closes_the_finger_whose_pad_is_off() -> None:
    layout = observation_layout(OBSERVATION_PARTS)
    obs = np.zeros(max(s.stop for s in layout.values()))
    obs[layout["feedback_torques"]] = _torques(True, False)
    thumb = joint_index("thumb_flexion")
    on = make_assistant(recogniser="none", layout=layout, tremor=False)
    off = make_assistant(recogniser="none", layout=layout, tremor=False, pads=False)
    for step in range(100):  # past the close of the library's pinches
        obs[layout["time"]] = step * DT
        with_pads, without = on.act(obs), off.act(obs)
    assert with_pads[thumb] > 0 and not without.any()
    assert not np.delete(with_pads, list(PINCH_JOINTS_OF["thumb"])).any()


def test_a_library_without_a_pinch_is_refused(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="does not exist"):
        pinch_closing(tmp_path / "missing.db")
    with SkillDB(tmp_path / "empty.db"):
        pass
    with pytest.raises(InputError, match="no glove session that pinches"):
        pinch_closing(tmp_path / "empty.db")
