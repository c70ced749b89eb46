"""The library's skill templates (ias_gym.assist.skill_motions): demonstrations of one motion
by persons of different amplitude and speed are aligned before they are averaged; a
template says where its motion is done and where the demonstrations leave the pen."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ias_gym.assist.skill_motions import (
    SkillMotion,
    align_demonstrations,
    chance_ranges,
    lift_slope,
    load_motions,
    moving_joints,
    pen_elevation,
)

TAU = np.arange(0.0, 3.0, 0.01)


def _seesaw(tau: np.ndarray) -> np.ndarray:
    """Two cycles of a see-saw (period 0.75 s) that fades in and out, then rest."""
    u = np.clip(tau / 1.5, 0.0, 1.0)
    return (np.sin(np.pi * u) ** 2 * np.sin(2 * np.pi * tau / 0.75) * (tau < 1.5))[:, None]


def test_the_persons_amplitudes_and_speeds_are_recovered_and_the_template_is_sharp() -> None:
    rng = np.random.default_rng(0)
    amps = np.exp(rng.normal(0.0, 0.1, 12))
    speeds = np.exp(rng.normal(0.0, 0.1, 12))
    demos = np.array([a * _seesaw(v * TAU) for a, v in zip(amps, speeds, strict=True)])
    mean, a_fit, v_fit = align_demonstrations(TAU, demos)
    # relative to the typical person: the fit's grid of speeds is 0.02 apart
    np.testing.assert_allclose(a_fit / a_fit.mean(), amps / amps.mean(), rtol=0.03)
    gm = np.exp(np.log(v_fit).mean())
    np.testing.assert_allclose(v_fit / gm, speeds / np.exp(np.log(speeds).mean()), atol=0.025)
    # the aligned template keeps the see-saw's amplitude; a plain mean blurs it
    typical = amps.mean() * _seesaw(np.exp(np.log(speeds).mean()) * TAU)
    assert np.ptp(demos.mean(axis=0)) < 0.9 * np.ptp(typical)
    assert abs(np.ptp(mean) / np.ptp(typical) - 1.0) < 0.05


def test_identical_demonstrations_are_their_own_template() -> None:
    demos = np.repeat(_seesaw(TAU)[None], 3, axis=0)
    mean, a_fit, v_fit = align_demonstrations(TAU, demos)
    np.testing.assert_allclose(mean, demos[0], atol=1e-12)
    np.testing.assert_allclose(a_fit, 1.0, atol=1e-12)
    np.testing.assert_allclose(v_fit, 1.0, atol=1e-12)


def test_chance_ranges_are_the_largest_range_of_one_hold_about_the_mean() -> None:
    # three holds of two joints: the first joint corrected by one person (a step of 0.06),
    # the second never moved; the mean of the three carries a third of the step, so the one
    # who corrected is 0.04 from it, the others 0.02
    hold = np.zeros((3, len(TAU), 2))
    hold[0, TAU > 1.0, 0] = 0.06
    np.testing.assert_allclose(chance_ranges(hold), [0.04, 0.0], atol=1e-12)
    # one demonstration says nothing about chance
    np.testing.assert_array_equal(chance_ranges(hold[:1]), [0.0, 0.0])


def test_one_demonstration_moves_only_the_joints_beyond_a_persons_corrections() -> None:
    # a tilt's pronation (0.19 rad) and one person's corrections of the wrist's flexion and
    # the index (0.05 rad), against what single holds move those joints by (0.03-0.11):
    ranges, chance = np.array([0.19, 0.049, 0.047]), np.array([0.027, 0.053, 0.106])
    np.testing.assert_array_equal(moving_joints(ranges, ranges[None], chance), [0])
    # eight persons who all make those motions: their mean moves a joint by chance a third
    # as far, and the same ranges there are the skill's
    each = np.tile(ranges, (8, 1)) * 2.5
    np.testing.assert_array_equal(moving_joints(ranges, each, chance), [0, 1, 2])
    # never below the floor, whatever the holds
    small = moving_joints(np.array([0.02]), np.array([[0.02]]), np.zeros(1))
    assert small.size == 0


def test_one_persons_grip_in_a_mean_of_four_is_no_motion_of_the_skill() -> None:
    # four demonstrations: the pronation moved by all, the index MCP by one person (0.14
    # rad), whose mean of 0.035 passes the floor and the chance range of a mean of four
    ranges, chance = np.array([0.17, 0.035]), np.array([0.027, 0.043])
    each = np.array([[0.17, 0.14], [0.16, 0.0], [0.18, 0.01], [0.17, 0.0]])
    np.testing.assert_array_equal(moving_joints(ranges, each, chance), [0])
    # three of the four moving it: the skill's
    each[1:3, 1] = 0.06
    np.testing.assert_array_equal(moving_joints(ranges, each, chance), [0, 1])


def test_a_lift_slope_is_the_line_through_the_rise() -> None:
    flexion = np.linspace(0.0, -0.3, 60)
    height = np.clip(-0.12 * flexion, 0.0, 0.03)  # rises, then is held at 3 cm
    height = np.r_[np.zeros(20), height, np.full(20, 0.03)]
    flexion = np.r_[np.zeros(20), flexion, np.full(20, -0.3)]
    assert lift_slope(height, flexion) == pytest.approx(-0.12, rel=1e-6)
    assert math.isnan(lift_slope(height[:2], flexion[:2]))
    assert math.isnan(lift_slope(np.zeros(50), flexion[:50]))  # never lifted


def test_a_motion_is_done_when_its_principal_joint_settles() -> None:
    tau = np.arange(0.0, 2.0, 0.01)
    rise = np.clip(tau / 0.8, 0.0, 1.0)  # a ramp over 0.8 s, then held
    delta = np.stack([0.3 * rise, 0.01 * np.sin(5 * tau)], axis=1)  # a small second joint
    motion = SkillMotion("ramp", tau, delta, np.array([0, 2]), 0.1, 0.1)
    assert motion.principal == 0
    assert 0.75 <= motion.end_tau <= 0.8  # 95 % of the ramp, whatever the other joint does


def test_the_shipped_skills_leave_the_pen_where_they_should() -> None:
    motions = load_motions()
    for name in ("tilt_left", "tilt_right", "seesaw_slow", "seesaw_fast"):
        # held up after the lift (the lifted height is some centimetres)
        assert 0.02 < motions[name].goal_height < 0.06
        assert 0.0 < motions[name].end_tau <= motions[name].tau[-1]
    assert abs(motions["lift_place"].goal_height) < 0.005  # placed back on the support
    # extension raises the pen, by about a tenth of a metre per radian (a hand's length)
    for motion in motions.values():
        assert -0.3 < motion.rise_per_flexion < -0.03


def test_the_elevation_is_the_pen_axis_angle_above_the_horizontal() -> None:
    beta = np.array([-0.2, 0.0, 0.3])  # turns about the world's y axis
    quat = np.stack([np.cos(beta / 2), 0 * beta, np.sin(beta / 2), 0 * beta], axis=1)
    np.testing.assert_allclose(pen_elevation(quat), -beta, atol=1e-12)
    yaw = np.array([[np.cos(0.4), 0.0, 0.0, np.sin(0.4)]])  # turned in the horizontal plane
    np.testing.assert_allclose(pen_elevation(yaw), 0.0, atol=1e-12)


def test_the_shipped_skills_tilt_the_pen_their_own_way() -> None:
    motions = load_motions()
    assert motions["tilt_left"].tilt_per_amplitude > 0.05
    assert motions["tilt_right"].tilt_per_amplitude < -0.05
    for name in ("seesaw_slow", "seesaw_fast"):  # back near where they started (3 deg)
        assert abs(motions[name].tilt_per_amplitude) < 0.05
    for name in ("tilt_left", "tilt_right", "seesaw_slow", "seesaw_fast"):
        # supination (negative pronation) raises the +x end, by about as much as it turns
        assert -1.5 < motions[name].tilt_per_pronation < -0.3
