"""The policies shipped in ``ias_gym/assets/policies``: they load without unpickling, act in
their env's spaces, carry the expert they were cloned from, and ``shipped`` on an env
without one is a one-line error."""

from __future__ import annotations

import pickle

import gymnasium as gym
import numpy as np
import pytest

pytest.importorskip("stable_baselines3")

import ias_gym  # noqa: F401  (registers the envs)
from ias_gym.baselines.policies import load_policy, shipped_policy_path
from ias_gym.cli import main
from ias_gym.errors import PolicyNotFoundError
from ias_gym.rollout import rollout

SHIPPED = ["IAS-PenSkill-v0", "IAS-PenSlide-v0", "IAS-PenRotate-v0"]


@pytest.mark.parametrize("env_id", SHIPPED)
def test_a_shipped_policy_loads_without_unpickling_and_acts(
    env_id: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_unpickling(*args: object, **kwargs: object) -> None:
        raise AssertionError("the shipped policy was unpickled")

    env = gym.make(env_id)
    monkeypatch.setattr(pickle, "loads", no_unpickling)
    monkeypatch.setattr(pickle, "load", no_unpickling)
    policy = load_policy("shipped", env)
    monkeypatch.undo()
    obs, _ = env.reset(seed=3)
    for _ in range(3):
        action = policy.predict(obs, deterministic=True)[0]
        assert env.action_space.contains(action.astype(env.action_space.dtype))
        obs, *_ = env.step(action)
    env.close()


def _assert_the_shipped_policy_follows_the_expert(
    env: gym.Env, seed: int, reset_options: dict[str, int] | None = None
) -> None:
    """On the states of one expert episode, the shipped policy's torques are within a fifth
    of the expert's mean |torque| (RMS); an untrained or a truncated model is off by the
    torques' own size (a random policy: 33 times)."""
    expert, shipped = load_policy("expert", env), load_policy("shipped", env)
    trajectory = rollout(env, expert, seed, reset_options=reset_options, keep_observations=True)
    assert trajectory.observations is not None
    actions = np.asarray(trajectory.actions)
    cloned = np.array(
        [shipped.predict(o, deterministic=True)[0] for o in trajectory.observations[:-1]]
    )
    error = float(np.sqrt(np.mean((cloned - actions) ** 2)))
    assert error < 0.2 * float(np.mean(np.abs(actions)))
    env.close()


@pytest.mark.parametrize("skill", [0, 3])  # the first person's lift_hold and tilt_left
def test_the_shipped_skill_policy_acts_as_the_expert_on_its_states(skill: int) -> None:
    # measured 0.0007-0.0008 RMS against a mean |torque| of 0.016 (normalised)
    env = gym.make("IAS-PenSkill-v0")
    _assert_the_shipped_policy_follows_the_expert(env, 100 + skill, {"skill": skill})


@pytest.mark.parametrize("env_id", ["IAS-PenSlide-v0", "IAS-PenRotate-v0"])
def test_a_shipped_pen_task_policy_acts_as_the_expert_on_its_states(env_id: str) -> None:
    # the DAgger learners under a heavier pen (a class they were trained across); measured
    # 0.02-0.04 of the mean |torque|
    _assert_the_shipped_policy_follows_the_expert(gym.make(env_id, mass_scale=1.2), 4242)


def test_shipped_on_an_env_without_a_model_names_the_shipped_ones(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(PolicyNotFoundError, match="IAS-PenSkill-v0"):
        shipped_policy_path("IAS-PenRotate3F-v0")
    argv = ["evaluate", "--env", "IAS-PenRotate3F-v0", "--policy", "shipped", "--episodes", "1"]
    assert main(argv) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1 and "no policy is shipped for IAS-PenRotate3F-v0" in err[0]
    assert shipped_policy_path("IAS-PenSkill-v0").stat().st_size > 0
