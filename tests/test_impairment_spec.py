"""Impairment specs (ias_gym.glove.impairment_spec) and the families the assist env applies:
parsing, ranges, the errors a user can make, ``sampled``, and what each new family changes
in the operator's joint targets."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401
from ias_gym.errors import InputError
from ias_gym.glove.hand import joint_index
from ias_gym.glove.impairment_spec import (
    FAMILIES,
    Impairment,
    expand_specs,
    family_table,
    parse_impairment,
)
from ias_gym.glove.impairments import pinch_direction, reference_kwargs


def test_a_bare_name_takes_every_default_and_keys_override_them() -> None:
    tremor = parse_impairment("tremor").families[0]
    assert tremor.number("hz") == 10.0 and tremor.number("amplitude_rad") == 0.06
    five = parse_impairment("tremor:hz=5").families[0]
    assert five.number("hz") == 5.0 and five.number("amplitude_rad") == 0.06
    weak = parse_impairment("weak_grip:fingers=thumb, rad=0.1").families[0]
    assert weak["fingers"] == "thumb" and weak.number("rad") == 0.1
    assert parse_impairment("biased_calibration:rad=-0.05").strength == -0.05
    # a sign on a value is no join of families
    assert parse_impairment("biased_calibration:rad=+0.05").strength == 0.05
    signed = parse_impairment("biased_calibration:rad=+0.05,fingers=index + tremor:hz=5")
    assert signed.name == "biased_calibration+tremor"
    assert (
        signed.family("biased_calibration")
        == parse_impairment("biased_calibration:rad=0.05,fingers=index").families[0]
    )
    both = parse_impairment("tremor+weak_grip:rad=0.1")
    assert both.name == "tremor+weak_grip" and both.family("weak_grip") is not None
    assert parse_impairment("none").families == () and parse_impairment("none").strength == 0.0
    # the canonical spec parses back to the same family
    assert parse_impairment(five.spec()).families[0] == five


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("palsy", "not known"),
        ("tremor:freq=5", "KEY=VALUE"),
        ("tremor:hz=2", r"out of range \(4..12 Hz\)"),
        ("tremor:hz=fast", "not a number"),
        ("tremor:hz=nan", "out of range"),
        ("weak_grip:fingers=ring", "index|thumb|both"),
        ("stops:at=1.5", "out of range"),
        ("hand_size:scale=3", r"out of range \(0.8..1.25\)"),
        ("tremor:hz=5,hz=6", "twice"),
        ("tremor+tremor", "twice"),
        ("none+tremor", "stand alone"),
        ("tremor:", "nothing after"),
        ("", "non-empty"),
    ],
)
def test_a_bad_spec_names_what_is_wrong(spec: str, match: str) -> None:
    with pytest.raises(InputError, match=match):
        parse_impairment(spec)


def test_all_expands_and_the_legacy_strength_sets_the_size_key() -> None:
    assert expand_specs(["none", "all", "tremor"]) == ["none", *FAMILIES]
    assert Impairment.make("lag", 0.2).families[0].number("s") == 0.2
    with pytest.raises(InputError, match="strength"):
        Impairment.make("tremor:hz=5", 0.1)
    with pytest.raises(ValueError, match="single"):
        _ = parse_impairment("tremor+lag").strength
    assert {row["family"] for row in family_table()} == set(FAMILIES)


def test_sampled_draws_a_family_within_its_sample_ranges_reproducibly() -> None:
    imp = parse_impairment("sampled")
    seen = set()
    for seed in range(60):
        drawn = imp.draw(np.random.default_rng(seed))
        assert drawn.draw(np.random.default_rng(0)) == drawn  # concrete: drawn once
        (family,) = drawn.families
        seen.add(family.name)
        for key, k in FAMILIES[family.name].items():
            value = family[key]
            if k.is_choice:
                assert value in k.sample
            else:
                lo, hi = (float(v) for v in k.sample)
                assert lo <= float(value) <= hi
        assert parse_impairment(drawn.spec) == Impairment(drawn.spec, drawn.families)
    assert seen == set(FAMILIES)
    first = imp.draw(np.random.default_rng(3))
    assert imp.draw(np.random.default_rng(3)) == first


def _operator_targets(**kwargs: object) -> np.ndarray:
    env = gym.make("IAS-GloveAssist-v0", person_id="p1", **kwargs)
    env.reset(seed=0)
    out = []
    for _ in range(350):
        *_, info = env.step(np.zeros(10))
        out.append(info["operator_theta"])
    env.close()
    return np.array(out)


def test_stops_holds_the_skills_own_motion_and_at_one_changes_nothing() -> None:
    skill = "tilt_left"
    full = _operator_targets(skill=skill)
    # the same plan to its last bits but for rounding at the motion's end, which the person
    # in the loop carries on (1e-9 rad here)
    np.testing.assert_allclose(
        _operator_targets(skill=skill, impairment="stops:at=1"), full, rtol=0, atol=1e-6
    )
    stopped = _operator_targets(skill=skill, impairment="stops:at=0.4")
    pron = joint_index("wrist_pronation")
    moved_full = np.ptp(full[:, pron])
    moved_stopped = np.ptp(stopped[:, pron])
    # the stopped operator turns the wrist part of the way (the physiological tremor aside)
    assert 0.2 * moved_full < moved_stopped < 0.6 * moved_full
    # and holds still at the end while the skill's own motion is over for both
    tail = stopped[-50:, pron]
    assert np.ptp(tail) < 0.1 * moved_full


def test_a_one_finger_weak_grip_opens_only_that_fingers_joints() -> None:
    base = _operator_targets(skill="lift_hold")
    thumb = _operator_targets(skill="lift_hold", impairment="weak_grip:fingers=thumb")
    diff = np.abs(thumb - base)[-1]
    # the thumb closes less; the index only through the calibration's coupling of the
    # readings (one network per joint group)
    assert pinch_direction("thumb")[joint_index("index_mcp")] == 0.0
    assert diff[joint_index("thumb_flexion")] > 0.05
    assert diff[joint_index("thumb_flexion")] > 3.0 * diff[joint_index("index_mcp")]
    assert reference_kwargs(parse_impairment("hand_size:scale=0.9")) == {"hand_scale": 0.9}
