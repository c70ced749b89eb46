"""What a transfer carries from the human's grasp, and when a hand refuses a skill."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from transfer_fixtures import MU, antipodal_pinch, random_contacts, synthetic_skill

from ias_gym.grasp.grasp_margin import contact_margins, grasp_margin, least_squeeze
from ias_gym.sim import hands
from ias_gym.skills.db import SkillDB
from ias_gym.skills.tolerance import reference_distance, skill_tolerance, still_reference
from ias_gym.skills.transfer import transfer_reference
from ias_gym.skills.transfer_plan import GLOVE_CONTACTS, plan_transfer


# ---------------------------------------------------------------------------- per-contact margins
def test_an_antipodal_pinch_has_equal_contact_margins_of_the_closed_form() -> None:
    # each contact carries half the weight by friction: 1 / s_i* = squeeze 2 mu / weight
    c_p, c_h = antipodal_pinch(1.0, 4.0)
    assert contact_margins(c_p, c_h, MU) == pytest.approx([2.0, 2.0], rel=1e-12)


def test_a_contact_that_carries_less_has_the_larger_margin_and_the_grasp_the_smaller() -> None:
    c_p, c_h = antipodal_pinch(1.0, 4.0)
    c_p = c_p.copy()
    c_p[1], c_p[4] = 0.8, 0.2  # contact 1 carries 0.8 N of the weight, contact 2 0.2 N
    m = contact_margins(c_p, c_h, MU)
    assert m == pytest.approx([4.0 * MU / 0.8, 4.0 * MU / 0.2], rel=1e-12)
    assert grasp_margin(c_p, c_h, MU) == pytest.approx(m.min(), rel=1e-12)


@pytest.mark.parametrize("per", [3, 4])
def test_the_grasp_margin_is_the_least_contact_margin_and_both_scale_with_the_squeeze(
    per: int,
) -> None:
    rng = np.random.default_rng(10 + per)
    checked = 0
    for _ in range(300):
        c_p, c_h = random_contacts(rng, per)
        s = least_squeeze(c_p, c_h, MU, 0.005, per)
        m = contact_margins(c_p, c_h, MU, 0.005, per)
        assert np.all(m >= 0)
        # every contact holds from its own s_i* on, so the grasp needs the largest of them
        # (when the contacts' intervals meet at all; else no squeeze holds: s* = inf)
        if math.isfinite(s) and s > 0:
            checked += 1
            assert 1.0 / s == pytest.approx(m.min(), rel=1e-9)
            assert contact_margins(c_p, 3.0 * c_h, MU, 0.005, per) == pytest.approx(3.0 * m)
    assert checked > 50


def test_contact_margins_are_nan_for_non_finite_intensities() -> None:
    c_p, c_h = antipodal_pinch(1.0, 4.0)
    assert np.isnan(contact_margins(c_p, np.full_like(c_h, np.nan), MU)).all()
    with pytest.raises(ValueError):
        contact_margins(c_p[:5], c_h[:5], MU)


# ---------------------------------------------------------------------------- the mapping
@pytest.mark.parametrize("hand", hands.hand_names())
def test_every_finger_takes_the_role_of_the_glove_contacts_on_its_side(hand: str) -> None:
    plan = plan_transfer(synthetic_skill(lift=0.001, tilt=0.01), hand)
    spec = hands.get_hand(hand)
    names = dict(GLOVE_CONTACTS)
    assert [r.finger for r in plan.roles] == list(spec.fingers)
    for role, side in zip(plan.roles, spec.sides, strict=True):
        assert role.contacts and all(names[c] == side for c in role.contacts)
        assert role.touching == 1.0  # the synthetic pinch holds throughout
        # the synthetic pinch's contacts share the weight: both have the grasp's margin
        assert role.margin == pytest.approx(2 * MU * 4.0, rel=1e-6)


# ---------------------------------------------------------------------------- refusals
def _still_distance(skill: object, hand: str) -> tuple[float, float]:
    reference = transfer_reference(skill, hand)  # type: ignore[arg-type]
    rotation, position, _ = reference_distance(still_reference(reference), reference)
    return rotation, position


def test_a_hand_too_small_for_a_lift_refuses_it_and_a_larger_one_executes_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # 30 mm lifted, no turn: a Shadow hand that carried the pen 2 mm along every axis could
    # not show it above the person's repeatability; the four-finger hand (14 mm) can
    spec = hands.get_hand("shadow")
    small_reach = ((0.002,) * len(hands.REACH_DIRECTIONS),) * len(spec.reach_by_tilt)
    monkeypatch.setitem(hands.HANDS, "shadow", dataclasses.replace(spec, reach_by_tilt=small_reach))
    skill = synthetic_skill(lift=0.03, tilt=0.0)
    tolerance = skill_tolerance(skill.name)
    small, large = plan_transfer(skill, "shadow"), plan_transfer(skill, "ias4f")
    assert small.refused is not None and small.too_small
    assert "shadow" in small.refused and "repeatability" in small.refused
    assert _still_distance(skill, "shadow")[1] < tolerance.position
    assert large.refused is None
    assert _still_distance(skill, "ias4f")[1] > tolerance.position
    # the excursions are reported per axis, demonstrated and executed, in mm
    assert large.demonstrated_mm["y"] == pytest.approx(30.0, rel=1e-3)
    assert large.executed_mm["y"] == pytest.approx(30.0 * large.scale, rel=1e-3)
    assert small.executed_mm["y"] < large.executed_mm["y"]


@pytest.mark.parametrize("hand", hands.hand_names())
def test_a_motion_within_the_persons_spread_is_refused_by_no_hand(hand: str) -> None:
    # no hand can lose what the demonstration does not show: 1 mm and 0.5 deg
    assert plan_transfer(synthetic_skill(lift=0.001, tilt=0.01), hand).refused is None


@pytest.fixture
def small_hands(monkeypatch: pytest.MonkeyPatch) -> None:
    """The LEAP and Shadow hands shrunk to 1.1 deg of tilt and 0.5 mm of travel."""
    for name in ("leap", "shadow"):
        spec = hands.get_hand(name)
        small = ((0.0005,) * len(hands.REACH_DIRECTIONS),) * len(spec.reach_by_tilt)
        monkeypatch.setitem(
            hands.HANDS, name, dataclasses.replace(spec, skill_tilt=0.02, reach_by_tilt=small)
        )


def test_every_hand_takes_a_slow_tilt_in_its_envelope() -> None:
    # an 11.5 deg tilt in place: every hand tilts the pen 17 deg or more, slowly
    skill = synthetic_skill(lift=0.0, tilt=0.2, name="tilt_left")
    assert all(hands.get_hand(h).skill_tilt >= 0.3 for h in hands.hand_names())
    assert not any(plan_transfer(skill, h).refused for h in hands.hand_names())


@pytest.mark.usefixtures("small_hands")
def test_a_turn_beyond_a_hands_tilt_is_refused_by_it_alone() -> None:
    # the same tilt, against tilt_left's repeatability of 3.4 deg: the shrunk hands would
    # show 1.1 deg of it
    skill = synthetic_skill(lift=0.0, tilt=0.2, name="tilt_left")
    refusing = {h for h in hands.hand_names() if plan_transfer(skill, h).refused}
    assert refusing == {"leap", "shadow"}
    assert "deg" in str(plan_transfer(skill, "leap").refused)


def test_a_scheduled_slide_in_the_executed_window_is_refused() -> None:
    sliding = synthetic_skill(lift=0.005, tilt=0.05, sliding_from=1.0)
    plan = plan_transfer(sliding, "ias4f")
    assert plan.refused is not None and "slides its index contact" in plan.refused
    assert not plan.too_small  # no hand would take it
    # a slide after the executed window is not executed, and not refused
    assert plan_transfer(sliding, "ias4f", duration=0.5).refused is None


# ---------------------------------------------------------------------------- the CLI


@pytest.fixture(scope="module")
def lift_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("plan") / "skills.db"
    with SkillDB(path) as db:
        # an 11.5 deg tilt in place (refused by the shrunk hands of `small_hands`)
        db.add(synthetic_skill(lift=0.0, tilt=0.2, duration=1.5, name="tilt_left"))
    return path


def _cli(capsys: pytest.CaptureFixture[str], *args: str) -> tuple[int, str, str]:
    """``ias-gym skills transfer ARGS`` in this process (the shrunk hands are patched in)."""
    from ias_gym.cli import main

    code = main(["skills", "transfer", *args])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.usefixtures("small_hands")
def test_with_every_hand_a_refusing_hand_says_why_in_its_json_line(
    lift_db: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, stdout, stderr = _cli(
        capsys, "--db", str(lift_db), "--id", "1", "--hand", "all", "--json", "--duration", "1.2"
    )
    assert code == 0, stderr
    rows = {row["hand"]: row for row in map(json.loads, stdout.strip().splitlines())}
    assert set(rows) == set(hands.hand_names())
    for refusing in ("leap", "shadow"):
        row = rows.pop(refusing)
        assert row["success"] is False and "repeatability" in row["refused"]
        assert "held" not in row  # nothing ran
    for row in rows.values():
        assert row["refused"] is None and "held" in row
        assert set(row["executed_mm"]) == {"x", "y", "z"}
        assert row["executed_deg"]["tilt"] == pytest.approx(row["demonstrated_deg"]["tilt"])
        assert {f["side"] for f in row["fingers"]} == {"top", "bottom"}


@pytest.mark.usefixtures("small_hands")
def test_with_one_hand_a_refusal_is_a_one_line_error(
    lift_db: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, stdout, stderr = _cli(
        capsys, "--db", str(lift_db), "--id", "1", "--hand", "shadow", "--duration", "1.2"
    )
    assert code == 2 and stdout == ""
    assert len(stderr.strip().splitlines()) == 1 and "Traceback" not in stderr
    assert "hand shadow" in stderr and "--list-hands" in stderr


@pytest.mark.usefixtures("small_hands")
def test_the_transfer_figure_leaves_out_a_refusing_hand(lift_db: Path, tmp_path: Path) -> None:
    pytest.importorskip("matplotlib")
    from ias_gym.figures.transfer_figure import transfer_figure

    runs = transfer_figure(tmp_path / "transfer.png", lift_db, 1)
    assert set(runs) == set(hands.hand_names()) - {"leap", "shadow"}
    assert (tmp_path / "transfer.png").stat().st_size > 10_000
