"""SB3's ``VecEnv`` interface on the batched worker pool of :mod:`ias_gym.runtime.workers`.

:class:`BatchedVecEnv` is what ``SubprocVecEnv`` is to SB3, but with ``num_workers``
processes that each step a batch of envs, the data in shared memory (see
:class:`~ias_gym.runtime.workers.BatchedWorkers`): SB3's algorithms, ``evaluate_policy`` and
its wrappers (``VecNormalize``, ...) use it as any ``VecEnv``. SB3's conventions hold: an
episode that ends is reset in the same step, its last observation is in
``infos[i]["terminal_observation"]``, ``infos[i]["TimeLimit.truncated"]`` tells a
truncation, and ``seed(s)`` seeds env ``i`` with ``s + i`` at the next ``reset``.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode
from stable_baselines3.common.vec_env.base_vec_env import (
    VecEnv,
    VecEnvIndices,
    VecEnvObs,
    VecEnvStepReturn,
)

from ias_gym.runtime.workers import BatchedWorkers


class BatchedVecEnv(VecEnv):
    """An SB3 ``VecEnv`` of ``len(env_fns)`` envs stepped in batches by worker processes.

    Args:
        env_fns: one function per env that builds it (run in the worker; closures work).
        num_workers: worker processes (default: ``min(len(env_fns), os.cpu_count())``).
        context: multiprocessing start method (default ``"forkserver"`` where there is one,
            as SB3's ``SubprocVecEnv``: a forked child of a process running torch threads
            can hang).
        timeout: longest wait for a worker's reply [s] (``None``: no limit).

    Raises:
        ~ias_gym.errors.InputError: no envs, or ``num_workers`` outside ``1..len(env_fns)``.
        ~ias_gym.errors.WorkerError: a worker could not build its envs, died, or
            timed out.
    """

    def __init__(
        self,
        env_fns: Sequence[Callable[[], gym.Env[Any, Any]]],
        num_workers: int | None = None,
        *,
        context: str | None = None,
        timeout: float | None = None,
    ) -> None:
        if context is None:
            import multiprocessing as mp

            context = "forkserver" if "forkserver" in mp.get_all_start_methods() else "spawn"
        self.workers = BatchedWorkers(
            env_fns,
            num_workers,
            context=context,
            autoreset_mode=AutoresetMode.SAME_STEP,
            timeout=timeout,
        )
        self.num_workers = self.workers.num_workers
        self._actions: Any = None
        super().__init__(
            self.workers.num_envs,
            self.workers.single_observation_space,
            self.workers.single_action_space,
        )

    def reset(self) -> VecEnvObs:
        """Reset every env (with the seeds and options set since the last reset)."""
        options = [opts or None for opts in self._options]
        infos = self.workers.reset(self._seeds, options)
        self.reset_infos = [dict(info or {}) for info in infos]
        self._reset_seeds()
        self._reset_options()
        return self._observations()

    def step_async(self, actions: np.ndarray) -> None:
        """Keep the actions for :meth:`step_wait` (the workers step them there)."""
        self._actions = actions

    def step_wait(self) -> VecEnvStepReturn:
        """Step every env; an env whose episode ends is reset (SB3's convention)."""
        w = self.workers
        results = w.step(self._actions)
        terminated, truncated = w.terminations.copy(), w.truncations.copy()
        infos: list[dict[str, Any]] = []
        for i, (final, info) in enumerate(results):
            if final is not None:  # the episode ended: info is the new episode's reset info
                self.reset_infos[i] = info
                info = dict(final["final_info"])
                info["terminal_observation"] = final["final_obs"]
            else:
                info = dict(info)
            info["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            infos.append(info)
        # float32 rewards, as SB3's DummyVecEnv (its rollout buffers store float32)
        rewards = w.rewards.astype(np.float32)
        return self._observations(), rewards, terminated | truncated, infos

    def _observations(self) -> VecEnvObs:
        obs: VecEnvObs = copy.deepcopy(self.workers.observations)
        return obs

    def close(self) -> None:
        """Close the envs and end the workers."""
        self.workers.close()

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """Attribute ``attr_name`` of the envs ``indices`` (through their wrappers)."""
        return self.workers.get_attr(attr_name, list(self._get_indices(indices)))

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set attribute ``attr_name`` of the envs ``indices`` to ``value``."""
        idx = list(self._get_indices(indices))
        self.workers.set_attr(attr_name, [value] * len(idx), idx)

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        """Call method ``method_name`` of the envs ``indices``; their results."""
        return self.workers.call(
            method_name, method_args, method_kwargs, list(self._get_indices(indices))
        )

    def env_is_wrapped(
        self, wrapper_class: type[gym.Wrapper[Any, Any, Any, Any]], indices: VecEnvIndices = None
    ) -> list[bool]:
        """Whether the envs ``indices`` have a ``wrapper_class`` wrapper."""
        return self.workers.is_wrapped(wrapper_class, list(self._get_indices(indices)))

    def get_images(self) -> Sequence[np.ndarray | None]:
        """Each env's ``render()`` frame (``rgb_array`` mode)."""
        return list(self.workers.call("render"))
