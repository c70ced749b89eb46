"""A vector env that scales with the cores: each worker process steps a batch of envs.

Gymnasium's ``AsyncVectorEnv`` and SB3's ``SubprocVecEnv`` run one env per process and pay
one pipe round trip (pickle, write, wake the process, read, pickle back) per env and step.
An ``IAS-*`` step costs about 0.35 ms, and on a busy machine the round trip costs as much
(measured in ``bench/bench_vector.py``: one async env steps at about half the rate of a
plain one). :class:`BatchedVectorEnv` puts ``num_envs`` envs into ``num_workers`` processes
(a vector of vectors): each worker steps its contiguous batch of envs in turn; observations,
actions, rewards and the termination flags live in shared memory, and each batch step is one
small pipe message per worker (the command out, the envs' ``info`` dicts back). With as many
workers as cores the round trip is paid once per batch instead of once per env.

Written here, not taken from a library: Gymnasium's and SB3's process vector envs hold one
env per process, and EnvPool (which batches in C++) runs only its own C++ envs.

Semantics are those of Gymnasium's ``SyncVectorEnv``: sub-env ``i`` of ``reset(seed=s)`` is
seeded ``s + i``, the same ``autoreset_mode`` choices (next step by default, same step,
disabled), ``options={"reset_mask": mask}``, and the same ``info`` layout. Run on the same
seeds and actions, sub-env ``i`` gives exactly the trajectory of a single env seeded
``s + i`` (``tests/test_vector.py``). Actions are stored in the action space's dtype (as
elements of that space).

:class:`~ias_gym.runtime.workers.BatchedWorkers` is the process pool itself, returning
per-env ``info`` dicts; the SB3 ``VecEnv`` adapter (:mod:`ias_gym.runtime.sb3_vec_env`)
builds on it.
"""

from __future__ import annotations

import copy
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space
from numpy.typing import NDArray

from ias_gym.errors import InputError
from ias_gym.runtime.workers import BatchedWorkers, EnvFn


