"""The grip-transform controller as an expert policy with Stable-Baselines3's interface.

The expert is privileged: it reads the simulator (contacts, Jacobians, the task's reference),
not the observation. So it must run where the simulator is (docs/controller.md, "The expert
in vector envs"):

- one env, or a vector env whose envs live in this process (SB3's ``DummyVecEnv``,
  Gymnasium's ``SyncVectorEnv``): :class:`ExpertPolicy` reads them directly, all envs in one
  batched control step (:class:`BatchedExpert`);
- a process-based vector env (SB3's ``SubprocVecEnv``, Gymnasium's ``AsyncVectorEnv``): each
  worker's env is wrapped in :class:`ExpertActionWrapper`, which owns that env's controller;
  :class:`ExpertPolicy` asks every worker for its action with one
  ``env_method("expert_action")`` (SB3) or ``call("expert_action")`` (Gymnasium).

``predict`` follows SB3's convention: an observation of the env's shape gives one action, a
batch ``(n, obs_dim)`` gives ``(n, act_dim)`` actions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import gymnasium as gym
import numpy as np

from ias_gym.baselines.batch import batch_size
from ias_gym.baselines.grip_transform_control import (
    ControllerGains,
    GripTransformController,
    batch_torques,
)
from ias_gym.envs.pen_hand_env import FloatArray, PenHandEnv
from ias_gym.errors import InputError

#: The method :class:`ExpertActionWrapper` adds, called by name through a vector env.
EXPERT_ACTION = "expert_action"


def _pen_env(env: gym.Env[Any, Any]) -> PenHandEnv:
    unwrapped = env.unwrapped
    if not isinstance(unwrapped, PenHandEnv):
        raise TypeError(f"the expert controls IAS pen environments, got {type(unwrapped).__name__}")
    return unwrapped


class BatchedExpert:
    """The expert of ``n`` in-process pen envs, one batched control step for all of them.

    Each env keeps its own :class:`GripTransformController` (its memory and its internal-force
    solver); :func:`~ias_gym.baselines.grip_transform_control.batch_torques` reads every env
    and does the dense linear algebra of eq. (45) for all of them at once (numpy over the env
    axis). The actions equal those of ``n`` separate :class:`ExpertPolicy` objects.

    A controller also starts afresh when its env's clock went back since the last step (the
    env was reset, e.g. by a vector env's autoreset, and nobody said so): it never carries
    one episode's W, J and servo forces into the next.

    Args:
        envs: ``IAS-Pen*`` environments (wrappers are looked through), stepped by the caller.
        gains: controller gains (defaults tuned for the 10 ms control period).

    Raises:
        TypeError: an env is not an IAS pen environment.
    """

    def __init__(
        self, envs: Sequence[gym.Env[Any, Any]], gains: ControllerGains | None = None
    ) -> None:
        self.envs = [_pen_env(e) for e in envs]
        self.gains = gains or ControllerGains()
        self.controllers = [self._controller(e) for e in self.envs]
        self._times = [math.inf] * len(self.envs)  # env time [s] at the last step

    def _controller(self, env: PenHandEnv) -> GripTransformController:
        return GripTransformController(f0=env.config.min_grasp_force, gains=self.gains)

    def reset(self, index: int | None = None) -> None:
        """Forget the memory of env ``index``'s controller (``None``: all); at episode start."""
        for i in range(len(self.envs)) if index is None else (index,):
            self.controllers[i] = self._controller(self.envs[i])

    def actions(self) -> FloatArray:
        """``(n, act_dim)`` float32 actions (normalised torques) for the envs' current states."""
        for i, env in enumerate(self.envs):
            now = env.time
            if now < self._times[i]:  # reset since the last step
                self.controllers[i] = self._controller(env)
            self._times[i] = now
        tau = batch_torques(self.controllers, self.envs)
        ctrl_max = np.stack([e._ctrl_max for e in self.envs])
        return np.clip(tau / ctrl_max, -1.0, 1.0).astype(np.float32)


class ExpertActionWrapper(gym.Wrapper[Any, Any, Any, Any]):
    """Carries the expert with its env, for vector envs whose envs live in other processes.

    Apply it to each env where the env is made (SB3: ``make_vec_env(id, n,
    vec_env_cls=SubprocVecEnv, wrapper_class=ExpertActionWrapper)``; Gymnasium:
    ``gym.make_vec(id, n, vectorization_mode="async", wrappers=[ExpertActionWrapper])``).
    The wrapper owns the env's controller, resets it whenever the env resets (also an
    autoreset inside the vector env) and computes the expert's action for the current state
    on request: :meth:`expert_action`, called through the vector env by name
    (:class:`ExpertPolicy` does it). Observations, rewards and actions pass unchanged.

    Args:
        env: an ``IAS-Pen*`` environment.
        gains: controller gains (defaults tuned for the 10 ms control period).
    """

    def __init__(self, env: gym.Env[Any, Any], gains: ControllerGains | None = None) -> None:
        super().__init__(env)
        self._expert = BatchedExpert([env], gains)
        self._action: FloatArray | None = None

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        """Reset the env and the controller's memory (arguments as ``env.reset``)."""
        result = self.env.reset(**kwargs)
        self._expert.reset()
        self._action = None
        return result

    def step(self, action: Any) -> tuple[Any, Any, bool, bool, dict[str, Any]]:
        """Step the env (unchanged); the next :meth:`expert_action` is for the new state."""
        self._action = None
        return self.env.step(action)

    @property
    def controller(self) -> GripTransformController:
        """The env's controller (diagnostics: ``.last``, ``.infeasible_count``)."""
        return self._expert.controllers[0]

    def expert_action(self) -> FloatArray:
        """The expert's action ``(act_dim,)`` float32 for the env's current state.

        Computed once per state: the controller keeps the previous step's W and J for their
        rates, so a second call before the next step returns the same action.
        """
        if self._action is None:
            self._action = self._expert.actions()[0]
        return self._action.copy()


