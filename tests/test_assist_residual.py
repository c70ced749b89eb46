"""The learned residual (ias_gym.learning.assist_residual): on the assistant on observations
it reads the observation alone, adds at most RESIDUAL_SCALE to its base, is trained and
loaded without unpickling, and bad input is refused before any work."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401
from ias_gym.assist.policy import make_assistant
from ias_gym.errors import InputError
from ias_gym.learning.assist_residual import (
    RESIDUAL_SCALE,
    ObservationResidualAssistant,
    ResidualAssistant,
    ResidualAssistEnv,
)
from ias_gym.safe_sb3 import PolicyFileError
from tests.train_scripts import load_train_script


class _Constant:
    """A policy that always answers ``value`` (and records what it was asked)."""

    def __init__(self, value: float) -> None:
        self.value = value
        self.seen: list[np.ndarray] = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        self.seen.append(np.array(obs))
        return np.full(10, self.value)


def _actions(assistant: object, steps: int = 200) -> tuple[np.ndarray, np.ndarray]:
    """The actions of ``assistant`` fed nothing but the observations of a stopped tilt."""
    env = gym.make("IAS-GloveAssist-v0", person_id="p1", skill="tilt_left", impairment="stops")
    assistant.reset()  # type: ignore[attr-defined]
    obs, _ = env.reset(seed=0)
    actions, observations = [], []
    for _ in range(steps):
        observations.append(obs.copy())
        action = assistant.act(obs.copy())  # type: ignore[attr-defined]
        actions.append(action)
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            break
    env.close()
    return np.array(actions), np.array(observations)


def test_a_zero_residual_is_its_base_and_a_full_one_adds_its_scale() -> None:
    """Fed the same observations, the residual's action is the base's plus
    RESIDUAL_SCALE x the policy's (clipped to [-1, 1]); the policy sees the observation and
    the base's action, nothing else."""
    layout = gym.make("IAS-GloveAssist-v0").unwrapped.observation_layout
    base_actions, observations = _actions(make_assistant(layout=layout))
    zero = ObservationResidualAssistant(_Constant(0.0), make_assistant(layout=layout))
    np.testing.assert_allclose(_actions(zero)[0], base_actions, atol=1e-12)
    policy = _Constant(1.0)
    full = ObservationResidualAssistant(policy, make_assistant(layout=layout))
    base = make_assistant(layout=layout)
    base.reset()
    full.reset()
    for obs in observations[:50]:
        b = base.act(obs)
        np.testing.assert_allclose(full.act(obs), np.clip(b + RESIDUAL_SCALE, -1, 1), atol=1e-12)
        np.testing.assert_allclose(policy.seen[-1], np.concatenate([obs, b]))
    assert full.reads_observations
    with pytest.raises(InputError, match="IAS-GloveAssist-v0"):
        full.act(observations[0][:39])  # IAS-GloveHardware-v0's size: no upcoming targets


def test_the_training_env_runs_its_base_on_observations() -> None:
    """The agent's observation is the env's and the base's action on it: an assistant on
    observations fed the same observations gives the same actions; the reward is at most
    2 and near it while the pen still rests where its reference does."""
    env = ResidualAssistEnv({}, ["p1"], ["sampled"], skills=("tilt_left",), base="observation")
    obs, _ = env.reset(seed=3)
    assert obs.shape == env.observation_space.shape == (59,)
    layout = gym.make("IAS-GloveAssist-v0").unwrapped.observation_layout
    replay = make_assistant(layout=layout)
    replay.reset()
    total, steps = 0.0, 0
    done = False
    while not done and steps < 30:
        np.testing.assert_allclose(obs[49:], replay.act(obs[:49]), atol=1e-12)
        obs, reward, terminated, truncated, _ = env.step(np.zeros(10, dtype=np.float32))
        assert reward <= 2.0
        total += reward
        steps += 1
        done = terminated or truncated
    assert total > 0.5 * steps  # early in the session the pen is where its reference is
    env.close()


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"base": "oracle"}, "base"),
        ({"impairments": ["tremor:hz=30"]}, "out of range"),
        ({"persons": []}, "person"),
    ],
)
def test_the_training_env_refuses_bad_input(kwargs: dict, match: str) -> None:
    args = {"persons": ["p1"], "impairments": ["none"], **kwargs}
    with pytest.raises(InputError, match=match):
        ResidualAssistEnv({}, args.pop("persons"), args.pop("impairments"), **args)


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--impairment", "tremor:hz=30"], "out of range"),
        (["--db", "missing.db"], "no such skill library"),
    ],
)
def test_the_script_refuses_bad_input_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], expected: str
) -> None:
    script = load_train_script("assist_residual")
    out = tmp_path / "r.zip"
    assert script.main([*args, "--base", "observation", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_a_trained_residual_loads_without_unpickling_and_stays_near_its_base(
    tmp_path: Path,
) -> None:
    """A few hundred PPO steps from ``log_std_init=-2``: the loaded residual's actions stay
    within RESIDUAL_SCALE of the base's on the same observations."""
    script = load_train_script("assist_residual")
    out = tmp_path / "r.zip"
    argv = ["--base", "observation", "--persons", "1", "--population-seed", "62"]
    argv += ["--impairment", "stops", "--timesteps", "200", "--n-steps", "100", "--out", str(out)]
    assert script.main(argv) == 0
    learned = ObservationResidualAssistant.load(out)
    layout = gym.make("IAS-GloveAssist-v0").unwrapped.observation_layout
    base_actions, observations = _actions(make_assistant(layout=layout), steps=120)
    learned.reset()
    actions = np.array([learned.act(obs) for obs in observations])
    assert np.all(np.abs(actions - base_actions) <= RESIDUAL_SCALE + 1e-9)
    assert np.any(actions != base_actions)
    with pytest.raises(PolicyFileError, match="--base analytic"):
        ResidualAssistant.load(out, {})  # trained on the other base
