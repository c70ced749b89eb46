"""Every registered ``IAS-*`` environment: Gymnasium conventions, determinism, bad input."""

from __future__ import annotations

import os
import pickle

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.registration import ENV_SPECS

os.environ.setdefault("MUJOCO_GL", "egl")
ENV_IDS = sorted(ENV_SPECS)
#: The pen tasks (the glove env holds a live glove device: see test_glove_grasp.py).
PEN_IDS = [env_id for env_id in ENV_IDS if env_id.startswith("IAS-Pen")]


def _actions(env_id: str, n: int, scale: float, seed: int = 0) -> np.ndarray:
    dim = gym.make(env_id).action_space.shape[0]
    return np.random.default_rng(seed).uniform(-scale, scale, (n, dim))


def _rollout(env: gym.Env, seed: int, actions: np.ndarray) -> tuple[list, list, list]:
    obs, info = env.reset(seed=seed)
    observations, rewards, infos = [obs], [], [info]
    for a in actions:
        obs, reward, terminated, truncated, info = env.step(a)
        observations.append(obs)
        rewards.append(reward)
        infos.append(info)
        if terminated or truncated:
            break
    return observations, rewards, infos


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_gymnasium_check_env(env_id: str) -> None:
    env = gym.make(env_id)
    check_env(env.unwrapped, skip_render_check=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_sb3_check_env(env_id: str) -> None:
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    sb3_checker.check_env(gym.make(env_id).unwrapped, warn=True)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reachable_with_module_prefix(env_id: str) -> None:
    env = gym.make(f"ias_gym:{env_id}")
    assert env.spec is not None and env.spec.max_episode_steps == ENV_SPECS[env_id][1]
    assert env.unwrapped.max_steps == env.spec.max_episode_steps


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_deterministic_for_a_seed_and_random_across_seeds(env_id: str) -> None:
    actions = _actions(env_id, 30, 0.2)
    a_obs, a_rew, _ = _rollout(gym.make(env_id), 7, actions)
    b_obs, b_rew, _ = _rollout(gym.make(env_id), 7, actions)
    np.testing.assert_array_equal(np.array(a_obs), np.array(b_obs))
    np.testing.assert_array_equal(a_rew, b_rew)
    c_obs, _, _ = _rollout(gym.make(env_id), 8, actions[:1])
    assert not np.allclose(a_obs[0], c_obs[0]), "different seeds gave the same initial state"


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_observations_share_no_memory(env_id: str) -> None:
    env = gym.make(env_id)
    obs0, _ = env.reset(seed=0)
    keep = obs0.copy()
    obs1, *_ = env.step(np.zeros(env.action_space.shape))
    assert not np.shares_memory(obs0, obs1)
    np.testing.assert_array_equal(obs0, keep)  # stepping did not write into an old obs


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_reward_is_the_sum_of_its_terms_and_info_keys_are_stable(env_id: str) -> None:
    env = gym.make(env_id)
    _, info0 = env.reset(seed=1)
    keys = set(info0)
    assert "is_success" in keys and any(k.startswith("reward_") for k in keys)
    for _ in range(20):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert set(info) == keys
        terms = sum(v for k, v in info.items() if k.startswith("reward_"))
        assert reward == pytest.approx(terms, abs=1e-12)
        if terminated or truncated:
            break


@pytest.mark.parametrize("env_id", PEN_IDS)
def test_pickle_round_trip_continues_identically(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=3)
    actions = _actions(env_id, 10, 0.1, seed=1)
    for a in actions[:5]:
        env.step(a)
    clone = pickle.loads(pickle.dumps(env))
    for a in actions[5:]:
        o1, r1, *_ = env.step(a)
        o2, r2, *_ = clone.step(a)
        np.testing.assert_array_equal(o1, o2)
        assert r1 == r2
    assert clone.unwrapped.config == env.unwrapped.config


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_bad_actions(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=0)
    dim = env.action_space.shape[0]
    bad = np.zeros(dim)
    bad[3] = np.nan
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(bad)
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(np.full(dim, np.inf))
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(dim - 1))


@pytest.mark.parametrize("env_id", PEN_IDS)
def test_out_of_range_actions_are_clipped(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=0)
    # Out-of-range actions are clipped to the motors' limits, not rejected.
    env.step(np.full(env.action_space.shape, 5.0))
    ctrl_max = env.unwrapped.model.actuator_ctrlrange[:, 1]
    np.testing.assert_allclose(env.unwrapped.data.ctrl, ctrl_max)


@pytest.mark.parametrize("env_id", PEN_IDS)
def test_reset_options_start_from_a_given_state(env_id: str) -> None:
    env = gym.make(env_id)
    env.reset(seed=5)
    for _ in range(3):
        env.step(np.zeros(env.action_space.shape))
    qpos = env.unwrapped.data.qpos.copy()
    qvel = env.unwrapped.data.qvel.copy()
    env.reset(seed=6, options={"qpos": qpos, "qvel": qvel})
    np.testing.assert_array_equal(env.unwrapped.data.qpos, qpos)
    np.testing.assert_array_equal(env.unwrapped.data.qvel, qvel)
    with pytest.raises(ValueError, match="qpos"):
        env.reset(options={"qpos": qpos[:-1]})


@pytest.mark.parametrize("env_id", PEN_IDS)
def test_zero_torque_drops_the_pen(env_id: str) -> None:
    """Without a controller the pen falls: the task is not solved by doing nothing."""
    env = gym.make(env_id)
    env.reset(seed=0)
    for _ in range(100):
        _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
        if terminated or truncated:
            break
    assert terminated and info["dropped"] and not info["is_success"]


def test_diverging_simulation_is_truncated_not_raised() -> None:
    env = gym.make("IAS-PenSlide-v0")
    env.reset(seed=0)
    env.unwrapped.data.qvel[:] = 1e12  # a state no integrator survives
    _, _, terminated, truncated, info = env.step(np.zeros(env.action_space.shape))
    assert truncated and not terminated and info["sim_unstable"]


@pytest.mark.parametrize("env_id", PEN_IDS)
@pytest.mark.parametrize("mode", ["rgb_array", "depth_array"])
def test_render_modes(env_id: str, mode: str) -> None:
    env = gym.make(env_id, render_mode=mode, render_width=64, render_height=48)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame is not None and frame.shape[:2] == (48, 64)
    assert np.ptp(frame) > 0  # not a blank image


def test_unknown_config_is_refused_with_the_known_names() -> None:
    with pytest.raises(TypeError, match="known:"):
        gym.make("IAS-PenSlide-v0", not_a_setting=1)
    with pytest.raises(ValueError, match="amplitude"):
        gym.make("IAS-PenRotate-v0", amplitude=1.0)