class ExpertPolicy:
    """``predict(obs) -> (action, None)`` from the grip-transform controller.

    The expert is privileged: it ignores the observation and reads the simulation state
    (contacts, Jacobians, the task's reference) of the env(s) it was built for; it acts only
    through the env's action (normalised torques). Use it with that env, stepping it with
    the returned actions.

    Args:
        env: an ``IAS-Pen*`` environment (wrappers are looked through), or a vector env of
            them: SB3's ``VecEnv`` (e.g. from ``make_vec_env``) or Gymnasium's
            ``VectorEnv``. Envs in this process are read directly; envs in worker processes
            must be wrapped in :class:`ExpertActionWrapper`.
        gains: controller gains (defaults tuned for the 10 ms control period).

    Raises:
        TypeError: the env (or a vector env's env) is not an IAS pen environment.
        InputError: a process-based vector env whose envs are not wrapped in
            :class:`ExpertActionWrapper`.
    """

    def __init__(self, env: Any, gains: ControllerGains | None = None) -> None:
        self.gains = gains or ControllerGains()
        #: The envs' actions on request, for envs in other processes (else ``None``).
        self._remote: Callable[[], Sequence[Any]] | None = None
        self._local: BatchedExpert | None = None
        self._single = not hasattr(env, "num_envs")
        self.num_envs = 1 if self._single else int(env.num_envs)
        if self._single:
            self.env = _pen_env(env)
            self._local = BatchedExpert([self.env], self.gains)
            self.observation_shape = tuple(env.observation_space.shape)
        else:
            self._connect(env)
            space = getattr(env, "single_observation_space", env.observation_space)
            self.observation_shape = tuple(space.shape)

    def _connect(self, venv: Any) -> None:
        """Find how to reach the vector env's simulators (see the module docstring)."""
        if hasattr(venv, "env_method"):  # SB3's VecEnv (and its VecEnvWrappers)
            if all(venv.env_is_wrapped(ExpertActionWrapper)):
                self._remote = lambda: venv.env_method(EXPERT_ACTION)
                return
            envs = getattr(venv, "envs", None)
        else:  # Gymnasium's VectorEnv
            envs = getattr(venv, "envs", None)
            if envs is None or all(_is_wrapped(e) for e in envs):
                self._remote = lambda: venv.call(EXPERT_ACTION)
                return
        if envs is None:
            raise InputError(
                f"{type(venv).__name__} runs its envs in other processes, where the expert "
                "must run too: wrap each env in ias_gym.baselines.expert.ExpertActionWrapper "
                "(SB3: make_vec_env(..., wrapper_class=ExpertActionWrapper); Gymnasium: "
                "gym.make_vec(..., wrappers=[ExpertActionWrapper]))"
            )
        self._local = BatchedExpert(envs, self.gains)

    def reset(self) -> None:
        """Forget the controllers' memory (last feasible forces); call at episode start.

        Envs wrapped in :class:`ExpertActionWrapper` reset their controller with the env.
        """
        if self._local is not None:
            self._local.reset()

    @property
    def controller(self) -> GripTransformController:
        """The controller of the (first) env in this process (diagnostics: ``.last``)."""
        if self._local is None:
            raise AttributeError("the controllers of a process-based vector env live there")
        return self._local.controllers[0]

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[FloatArray, None]:
        """The action(s) for the env's current state (SB3's signature).

        Args:
            observation: one observation (one action returned) or a batch ``(n, obs_dim)``
                (``(n, act_dim)`` returned); its values are unused.
            state: unused (SB3's recurrent state).
            episode_start: ``(n,)`` or scalar bool: reset those envs' controllers (envs in
                other processes reset their controller with the env itself).
            deterministic: unused (the expert is deterministic).

        Raises:
            InputError: the observation is neither one observation nor a batch of the vector
                env's size.
        """
        n = batch_size(observation, self.observation_shape)
        if (n or 1) != self.num_envs:
            raise InputError(f"a batch of {n} observations for an expert of {self.num_envs} env(s)")
        actions: np.ndarray
        if self._remote is not None:
            actions = np.stack([np.asarray(a, dtype=np.float32) for a in self._remote()])
        else:
            assert self._local is not None
            if episode_start is not None:
                starts = np.broadcast_to(np.asarray(episode_start, dtype=bool), self.num_envs)
                for i in np.flatnonzero(starts):
                    self._local.reset(int(i))
            actions = self._local.actions()
        result: FloatArray = actions if n is not None else actions[0]
        return result, None


def _is_wrapped(env: gym.Env[Any, Any]) -> bool:
    """Whether ``env`` has an :class:`ExpertActionWrapper` among its wrappers."""
    while isinstance(env, gym.Wrapper):
        if isinstance(env, ExpertActionWrapper):
            return True
        env = env.env
    return False
