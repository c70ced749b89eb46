"""The analytic assistant sees the operator's start: from their wrist, not from the generator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ias_gym.assist.assistants import ONSET_RAD, AnalyticAssistant, onset_delay
from ias_gym.assist.sessions import LIFT_END
from ias_gym.assist.skill_templates import SkillTemplate
from ias_gym.glove.hand import JOINT_NAMES, N_JOINTS

WRIST = np.array([JOINT_NAMES.index("wrist_flexion"), JOINT_NAMES.index("wrist_pronation")])
PRONATION = JOINT_NAMES.index("wrist_pronation")


def _template(name: str, start: float, rate: float) -> SkillTemplate:
    """A template whose pronation turns at ``rate`` [rad/s] from ``start`` on."""
    time = np.arange(0.0, 4.0, 0.01)
    theta = np.zeros((len(time), N_JOINTS))
    theta[:, PRONATION] = rate * np.maximum(time - start, 0.0)
    return SkillTemplate(name, time, theta, start, 1.2, np.zeros(len(time)), 1.0)


def test_a_templates_onset_delay_is_its_time_to_the_departure() -> None:
    template = _template("tilt_left", 1.8, 0.2)
    assert onset_delay(template, WRIST) == pytest.approx(ONSET_RAD / 0.2, abs=0.011)
    assert onset_delay(_template("lift_hold", 1.8, 0.0), WRIST) == math.inf


def test_the_operator_start_is_their_onset_less_the_templates_delay() -> None:
    """The lift still ending re-anchors the pose; the skill's departure sets the onset; the
    template time then runs from the operator's own start, whatever the generator drew."""
    tilt = _template("tilt_left", 1.8, 0.2)
    assistant = AnalyticAssistant({"tilt_left": tilt, "lift_hold": _template("lift_hold", 1.8, 0)})
    assistant._theta_lift, assistant._onset = None, None
    pose = np.zeros(N_JOINTS)
    assistant._see_onset(LIFT_END - 0.1, pose)  # before the lift's end: nothing
    assert assistant._theta_lift is None
    assistant._see_onset(LIFT_END, pose)
    moved = pose.copy()
    moved[PRONATION] = 2 * ONSET_RAD
    assistant._see_onset(LIFT_END + 0.01, moved)  # too early for any skill: the lift ending
    assert assistant._onset is None
    np.testing.assert_array_equal(assistant._theta_lift, moved)
    start = 2.3  # a late operator
    for t in np.arange(LIFT_END + 0.02, 3.0, 0.01):
        turned = moved.copy()
        turned[PRONATION] += 0.2 * max(t - start, 0.0)
        assistant._see_onset(float(t), turned)
    assert assistant._onset is not None
    delay = onset_delay(tilt, WRIST)
    assert assistant._onset - delay == pytest.approx(start, abs=0.011)
    assert assistant._template_time(tilt, 2.8) == pytest.approx(2.8 - start + tilt.start, abs=0.011)
