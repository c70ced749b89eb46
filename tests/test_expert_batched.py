"""The expert in vector envs: batched ``predict``, SB3's ``evaluate_policy``, worker processes.

Every vectorised way of running the expert must act exactly as one serial expert per env:
the same actions bit for bit, step by step, from each env's seed (and into the episode that
follows an autoreset, where a controller that kept the last episode's memory would differ).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import pytest

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import BatchedExpert, ExpertActionWrapper, ExpertPolicy
from ias_gym.baselines.policies import RandomPolicy, ZeroPolicy, load_policy
from ias_gym.errors import InputError

sb3 = pytest.importorskip("stable_baselines3")
from stable_baselines3.common.env_util import make_vec_env  # noqa: E402
from stable_baselines3.common.evaluation import evaluate_policy  # noqa: E402
from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv  # noqa: E402

ROTATE = "IAS-PenRotate-v0"
SLIDE = "IAS-PenSlide-v0"
SHORT = {"duration": 0.3, "settle_time": 0.1}  # PenRotate: 30 steps of 10 ms
SLIDING_NOW = {"hold_time": 0.0}  # PenSlide: a finger slides from the first step


def _serial_episodes(
    env_id: str, seed: int, episodes: int, kwargs: dict[str, Any]
) -> tuple[list[float], list[np.ndarray]]:
    """Returns and actions of one serial expert: ``reset(seed)``, then unseeded resets (as a
    vector env's autoreset does), a fresh controller each episode."""
    env = gym.make(env_id, **kwargs)
    expert = ExpertPolicy(env)
    returns, actions = [], []
    obs, _ = env.reset(seed=seed)
    for _ in range(episodes):
        expert.reset()
        total, done = 0.0, False
        while not done:
            action = expert.predict(obs)[0]
            actions.append(action)
            obs, reward, terminated, truncated, _ = env.step(action)
            total += float(reward)
            done = terminated or truncated
        returns.append(total)
        obs, _ = env.reset()
    env.close()
    return returns, actions


def _lockstep(venv: Any, env_id: str, seed: int, steps: int, kwargs: dict[str, Any]) -> None:
    """Step ``venv`` (envs seeded seed, seed + 1, ...) with the batched expert and one serial
    expert per env alongside; the actions must agree bit for bit at every step."""
    n = venv.num_envs
    serial = [gym.make(env_id, **kwargs) for _ in range(n)]
    experts = [ExpertPolicy(e) for e in serial]
    for i, env in enumerate(serial):
        env.reset(seed=seed + i)
    batched = ExpertPolicy(venv)
    for step in range(steps):
        actions, state = batched.predict(np.zeros((n, *batched.observation_shape)))
        assert state is None and actions.shape == (n, *venv.action_space.shape[-1:])
        assert actions.dtype == np.float32
        for i, (env, expert) in enumerate(zip(serial, experts, strict=True)):
            expected = expert.predict(np.zeros(batched.observation_shape))[0]
            np.testing.assert_array_equal(actions[i], expected, err_msg=f"step {step} env {i}")
            env.step(expected)
        venv.step(actions)


def test_sb3_evaluate_policy_on_one_env_equals_the_serial_expert() -> None:
    """SB3 wraps a single env in a DummyVecEnv and hands predict a batch of one."""
    env = gym.make(ROTATE, **SHORT)
    venv = DummyVecEnv([lambda: env])
    venv.seed(7)
    returns, _ = evaluate_policy(
        ExpertPolicy(env), venv, n_eval_episodes=2, return_episode_rewards=True, warn=False
    )
    expected, _ = _serial_episodes(ROTATE, 7, 2, SHORT)
    # the VecEnv keeps rewards as float32: equal to the float32 sums' precision
    np.testing.assert_allclose(returns, expected, rtol=1e-6)
    assert returns[0] != returns[1]


@pytest.mark.parametrize("vec_env_cls", [DummyVecEnv, SubprocVecEnv])
def test_sb3_evaluate_policy_on_make_vec_env_equals_serial_experts(vec_env_cls: type) -> None:
    """Two envs, two episodes each (the second after an autoreset): every return is the
    serial expert's for that env's seed (Monitor rounds returns to 1e-6)."""
    wrapper = ExpertActionWrapper if vec_env_cls is SubprocVecEnv else None
    venv = make_vec_env(
        ROTATE, n_envs=2, seed=3, vec_env_cls=vec_env_cls, env_kwargs=SHORT, wrapper_class=wrapper
    )
    try:
        returns, lengths = evaluate_policy(
            ExpertPolicy(venv), venv, n_eval_episodes=4, return_episode_rewards=True
        )
    finally:
        venv.close()
    # evaluate_policy lists episodes as they end: env 0, env 1 (same lengths), then again
    first = [_serial_episodes(ROTATE, 3 + i, 2, SHORT)[0] for i in range(2)]
    expected = [first[0][0], first[1][0], first[0][1], first[1][1]]
    np.testing.assert_allclose(returns, expected, rtol=0, atol=2e-6)
    assert lengths == [30] * 4


def test_in_process_vec_env_acts_as_serial_experts_bit_for_bit() -> None:
    """PenSlide with a finger sliding from the start (the solver's sliding path)."""
    venv = make_vec_env(SLIDE, n_envs=3, seed=11, env_kwargs=SLIDING_NOW)
    venv.reset()
    try:
        _lockstep(venv, SLIDE, 11, 40, SLIDING_NOW)
    finally:
        venv.close()


def test_subproc_vec_env_with_the_wrapper_acts_as_serial_experts_bit_for_bit() -> None:
    venv = make_vec_env(
        SLIDE,
        n_envs=2,
        seed=5,
        vec_env_cls=SubprocVecEnv,
        env_kwargs=SLIDING_NOW,
        wrapper_class=ExpertActionWrapper,
    )
    venv.reset()
    try:
        _lockstep(venv, SLIDE, 5, 30, SLIDING_NOW)
    finally:
        venv.close()


def test_gymnasium_async_vector_env_with_the_wrapper() -> None:
    venv = gym.make_vec(
        ROTATE, num_envs=2, vectorization_mode="async", wrappers=[ExpertActionWrapper], **SHORT
    )
    venv.reset(seed=[21, 22])
    try:
        _lockstep(venv, ROTATE, 21, 20, SHORT)
    finally:
        venv.close()


def test_gymnasium_sync_vector_env_in_process() -> None:
    venv = gym.make_vec(ROTATE, num_envs=2, vectorization_mode="sync", **SHORT)
    venv.reset(seed=[31, 32])
    try:
        _lockstep(venv, ROTATE, 31, 20, SHORT)
    finally:
        venv.close()


def test_subproc_vec_env_without_the_wrapper_is_refused_naming_the_fix() -> None:
    # "module:id" makes each worker import ias_gym (which registers the ids)
    venv = make_vec_env(f"ias_gym:{ROTATE}", n_envs=2, vec_env_cls=SubprocVecEnv, env_kwargs=SHORT)
    try:
        with pytest.raises(InputError, match="ExpertActionWrapper"):
            ExpertPolicy(venv)
    finally:
        venv.close()


def test_wrapper_computes_one_action_per_state_and_resets_with_the_env() -> None:
    env = ExpertActionWrapper(gym.make(ROTATE, **SHORT))
    env.reset(seed=2)
    first = env.expert_action()
    np.testing.assert_array_equal(env.expert_action(), first)  # same state, same action
    env.step(first)
    second = env.expert_action()
    assert not np.array_equal(second, first)
    assert env.controller.last is not None
    env.reset(seed=2)
    # a fresh controller: no memory of the last episode (its W, J, servo forces)
    assert env.controller.last is None and env.controller.infeasible_count == 0
    np.testing.assert_array_equal(env.expert_action(), first)


def test_batched_expert_resets_one_env_at_a_time() -> None:
    envs = [gym.make(ROTATE, **SHORT) for _ in range(2)]
    for i, env in enumerate(envs):
        env.reset(seed=40 + i)
    expert = BatchedExpert(envs)
    start = expert.actions()
    for _ in range(3):
        actions = expert.actions()
        for env, action in zip(envs, actions, strict=True):
            env.step(action)
    envs[0].reset(seed=40)
    expert.reset(0)
    again = expert.actions()
    np.testing.assert_array_equal(again[0], start[0])
    assert not np.array_equal(again[1], start[1])


def test_a_batch_of_different_tasks_and_disturbances_acts_as_serial_experts() -> None:
    """One batched step over envs that take the per-env branches differently (sensor noise,
    internal-force offsets of the task, sliding or not, another task) equals each env's own
    serial expert bit for bit, and records each env's own diagnostics."""
    disturbed = {
        **SLIDING_NOW,
        "force_noise": 0.02,
        "joint_velocity_noise": 0.01,
        "internal_force_step": 0.1,
    }
    rotate = {"duration": 0.8, "settle_time": 0.1}
    specs = [(SLIDE, SLIDING_NOW, 1), (SLIDE, disturbed, 2), (ROTATE, rotate, 3)]
    batch_envs = [gym.make(env_id, **kw) for env_id, kw, _ in specs]
    serial_envs = [gym.make(env_id, **kw) for env_id, kw, _ in specs]
    for (_, _, seed), a, b in zip(specs, batch_envs, serial_envs, strict=True):
        a.reset(seed=seed)
        b.reset(seed=seed)
    batched = BatchedExpert(batch_envs)
    serial = [ExpertPolicy(e) for e in serial_envs]
    for step in range(55):  # the task's first internal-force step comes at 0.5 s
        actions = batched.actions()
        for i, (env, expert) in enumerate(zip(serial_envs, serial, strict=True)):
            obs = np.zeros(env.observation_space.shape)
            np.testing.assert_array_equal(actions[i], expert.predict(obs)[0], err_msg=f"{step} {i}")
            np.testing.assert_array_equal(
                batched.controllers[i].last.c_h_desired, expert.controller.last.c_h_desired
            )
            env.step(actions[i])
            batch_envs[i].step(actions[i])
    assert batched.controllers[1]._N is not None  # env 1 took the offset branch
    assert batched.controllers[0]._N is None and batched.controllers[2]._N is None


def test_a_reset_nobody_announced_starts_the_controller_afresh() -> None:
    """A vector env autoresets its envs without telling the policy (Gymnasium's vector envs
    pass no episode_start): the controller must not carry the last episode's memory (its W,
    J and servo forces) into the next. Its measured internal forces show that memory."""
    env, twin = gym.make(ROTATE, **SHORT), gym.make(ROTATE, **SHORT)
    env.reset(seed=8)
    expert = BatchedExpert([env])
    for _ in range(5):
        env.step(expert.actions()[0])
    env.reset(seed=9)  # the expert is not told
    twin.reset(seed=9)
    fresh = BatchedExpert([twin])
    for _ in range(3):
        a, b = expert.actions()[0], fresh.actions()[0]
        np.testing.assert_array_equal(a, b)
        last, expected = expert.controllers[0].last, fresh.controllers[0].last
        assert last is not None and expected is not None
        np.testing.assert_array_equal(last.c_h_measured, expected.c_h_measured)
        env.step(a)
        twin.step(b)


def test_policies_take_one_observation_or_a_batch() -> None:
    env = gym.make(ROTATE, **SHORT)
    obs, _ = env.reset(seed=0)
    expert = load_policy("expert", env)
    assert expert.predict(obs)[0].shape == (12,)
    assert expert.predict(obs[None])[0].shape == (1, 12)
    with pytest.raises(InputError, match="batch of 3"):
        expert.predict(np.stack([obs] * 3))
    with pytest.raises(InputError, match="shape"):
        expert.predict(obs[:5])
    random = load_policy("random", env, seed=0)
    assert isinstance(random, RandomPolicy)
    assert random.predict(obs)[0].shape == (12,)
    batch = random.predict(np.stack([obs] * 4))[0]
    assert batch.shape == (4, 12) and len({tuple(a) for a in batch}) == 4
    zero = ZeroPolicy(env.action_space, observation_shape=obs.shape)  # type: ignore[arg-type]
    assert zero.predict(np.stack([obs] * 2))[0].shape == (2, 12)
    assert zero.predict(obs)[0].shape == (12,)
