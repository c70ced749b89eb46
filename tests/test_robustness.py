"""The disturbance suite: its command's JSON, and the expert holding the pen in every class."""

from __future__ import annotations

import json

import gymnasium as gym
import pytest

import ias_gym  # noqa: F401
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.baselines.policies import load_policy
from ias_gym.cli import main
from ias_gym.robustness import DISTURBANCES, run_robustness
from tests.closed_loop import perturbed_starts

SHORT = {"duration": 1.5}  # PenRotate: 1 s settling + 0.5 s tracked [s]


def test_robustness_json_lines_and_minimum(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["robustness", "--env", "IAS-PenRotate-v0", "--policy", "random", "--episodes", "2"]
    argv += ["--classes", "nominal,action_delay_1_step", "--env-kwargs", json.dumps(SHORT)]
    assert main([*argv, "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.strip().splitlines()]
    assert [x["disturbance"] for x in lines] == ["nominal", "action_delay_1_step", "all"]
    for row in lines[:2]:
        assert set(row) >= {"disturbance", "success_rate", "episodes", "ci95_low", "ci95_high"}
        assert row["ci95_low"] <= row["success_rate"] <= row["ci95_high"] < 1.0  # 0 of 2
        assert row["episodes"] == 2 and row["success_rate"] == 0.0  # random actions fail
    assert lines[-1]["success_rate"] == min(x["success_rate"] for x in lines[:2])


def test_unknown_class_is_one_line_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["robustness", "--env", "IAS-PenRotate-v0", "--classes", "gale"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gale" in err[0] and "nominal" in err[0]


def test_run_robustness_counts_episodes() -> None:
    rows = run_robustness(
        "IAS-PenRotate-v0",
        lambda env: load_policy("expert", env),
        episodes=1,
        seed=3,
        classes=["mass_x1.3"],
        env_kwargs=SHORT,
    )
    assert rows[0].disturbance == "mass_x1.3" and rows[0].episodes == 1
    assert rows[0].success_rate == 1.0
    # the interval is of the counted successes (1 of 1), on this path as on the spec one
    assert rows[0].successes == 1 and rows[0].as_json()["ci95_low"] > 0.0


@pytest.mark.closed_loop
@pytest.mark.parametrize("name", list(DISTURBANCES))
def test_expert_holds_the_pen_in_every_class(name: str) -> None:
    """From a seed and nearby starts (tests/closed_loop.py), 1.5 s of PenRotate in each class:
    the pen is neither dropped nor lost by a finger for long, and the tilt is tracked."""
    env = gym.make("IAS-PenRotate-v0", **SHORT, **DISTURBANCES[name])
    for options in perturbed_starts(env, seed=21):
        obs, _ = env.reset(seed=21, options=options)
        expert = ExpertPolicy(env)
        done = False
        while not done:
            obs, _, terminated, truncated, info = env.step(expert.predict(obs)[0])
            done = terminated or truncated
        assert info["is_success"], (name, info["max_position_error"], info["max_contact_gap"])
