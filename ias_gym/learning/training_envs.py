"""The training envs of ``train/*.py`` for SB3: one in this process or a batch in workers.

:func:`make_training_env` gives one env in this process (SB3's ``DummyVecEnv``, as
:func:`~ias_gym.learning.finetune.make_vec_env`) or, for ``n_envs > 1``, the same envs
batched in worker processes (:func:`make_batched_vec_env`, on
:class:`~ias_gym.runtime.sb3_vec_env.BatchedVecEnv`): SB3's ``Monitor`` (true returns,
``is_success``), the training reward scale, env ``i`` seeded ``seed + i``.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
from stable_baselines3.common.vec_env.base_vec_env import VecEnv

from ias_gym.errors import InputError
from ias_gym.runtime.sb3_vec_env import BatchedVecEnv


class _MonitoredEnv:
    """``gym.make`` in SB3's ``Monitor`` (true returns, ``is_success``), the reward scaled
    (as :func:`ias_gym.learning.finetune.make_vec_env`'s envs); picklable for the workers."""

    def __init__(
        self, env_id: str, env_kwargs: dict[str, Any], reward_scale: float, action_seed: int
    ) -> None:
        self.env_id, self.env_kwargs = env_id, env_kwargs
        self.reward_scale, self.action_seed = reward_scale, action_seed

    def __call__(self) -> gym.Env[Any, Any]:
        from stable_baselines3.common.monitor import Monitor

        env: gym.Env[Any, Any] = Monitor(
            gym.make(self.env_id, **self.env_kwargs), info_keywords=("is_success",)
        )
        if self.reward_scale != 1.0:
            scale = self.reward_scale
            env = gym.wrappers.TransformReward(env, lambda r: scale * float(r))
        env.action_space.seed(self.action_seed)
        return env


def make_batched_vec_env(
    env_id: str,
    n_envs: int,
    seed: int = 0,
    *,
    num_workers: int | None = None,
    reward_scale: float | None = None,
    env_kwargs: dict[str, Any] | None = None,
    context: str | None = None,
) -> BatchedVecEnv:
    """``n_envs`` copies of ``env_id`` for SB3 training in ``num_workers`` processes.

    The envs are those of :func:`ias_gym.learning.finetune.make_vec_env` (``Monitor``,
    reward times ``reward_scale``, env ``i`` seeded ``seed + i``), batched.

    Args:
        env_id: a registered id.
        n_envs: number of envs.
        seed: seed of the first env (env ``i`` gets ``seed + i`` at the first reset).
        num_workers: worker processes (default: ``min(n_envs, os.cpu_count())``).
        reward_scale: factor on every reward [-] (default: the training scale,
            :data:`ias_gym.learning.finetune.REWARD_SCALE`).
        env_kwargs: configuration overrides for ``gym.make``.
        context: multiprocessing start method (see :class:`BatchedVecEnv`).

    Returns:
        The seeded vector env.
    """
    if reward_scale is None:
        from ias_gym.learning.finetune import REWARD_SCALE

        reward_scale = REWARD_SCALE
    kwargs = dict(env_kwargs or {})
    vec = BatchedVecEnv(
        [_MonitoredEnv(env_id, kwargs, reward_scale, seed + i) for i in range(n_envs)],
        num_workers,
        context=context,
    )
    vec.seed(seed)
    return vec


def make_training_env(
    env_id: str,
    n_envs: int = 1,
    seed: int = 0,
    *,
    num_workers: int | None = None,
    env_kwargs: dict[str, Any] | None = None,
    context: str | None = None,
) -> VecEnv:
    """The training envs of ``train/*.py``: one env in this process (SB3's ``DummyVecEnv``,
    :func:`ias_gym.learning.finetune.make_vec_env`), or ``n_envs > 1`` batched in worker
    processes (:func:`make_batched_vec_env`); the same envs, seeds and trajectories.

    Args:
        env_id: a registered id.
        n_envs: number of envs.
        seed: seed of the first env (env ``i`` gets ``seed + i``).
        num_workers: worker processes for ``n_envs > 1`` (default: one per core, at most
            ``n_envs``).
        env_kwargs: configuration overrides for ``gym.make``.
        context: multiprocessing start method of the workers (see :class:`BatchedVecEnv`).

    Returns:
        The seeded vector env.

    Raises:
        ~ias_gym.errors.InputError: ``n_envs < 1`` or ``num_workers`` outside ``1..n_envs``.
    """
    if n_envs < 1:
        raise InputError(f"n_envs must be >= 1, got {n_envs}")
    if n_envs == 1:
        from ias_gym.learning.finetune import make_vec_env

        return make_vec_env(env_id, 1, seed=seed, env_kwargs=env_kwargs)
    return make_batched_vec_env(
        env_id, n_envs, seed, num_workers=num_workers, env_kwargs=env_kwargs, context=context
    )
