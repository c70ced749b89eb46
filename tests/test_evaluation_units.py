"""``ias-gym evaluate``'s summary names the unit of every task metric and converts to it."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest

from ias_gym.evaluation_results import METRIC_UNITS, EvaluationResult

SUFFIXES = ("_mm", "_deg", "_pct", "_N")
#: Summary keys without a unit: counts, fractions of episodes, the reward's own scale.
PLAIN = ("env", "policy", "episodes", "success_rate", "mean_return", "mean_length")


def _task_keys(summary: dict[str, object]) -> set[str]:
    return set(summary) - set(PLAIN)


def test_summary_converts_si_to_the_named_units() -> None:
    result = EvaluationResult("IAS-PenSlide-v0", "expert")
    for tilt, position in ((math.radians(3.0), 0.002), (math.radians(1.0), 0.004)):
        result.successes.append(True)
        result.returns.append(1.0)
        result.lengths.append(10)
        result.metrics.append(
            {
                "final_slide_error": 0.0005,  # [m]
                "max_position_error": position,  # [m]
                "max_pen_tilt": tilt,  # [rad]
                "rms_tilt_error_fraction": 0.02,  # [-]
                "rms_tilt_error": float("nan"),  # not defined in these episodes
                "pinch_force": 1.5,  # [N]
            }
        )
    summary = result.summary()
    assert summary["final_slide_error_max_mm"] == pytest.approx(0.5)
    assert summary["max_position_error_mean_mm"] == pytest.approx(3.0)
    assert summary["max_position_error_max_mm"] == pytest.approx(4.0)
    assert summary["max_pen_tilt_mean_deg"] == pytest.approx(2.0)
    assert summary["max_pen_tilt_max_deg"] == pytest.approx(3.0)
    assert summary["rms_tilt_error_of_amplitude_max_pct"] == pytest.approx(2.0)
    assert summary["rms_tilt_error_mean_deg"] is None
    assert summary["pinch_force_max_N"] == pytest.approx(1.5)
    assert set(summary) - _task_keys(summary) == set(PLAIN)
    assert all(key.endswith(SUFFIXES) for key in _task_keys(summary))


#: Short episodes [s]. PenSlide's cannot be shorter than its sliding schedule, but without
#: torque the pen drops within 100 steps, which ends the episode.
SHORT = {
    "IAS-PenSlide-v0": {},
    "IAS-PenRotate-v0": {"duration": 0.02, "settle_time": 0.0},
    "IAS-GloveGrasp-v0": {"duration": 0.02},
}


@pytest.mark.parametrize("env_id", sorted(SHORT))
def test_every_metric_of_every_env_has_a_unit(env_id: str) -> None:
    env = gym.make(env_id, **SHORT[env_id])
    env.reset(seed=0)
    info: dict[str, object] = {}
    done = False
    while not done:
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        done = terminated or truncated
    metrics = env.unwrapped.episode_metrics(info)  # type: ignore[attr-defined]
    env.close()
    assert set(metrics) <= set(METRIC_UNITS), set(metrics) - set(METRIC_UNITS)
    result = EvaluationResult(env_id, "zero", [False], [0.0], [2], [metrics])
    task_keys = _task_keys(result.summary())
    assert len(task_keys) == 2 * len(metrics)  # mean and max of each
    assert all(key.endswith(SUFFIXES) for key in task_keys), task_keys
