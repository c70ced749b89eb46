"""SAC with demonstrations: the symmetric minibatches, the stored transitions, the frozen actor
of the critic's warm-up, the pretraining, the randomised training env and the script's bad
input. Tiny budgets (episodes of 30 steps); properties, not numbers."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from ias_gym.learning.demo_rl import (  # noqa: E402
    CriticWarmup,
    DemoReplayBuffer,
    Transitions,
    add_cloning_term,
    episode_transitions,
    make_sac,
    pretrain_actor,
    target_entropy,
)
from ias_gym.learning.expert_labelling import collect_episode  # noqa: E402
from ias_gym.learning.randomised_dynamics import (  # noqa: E402
    RandomisedDynamicsEnv,
    episode_dynamics,
)
from tests.train_scripts import load_train_script  # noqa: E402

ENV_ID = "IAS-PenRotate-v0"
ENV_KWARGS: dict[str, Any] = {"duration": 0.3, "settle_time": 0.2}


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def episodes() -> list[Any]:
    return [
        collect_episode(
            ENV_ID, episode_dynamics(4, k), None, 1.0, env_kwargs=ENV_KWARGS, expert_noise=0.01
        )
        for k in range(2)
    ]


def _transitions(n: int, obs_dim: int, act_dim: int, value: float) -> Transitions:
    obs = np.full((n, obs_dim), value, dtype=np.float32)
    return Transitions(
        obs,
        np.zeros((n, act_dim), np.float32),
        np.ones(n, np.float32),
        obs.copy(),
        np.zeros(n, np.float32),
    )


def test_a_minibatch_is_half_demonstrations_once_the_agent_has_its_own() -> None:
    obs_space = gym.spaces.Box(-np.inf, np.inf, (3,), np.float32)
    act_space = gym.spaces.Box(-1.0, 1.0, (2,), np.float32)
    demos = _transitions(50, 3, 2, 7.0)  # demonstrations marked by 7
    buffer = DemoReplayBuffer(100, obs_space, act_space, "cpu", demonstrations=demos)
    only = buffer.sample(10)
    assert bool(torch.all(only.observations == 7.0))  # nothing of its own yet: all demos
    for _ in range(5):
        buffer.add(
            np.zeros((1, 3)), np.ones((1, 3)), np.zeros((1, 2)), np.zeros(1), np.zeros(1), [{}]
        )
    batch = buffer.sample(10)
    from_demos = int(torch.all(batch.observations == 7.0, dim=1).sum())
    assert from_demos == 5 and batch.observations.shape == (10, 3)
    assert batch.rewards.shape == batch.dones.shape == (10, 1)
    with pytest.raises(ValueError, match="demo_fraction"):
        DemoReplayBuffer(100, obs_space, act_space, demonstrations=demos, demo_fraction=1.5)


def test_transitions_are_what_was_executed_in_order(episodes: list[Any]) -> None:
    demos = episode_transitions(episodes, reward_scale=0.5)
    first = episodes[0].trajectory
    n = first.length
    assert len(demos) == sum(e.trajectory.length for e in episodes)
    np.testing.assert_allclose(demos.next_observations[: n - 1], demos.observations[1:n])
    np.testing.assert_allclose(demos.actions[:n], first.actions, atol=1e-7)
    # the executed actions carry the DART noise, the expert's labels do not
    assert np.abs(demos.actions[:n] - episodes[0].labels).max() > 1e-3
    np.testing.assert_allclose(demos.rewards[:n], 0.5 * first.rewards, rtol=1e-6)
    assert demos.dones.sum() == sum(e.trajectory.terminated for e in episodes)
    with pytest.raises(ValueError, match="no demonstration steps"):
        episode_transitions([])


def test_the_entropy_target_grows_with_the_noise() -> None:
    assert target_entropy(12, 1e-3) < target_entropy(12, 1e-2) < 0
    assert target_entropy(3, 1 / math.sqrt(2 * math.pi * math.e)) == pytest.approx(0.0, abs=1e-12)


def _sac(episodes: list[Any], **kwargs: Any) -> Any:
    env = RandomisedDynamicsEnv(ENV_ID, seed=9, env_kwargs=ENV_KWARGS)
    return make_sac(env, episode_transitions(episodes), net_arch=(16,), batch_size=32, **kwargs)


def _actor_weights(model: Any) -> list[Any]:
    return [p.detach().clone() for p in model.actor.parameters()]


def test_the_actor_stays_put_while_the_critic_warms_up(episodes: list[Any]) -> None:
    model = _sac(episodes, learning_starts=10)
    actor = _actor_weights(model)
    critic = [p.detach().clone() for p in model.critic.parameters()]
    model.learn(40, callback=CriticWarmup(60))
    assert all(torch.equal(a, b) for a, b in zip(actor, _actor_weights(model), strict=True))
    assert not all(
        torch.equal(a, b.detach()) for a, b in zip(critic, model.critic.parameters(), strict=True)
    )
    model.learn(40, callback=CriticWarmup(10), reset_num_timesteps=False)  # past its end
    assert not all(torch.equal(a, b) for a, b in zip(actor, _actor_weights(model), strict=True))
    assert all(p.requires_grad for p in model.actor.parameters())


def test_pretraining_moves_the_actor_onto_the_demonstrations(episodes: list[Any]) -> None:
    model = _sac(episodes)
    obs = np.concatenate([e.observations for e in episodes])
    labels = np.concatenate([e.labels for e in episodes])

    def error() -> float:
        actions = model.predict(obs.astype(np.float32), deterministic=True)[0]
        return float(np.mean((actions - labels) ** 2))

    before = error()
    pretrain_actor(model, obs, labels, epochs=30, batch_size=32)
    assert error() < 0.5 * before


def test_every_reset_draws_the_runs_next_dynamics() -> None:
    env = RandomisedDynamicsEnv(ENV_ID, seed=5, env_kwargs=ENV_KWARGS)
    families = []
    for _ in range(4):
        _, info = env.reset()
        families.append(info["dynamics_family"])
    assert families == [episode_dynamics(5, k).family for k in range(4)]
    _, info = env.reset(seed=5)  # a seed starts the run over
    assert info["dynamics_family"] == families[0]
    obs, *_ = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs.astype(env.observation_space.dtype))
    env.close()


def _script_main() -> Callable[[list[str]], int]:
    """``main`` of ``train/sac_demos.py`` (it imports its sibling ``train/dagger.py``)."""
    load_train_script("dagger")
    main: Callable[[list[str]], int] = load_train_script("sac_demos").main
    return main


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (["--env", "IAS-GloveGrasp-v0"], "not a pen task"),
        (["--demo-fraction", "2"], "--demo-fraction must be in [0, 1]"),
        (["--exploration-std", "0"], "--exploration-std must be > 0"),
        (["--eval-seed", "5"], "--eval-seed must be >= 100000"),
    ],
)
def test_the_script_refuses_bad_input_with_one_line(
    args: list[str], match: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert _script_main()(["--out", str(tmp_path / "p.zip"), *args]) == 2
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and match in lines[0], lines


def test_the_cloning_term_pulls_the_actor_to_the_demonstrations_unless_frozen(
    episodes: list[Any],
) -> None:
    model = _sac(episodes)
    obs = np.concatenate([e.observations for e in episodes]).astype(np.float32)
    labels = np.concatenate([e.labels for e in episodes])
    add_cloning_term(model, obs, labels, seed=1)
    optimizer = model.actor.optimizer

    def error() -> float:
        return float(np.mean((model.predict(obs, deterministic=True)[0] - labels) ** 2))

    for p in model.actor.parameters():  # frozen (the critic's warm-up): nothing moves
        p.requires_grad_(False)
    frozen = _actor_weights(model)
    optimizer.step()
    assert all(torch.equal(a, b) for a, b in zip(frozen, _actor_weights(model), strict=True))
    for p in model.actor.parameters():
        p.requires_grad_(True)
    before = error()
    for _ in range(30):  # no SAC loss: the steps follow the cloning term alone
        optimizer.zero_grad()
        optimizer.step()
    assert error() < 0.7 * before
    assert optimizer.last_weight > 0  # mean |Q| / 2.5 of an untrained critic, not zero
