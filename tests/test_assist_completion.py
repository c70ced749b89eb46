"""The completion's fit of an operator's motion and its stop test
(:class:`ias_gym.assist.motion_completion.Completion`), on a synthetic skill."""

from __future__ import annotations

import numpy as np
import pytest

from ias_gym.assist.motion_completion import AssistParams, Completion
from ias_gym.assist.sessions import LIFT_END
from ias_gym.assist.skill_motions import SkillMotion

DT = 0.01
AMPLITUDE = 0.3  # the skill's motion on its one joint [rad]
DURATION = 0.7  # of the library's typical person [s]
START = 2.05  # the operator's motion begins here [s]


def _minimum_jerk(s: np.ndarray) -> np.ndarray:
    s = np.clip(s, 0.0, 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def _motion() -> SkillMotion:
    tau = np.arange(0.0, 2.0, DT)
    delta = AMPLITUDE * _minimum_jerk(tau / DURATION)[:, None]
    return SkillMotion("turn", tau, delta, np.array([0]), 0.06, 0.09)


def _operator(times: np.ndarray, stop_at: float | None) -> np.ndarray:
    """The typical person's motion from :data:`START` on, after a dip of 0.015 rad against it
    0.2-0.1 s before (it sets the onset off early); held from ``stop_at`` of the way on."""
    dip = -0.015 * np.sin(np.pi * np.clip((times - 1.8) / 0.2, 0.0, 1.0))
    s = np.clip((times - START) / DURATION, 0.0, 1.0)
    if stop_at is not None:
        s = np.minimum(s, stop_at)
    return AMPLITUDE * _minimum_jerk(s) + dip


def _run(stop_at: float | None) -> Completion:
    completion = Completion(_motion(), AssistParams.load(), DT)
    times = np.arange(LIFT_END, 4.0, DT)
    for step, (t, value) in enumerate(zip(times, _operator(times, stop_at), strict=True)):
        completion.update(float(t), np.array([value]), refit=step % 5 == 0)
    return completion


def test_a_motion_after_an_early_onset_is_fitted_where_it_starts() -> None:
    """The dip sets the onset 0.2 s before the motion; an operator who then does the whole
    motion is fitted as the typical person and never latched as stopped."""
    completion = _run(stop_at=None)
    assert completion.onset is not None and completion.onset < START - 0.15
    assert completion.stopped_at is None
    assert completion.fit is not None
    a, v, t0 = completion.fit
    assert a == pytest.approx(1.0, abs=0.1)
    assert v == pytest.approx(1.0, abs=0.1)
    assert t0 == pytest.approx(START, abs=0.05)


@pytest.mark.parametrize("stop_at", [0.3, 0.5])
def test_an_operator_who_stops_part_way_is_latched(stop_at: float) -> None:
    completion = _run(stop_at=stop_at)
    assert completion.stopped_at is not None
    assert START < completion.stopped_at < START + DURATION + 0.5
