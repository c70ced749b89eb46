"""PPO fine-tuning of a cloned policy: training envs, SB3 callbacks, the fine-tuning schedule.

:func:`fine_tune` runs PPO with tiny steps (:data:`FINE_TUNE_PPO`), the actor frozen while
the critic warms up, and :class:`KeepBestPolicy` keeps the best policy on held-out
validation seeds: within 100k steps PPO did not improve on the cloned policy, and its last
iterate was often worse. :func:`make_vec_env` and :class:`WallClockLimit` serve training
from scratch as well (``train/from_scratch.py``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.monitor import Monitor
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv

from ias_gym.learning.demonstrations import GAMMA
from ias_gym.rollout import rollout

#: Rewards are multiplied by this while training (values of order one, not 100s) [-].
REWARD_SCALE = 1.0 - GAMMA
#: Fine-tuning hyperparameters of PPO. The steps must be tiny: the tasks tolerate torque
#: errors of about 0.001 (the expert itself drops the pen under noise of 0.002). Measured on
#: PenSlide from a cloned policy at 100 % (exploration noise 0.001, 100k steps): learning
#: rate 3e-5 ended at 0 % success, 1e-5 at 30 %, 3e-6 at 88-100 %.
FINE_TUNE_PPO: Mapping[str, Any] = {
    "learning_rate": 3e-6,
    "n_steps": 1024,
    "batch_size": 256,
    "n_epochs": 5,
    "clip_range": 0.1,
    "target_kl": 0.02,
    "gae_lambda": 0.95,
    "max_grad_norm": 0.5,
}
#: Environment steps of PPO fine-tuning during which only the critic learns.
CRITIC_WARMUP = 20_000


def make_vec_env(
    env_id: str,
    n_envs: int = 1,
    seed: int = 0,
    *,
    reward_scale: float = REWARD_SCALE,
    env_kwargs: Mapping[str, Any] | None = None,
) -> VecEnv:
    """``n_envs`` copies of ``env_id`` for SB3 training (``DummyVecEnv``, seeded).

    Each env is wrapped in SB3's ``Monitor`` (which logs the true episode returns and
    ``is_success``) and then its reward multiplied by ``reward_scale``.

    Args:
        env_id: a registered id.
        n_envs: number of envs.
        seed: seed of the first env (env ``i`` gets ``seed + i``).
        reward_scale: factor on every reward [-].
        env_kwargs: configuration overrides for ``gym.make``.
    """
    kwargs = dict(env_kwargs or {})

    def factory(rank: int) -> Callable[[], gym.Env[Any, Any]]:
        def make() -> gym.Env[Any, Any]:
            env: gym.Env[Any, Any] = Monitor(
                gym.make(env_id, **kwargs), info_keywords=("is_success",)
            )
            if reward_scale != 1.0:
                env = gym.wrappers.TransformReward(env, lambda r: reward_scale * float(r))
            env.action_space.seed(seed + rank)
            return env

        return make

    vec = DummyVecEnv([factory(i) for i in range(n_envs)])
    vec.seed(seed)
    return vec


class WallClockLimit(BaseCallback):
    """Stops SB3 training once ``seconds`` have passed since this callback was created.

    Args:
        seconds: the time budget [s].
    """

    def __init__(self, seconds: float) -> None:
        super().__init__()
        self.seconds = float(seconds)
        self.start = time.perf_counter()
        self.stopped = False

    def _on_step(self) -> bool:
        if time.perf_counter() - self.start > self.seconds:
            self.stopped = True
            return False
        return True


class KeepBestPolicy(BaseCallback):
    """Validates the deterministic policy on fixed seeds during training; keeps the best.

    Model selection on held-out seeds, as SB3's ``EvalCallback`` does, but on the same
    episodes every time (its episodes differ between evaluations) and ranked by success
    rate first, then mean return. The policy at the start of training is the first
    candidate: :meth:`restore` never returns something worse on the validation seeds.

    Args:
        env_id: the task.
        seeds: reset seeds of the validation episodes (keep them apart from test seeds).
        eval_freq: validate every this many environment steps (all envs together).
        env_kwargs: configuration overrides for ``gym.make``.

    Raises:
        ValueError: ``seeds`` is empty.
    """

    def __init__(
        self,
        env_id: str,
        seeds: Sequence[int],
        eval_freq: int = 20_000,
        *,
        env_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        super().__init__()
        if not seeds:
            raise ValueError("need at least one validation seed")
        self.env_id = env_id
        self.seeds = [int(s) for s in seeds]
        self.eval_freq = int(eval_freq)
        self.env_kwargs = dict(env_kwargs or {})
        self.history: list[tuple[int, float, float]] = []  # (steps, success rate, return)
        self.best: tuple[float, float] | None = None
        self.best_steps = 0
        self._best_state: dict[str, torch.Tensor] | None = None
        self._last_eval = 0

    def validate(self) -> tuple[float, float]:
        """``(success rate, mean return)`` of the deterministic policy on the seeds."""
        env = gym.make(self.env_id, **self.env_kwargs)
        successes, returns = [], []
        for seed in self.seeds:
            trajectory = rollout(env, self.model, seed, keep_observations=False, keep_infos=False)
            successes.append(bool(trajectory.final_info["is_success"]))
            returns.append(trajectory.episode_return)
        env.close()
        return float(np.mean(successes)), float(np.mean(returns))

    def _check(self) -> None:
        steps = int(self.model.num_timesteps)
        self._last_eval = steps
        score = self.validate()
        self.history.append((steps, *score))
        if self.best is None or score > self.best:
            self.best, self.best_steps = score, steps
            self._best_state = {
                k: v.detach().clone() for k, v in self.model.policy.state_dict().items()
            }

    def _on_training_start(self) -> None:
        if self.best is None:
            self._check()

    def _on_step(self) -> bool:
        if self.model.num_timesteps - self._last_eval >= self.eval_freq:
            self._check()
        return True

    def _on_training_end(self) -> None:
        if self.model.num_timesteps > self._last_eval:
            self._check()

    def restore(self) -> None:
        """Load the best policy seen into the model."""
        if self._best_state is not None:
            self.model.policy.load_state_dict(self._best_state)


def fine_tune(
    model: PPO,
    steps: int,
    *,
    critic_warmup: int = CRITIC_WARMUP,
    progress: bool = True,
    callback: BaseCallback | None = None,
    keep_best: KeepBestPolicy | None = None,
) -> PPO:
    """PPO fine-tuning of a cloned model on its env, the actor frozen at first.

    For the first ``critic_warmup`` steps only the critic learns (the actor's weights and
    ``log_std`` are frozen), so that the policy's first updates follow advantages of a
    value function fitted to its own rollouts, not only to the demonstrations.

    Args:
        model: a PPO model with an env (e.g. from
            :func:`ias_gym.learning.cloning.behaviour_clone` given a vec env).
        steps: environment steps in all (SB3 rounds each phase up to whole rollouts).
        critic_warmup: steps with the actor frozen.
        progress: show progress bars.
        callback: SB3 callback for both phases (e.g. :class:`WallClockLimit`).
        keep_best: validates after the warm-up and during the rest; at the end the model
            holds the best policy it saw (the cloned one included).

    Returns:
        ``model``, trained.
    """
    policy: Any = model.policy
    actor = [
        *policy.mlp_extractor.policy_net.parameters(),
        *policy.action_net.parameters(),
        policy.log_std,
    ]
    warmup = max(0, min(critic_warmup, steps))
    if warmup:
        for p in actor:
            p.requires_grad_(False)
        try:
            model.learn(warmup, callback=callback, progress_bar=progress)
        finally:
            for p in actor:
                p.requires_grad_(True)
    if steps > warmup:
        callbacks = [c for c in (callback, keep_best) if c is not None]
        model.learn(
            steps - warmup,
            callback=callbacks or None,
            progress_bar=progress,
            reset_num_timesteps=not warmup,
        )
        if keep_best is not None:
            keep_best.restore()
    return model