class BatchedVectorEnv(VectorEnv[Any, Any, Any]):
    """Gymnasium ``VectorEnv`` of ``len(env_fns)`` envs stepped in batches by worker processes.

    Behaves as Gymnasium's ``SyncVectorEnv`` (same results, seeds, autoreset and ``info``
    layout), with each of ``num_workers`` processes stepping a contiguous batch of envs and
    the data moving through shared memory (:class:`BatchedWorkers`).

    Args:
        env_fns: one function per env that builds it (see :class:`BatchedWorkers`).
        num_workers: worker processes (default: ``min(len(env_fns), os.cpu_count())``).
        context: multiprocessing start method (default: the platform's).
        autoreset_mode: Gymnasium's autoreset convention (default: next step).
        copy: return copies of the observations (``False``: a view of the shared memory
            that the next ``step`` or ``reset`` overwrites).
        timeout: longest wait for a worker's reply [s] (``None``: no limit).

    Raises:
        InputError: no envs, or ``num_workers`` outside ``1..len(env_fns)``.
        WorkerError: a worker could not build its envs, died, or timed out.
    """

    def __init__(
        self,
        env_fns: Sequence[EnvFn],
        num_workers: int | None = None,
        *,
        context: str | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        copy: bool = True,
        timeout: float | None = None,
    ) -> None:
        self.workers = BatchedWorkers(
            env_fns, num_workers, context=context, autoreset_mode=autoreset_mode, timeout=timeout
        )
        w = self.workers
        self.num_envs = w.num_envs
        self.num_workers = w.num_workers
        self.autoreset_mode = w.autoreset_mode
        self.copy = copy
        self.metadata = {**w.metadata, "autoreset_mode": w.autoreset_mode}
        self.render_mode = w.render_mode
        self.spec = w.spec
        self.single_observation_space = w.single_observation_space
        self.single_action_space = w.single_action_space
        self.observation_space = batch_space(w.single_observation_space, w.num_envs)
        self.action_space = w.batched_action_space

    def reset(
        self,
        *,
        seed: int | Sequence[int | None] | None = None,
        options: dict[str, Any] | None = None,
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the sub-envs; sub-env ``i`` is seeded ``seed + i`` (or ``seed[i]``).

        Args:
            seed: ``None``, an int, or one seed per sub-env.
            options: passed to every sub-env; ``options["reset_mask"]`` (a ``(num_envs,)``
                bool array) resets only those sub-envs.

        Returns:
            The batched observations and infos.

        Raises:
            ValueError: a seed list or ``reset_mask`` of the wrong length.
        """
        n = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * n
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
        if len(seeds) != n:
            raise ValueError(f"{len(seeds)} seeds for {n} envs: give one per sub-env")
        mask = None
        if options is not None and "reset_mask" in options:
            options = dict(options)
            mask = np.asarray(options.pop("reset_mask"))
            if mask.shape != (n,) or mask.dtype != np.bool_ or not mask.any():
                raise ValueError(
                    f"options['reset_mask'] must be a bool array of shape ({n},) with at "
                    f"least one True, got {mask!r}"
                )
        infos: dict[str, Any] = {}
        for i, info in enumerate(self.workers.reset(seeds, options, mask)):
            if info is not None:
                infos = self._add_info(infos, info, i)
        return self._observations(), infos

    def step(
        self, actions: Any
    ) -> tuple[Any, NDArray[np.float64], NDArray[np.bool_], NDArray[np.bool_], dict[str, Any]]:
        """Step every sub-env (a sub-env whose episode ended last step is reset instead, in
        next-step mode); returns the batched observations, rewards, terminations,
        truncations and infos.

        Raises:
            ValueError: actions of the wrong shape; an env's own errors are raised with
                their type (their worker's traceback in the notes).
        """
        infos: dict[str, Any] = {}
        for i, (final, info) in enumerate(self.workers.step(actions)):
            if final is not None:
                infos = self._add_info(infos, final, i)
            infos = self._add_info(infos, info, i)
        w = self.workers
        return (
            self._observations(),
            w.rewards.copy(),
            w.terminations.copy(),
            w.truncations.copy(),
            infos,
        )

    def _observations(self) -> Any:
        obs = self.workers.observations
        return copy.deepcopy(obs) if self.copy else obs

    def render(self) -> tuple[Any, ...] | None:
        """Each sub-env's ``render()`` (the frames of ``rgb_array`` mode)."""
        return tuple(self.workers.call("render"))

    def call(self, name: str, *args: Any, **kwargs: Any) -> tuple[Any, ...]:
        """Call method ``name`` of every sub-env (or read the attribute if not callable)."""
        return tuple(self.workers.call(name, args, kwargs))

    def get_attr(self, name: str) -> tuple[Any, ...]:
        """Attribute ``name`` of every sub-env."""
        return tuple(self.workers.get_attr(name))

    def set_attr(self, name: str, values: list[Any] | tuple[Any, ...] | object) -> None:
        """Set attribute ``name`` of the sub-envs: one value each (a list or tuple) or the
        same value for all."""
        if not isinstance(values, list | tuple):
            values = [values] * self.num_envs
        self.workers.set_attr(name, list(values))

    def __enter__(self) -> BatchedVectorEnv:
        """``with make_batched_vec(...) as vec:`` closes the workers at the end."""
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close_extras(self, terminate: bool = False, **kwargs: Any) -> None:
        """End the workers (see :meth:`BatchedWorkers.close`)."""
        self.workers.close(terminate=terminate, **kwargs)


def make_batched_vec(
    env_id: str,
    num_envs: int,
    num_workers: int | None = None,
    *,
    context: str | None = None,
    autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
    wrappers: Sequence[Callable[[gym.Env[Any, Any]], gym.Env[Any, Any]]] = (),
    copy: bool = True,
    timeout: float | None = None,
    **env_kwargs: Any,
) -> BatchedVectorEnv:
    """``num_envs`` copies of a registered env in ``num_workers`` processes (batched).

    The counterpart of ``gym.make_vec(env_id, num_envs, vectorization_mode="async")`` that
    scales where the per-step pipe round trip dominates (module docstring).

    Args:
        env_id: a registered id (``import ias_gym`` registers the ``IAS-*`` ones).
        num_envs: number of sub-envs.
        num_workers: worker processes (default: ``min(num_envs, os.cpu_count())``).
        context: multiprocessing start method (default: the platform's).
        autoreset_mode: Gymnasium's autoreset convention (default: next step).
        wrappers: applied to each sub-env after ``gym.make``, in order.
        copy: return copies of the observations.
        timeout: longest wait for a worker's reply [s].
        **env_kwargs: passed to ``gym.make`` (the env's configuration).

    Returns:
        The vector env (close it, or use it as a context manager).

    Raises:
        InputError: ``num_envs < 1`` or ``num_workers`` outside ``1..num_envs``.
    """
    if num_envs < 1:
        raise InputError(f"num_envs must be >= 1, got {num_envs}")
    fn = _EnvFactory(env_id, dict(env_kwargs), tuple(wrappers))
    return BatchedVectorEnv(
        [fn] * num_envs,
        num_workers,
        context=context,
        autoreset_mode=autoreset_mode,
        copy=copy,
        timeout=timeout,
    )


class _EnvFactory:
    """``gym.make(env_id, **env_kwargs)`` plus wrappers, as a picklable callable."""

    def __init__(self, env_id: str, env_kwargs: dict[str, Any], wrappers: tuple[Any, ...]):
        self.env_id, self.env_kwargs, self.wrappers = env_id, env_kwargs, wrappers

    def __call__(self) -> gym.Env[Any, Any]:
        # (In a spawned worker, unpickling this class imported ias_gym: the ids are there.)
        env: gym.Env[Any, Any] = gym.make(self.env_id, **self.env_kwargs)
        for wrapper in self.wrappers:
            env = wrapper(env)
        return env
