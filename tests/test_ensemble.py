"""An ensemble of clones as one SB3 model: it acts as the members' mean, saves and loads like
any clone, refuses members it cannot combine, and DAgger acts with it. Tiny networks and
random pairs: properties, not numbers."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from ias_gym.baselines.policies import load_policy  # noqa: E402
from ias_gym.errors import InputError  # noqa: E402
from ias_gym.learning.cloning import behaviour_clone, predicted_actions  # noqa: E402
from ias_gym.learning.dagger import dagger  # noqa: E402
from ias_gym.learning.ensemble import (  # noqa: E402
    clone_ensemble,
    ensemble_model,
    member_seed,
)

ENV_ID = "IAS-PenRotate-v0"


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


@pytest.fixture(scope="module")
def env() -> gym.Env:
    return gym.make(ENV_ID)


def _pairs(env: gym.Env, n: int = 300, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    obs = rng.normal(size=(n, *(env.observation_space.shape or ())))
    act = rng.uniform(-0.1, 0.1, size=(n, *(env.action_space.shape or ())))
    return obs, act


def _clones(env: gym.Env, count: int) -> list:
    obs, act = _pairs(env)
    return [
        behaviour_clone(env, obs, act, epochs=2, net_arch=(16, 8), seed=s, progress=False)
        for s in range(count)
    ]


def test_the_wide_model_acts_as_the_mean_of_its_members(env: gym.Env) -> None:
    members = _clones(env, 3)
    wide = ensemble_model(members, env)
    # the hidden layers are the members' side by side
    hidden = [m.out_features for m in wide.policy.mlp_extractor.policy_net if hasattr(m, "weight")]
    assert hidden == [48, 24]
    critic = [m.out_features for m in wide.policy.mlp_extractor.value_net if hasattr(m, "weight")]
    assert critic == [16, 8]  # the unfitted critic is not widened
    x = np.random.default_rng(1).normal(scale=3.0, size=(40, *(env.observation_space.shape or ())))
    mean = np.mean([predicted_actions(m, x, clip=False) for m in members], axis=0)
    single = predicted_actions(members[0], x, clip=False)
    got = predicted_actions(wide, x, clip=False)
    np.testing.assert_allclose(got, mean, rtol=1e-5, atol=1e-7)
    assert np.abs(single - mean).max() > 100 * np.abs(got - mean).max()  # the mean, not one


def test_an_ensemble_saves_and_loads_with_the_safe_loader(env: gym.Env, tmp_path: Path) -> None:
    obs, act = _pairs(env)
    wide = clone_ensemble(env, obs, act, 2, 5, epochs=1, net_arch=(8,), progress=False)
    path = tmp_path / "ensemble.zip"
    wide.save(path)
    policy = load_policy(str(path), env)  # no unpickling
    x = obs[:5].astype(np.float32)
    loaded = np.stack([policy.predict(o, deterministic=True)[0] for o in x])
    np.testing.assert_allclose(loaded, predicted_actions(wide, x), rtol=1e-5, atol=1e-7)


def test_the_observation_clip_survives_the_ensemble_and_the_safe_loader(
    env: gym.Env, tmp_path: Path
) -> None:
    """A feature 30 standard deviations out reaches the network with a clip of 100 (the
    action differs from one at 20) and does not with the default clip of 10."""
    obs, act = _pairs(env)
    actions = {}
    for clip in (10.0, 100.0):
        wide = clone_ensemble(
            env, obs, act, 2, 5, epochs=1, net_arch=(8,), progress=False, obs_clip=clip
        )
        path = tmp_path / f"clip{clip:g}.zip"
        wide.save(path)
        policy = load_policy(str(path), env)  # no unpickling
        assert policy.loaded.policy.features_extractor.clip == clip
        extractor = wide.policy.features_extractor
        far = np.stack([obs[0], obs[0]]).astype(np.float32)
        far[0, 0] = float(extractor.mean[0] + 20 * extractor.std[0])
        far[1, 0] = float(extractor.mean[0] + 30 * extractor.std[0])
        actions[clip] = np.stack([policy.predict(o, deterministic=True)[0] for o in far])
    np.testing.assert_array_equal(actions[10.0][0], actions[10.0][1])
    assert np.abs(actions[100.0][0] - actions[100.0][1]).max() > 1e-6


def test_one_member_is_the_plain_clone(env: gym.Env) -> None:
    obs, act = _pairs(env)
    kwargs: dict[str, Any] = {"epochs": 1, "net_arch": (8,), "progress": False}
    single = clone_ensemble(env, obs, act, 1, 4, **kwargs)
    plain = behaviour_clone(env, obs, act, seed=4, **kwargs)
    np.testing.assert_array_equal(
        predicted_actions(single, obs[:10]), predicted_actions(plain, obs[:10])
    )
    assert member_seed(4, 0) == 4
    assert len({member_seed(4, k) for k in range(5)}) == 5


def test_members_it_cannot_combine_are_refused(env: gym.Env) -> None:
    obs, act = _pairs(env)
    a = behaviour_clone(env, obs, act, epochs=1, net_arch=(8,), progress=False)
    other_layers = behaviour_clone(env, obs, act, epochs=1, net_arch=(4,), progress=False)
    other_data = behaviour_clone(env, obs + 1.0, act, epochs=1, net_arch=(8,), progress=False)
    with pytest.raises(ValueError, match="layers"):
        ensemble_model([a, other_layers], env)
    with pytest.raises(ValueError, match="normalises observations differently"):
        ensemble_model([a, other_data], env)
    other_clip = behaviour_clone(
        env, obs, act, epochs=1, net_arch=(8,), progress=False, obs_clip=50
    )
    with pytest.raises(ValueError, match="normalises observations differently"):
        ensemble_model([a, other_clip], env)
    with pytest.raises(ValueError, match="at least one member"):
        ensemble_model([], env)
    with pytest.raises(ValueError, match="members >= 1"):
        clone_ensemble(env, obs, act, 0)


def test_dagger_acts_with_the_ensemble() -> None:
    kwargs = {"duration": 0.3, "settle_time": 0.2}
    result = dagger(
        ENV_ID,
        1,
        1,
        seed=1,
        env_kwargs=kwargs,
        epochs=2,
        net_arch=(8,),
        ensemble=2,
        progress=False,
    )
    layers = [m for m in result.model.policy.mlp_extractor.policy_net if hasattr(m, "weight")]
    assert layers[0].out_features == 16
    with pytest.raises(InputError, match="ensemble must be >= 1"):
        dagger(ENV_ID, 1, 1, ensemble=0, progress=False)
    with pytest.raises(InputError, match="an ensemble needs warm_start=False"):
        dagger(ENV_ID, 1, 1, ensemble=2, warm_start=True, progress=False)
