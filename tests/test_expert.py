"""The grip-transform expert solves both tasks; random actions do not; evaluation and video."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from ias_gym.cli import main
from ias_gym.evaluation import evaluate

os.environ.setdefault("MUJOCO_GL", "egl")


@pytest.mark.parametrize("env_id", ["IAS-PenSlide-v0", "IAS-PenRotate-v0"])
def test_expert_succeeds_and_random_fails(env_id: str) -> None:
    expert = evaluate(env_id, "expert", episodes=3, seed=100)
    assert expert.successes == [True, True, True], expert.summary()
    random = evaluate(env_id, "random", episodes=3, seed=100)
    assert not any(random.successes)
    assert expert.summary()["mean_return"] > 10 * random.summary()["mean_return"]


def test_expert_slide_metrics_meet_the_task() -> None:
    summary = evaluate("IAS-PenSlide-v0", "expert", episodes=2, seed=7).summary()
    assert summary["final_slide_error_max_mm"] < 2.0  # every finger within 2 mm of target
    assert summary["max_position_error_max_mm"] < 5.0
    assert summary["max_pen_tilt_max_deg"] < 5.0


def test_evaluate_cli_json_and_video(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    video = tmp_path / "rotate.mp4"
    argv = ["evaluate", "--env", "IAS-PenRotate-v0", "--policy", "random", "--episodes", "2"]
    assert main([*argv, "--json", "--video", str(video)]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    for key in (
        "env",
        "policy",
        "episodes",
        "success_rate",
        "mean_return",
        "max_position_error_mean_mm",
        "max_position_error_max_mm",
    ):
        assert key in summary
    assert summary["episodes"] == 2 and summary["success_rate"] == 0.0
    import imageio.v3 as iio

    frames = iio.imread(video)
    assert frames.ndim == 4 and frames.shape[0] >= 1


def test_unknown_policy_is_a_clear_error() -> None:
    with pytest.raises(FileNotFoundError, match="not 'expert', 'teleop', 'random'"):
        evaluate("IAS-PenSlide-v0", "no/such/model.zip", episodes=1)
