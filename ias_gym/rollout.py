"""One episode of a policy in an env: :func:`rollout` and the :class:`Trajectory` it returns.

Every episode loop of the package runs here: evaluation, skill recording, skill transfer,
the assisting sessions, the figures, the completion table, the observation statistics and
the fine-tuning's validation. A policy is anything with Stable-Baselines3's ``predict``
(:class:`Policy`); other drivers are adapted where they are used (an assistant that acts on
the env: :class:`~ias_gym.assist.sessions.AssistantPolicy`; a plain function of the
observation: :class:`FunctionPolicy`). What a loop needs beyond the trajectory (a skill
model sampled from the physics, video frames: :class:`FrameRecorder`) it does in the hooks
``on_reset`` and ``on_step``.

Example::

    import gymnasium as gym
    import ias_gym
    from ias_gym.baselines.policies import load_policy
    from ias_gym.rollout import rollout

    env = gym.make("IAS-PenSlide-v0")
    trajectory = rollout(env, load_policy("expert", env), seed=0)
    trajectory.episode_return, trajectory.is_success  # the rewards' sum, the last info's
    trajectory.observations.shape  # (T + 1, 67): the reset observation, then one per step
    trajectory.actions.shape  # (T, 12)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import gymnasium as gym
import numpy as np
from numpy.typing import DTypeLike, NDArray

from ias_gym.errors import (
    RolloutError,
)

#: ``on_reset(env, observation, info)``: called once, after ``env.reset``.
ResetHook = Callable[[gym.Env[Any, Any], Any, dict[str, Any]], None]
#: ``on_step(env, observation, action, reward, info)``: called after every ``env.step``
#: with what it returned and the action it was given.
StepHook = Callable[[gym.Env[Any, Any], Any, NDArray[Any], float, dict[str, Any]], None]


@runtime_checkable
class Policy(Protocol):
    """Stable-Baselines3's policy interface: what :func:`rollout` calls."""

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """The action for ``observation`` and the policy's next ``state``.

        Args:
            observation: the env's observation, or a batch ``(n, *obs_shape)`` from a vector
                env (then the actions are ``(n, *act_shape)``).
            state: the state the previous call returned (``None`` at an episode's start).
            episode_start: true on the first step of an episode (a stateful policy resets).
            deterministic: act deterministically (SB3: the mode of the distribution).
        """
        ...


@dataclass(frozen=True)
class FunctionPolicy:
    """A function of the observation as a :class:`Policy` (stateless).

    Attributes:
        function: ``observation -> action``.
    """

    function: Callable[[Any], Any]

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[Any, Any]:
        """``(function(observation), state)`` (SB3's signature)."""
        return self.function(observation), state


@dataclass
class FrameRecorder:
    """Hooks of :func:`rollout` that collect ``env.render()``: after the reset and after
    every ``stride``-th step (a ``None`` frame is skipped).

    Attributes:
        stride: render every this many steps (>= 1).
        frames: the frames so far (appended to).
    """

    stride: int = 1
    frames: list[NDArray[Any]] = field(default_factory=list)
    _steps: int = 0

    def on_reset(self, env: gym.Env[Any, Any], observation: Any, info: dict[str, Any]) -> None:
        """Render the reset state (the ``on_reset`` hook)."""
        self._steps = 0
        self._grab(env)

    def on_step(
        self,
        env: gym.Env[Any, Any],
        observation: Any,
        action: NDArray[Any],
        reward: float,
        info: dict[str, Any],
    ) -> None:
        """Render after every ``stride``-th step (the ``on_step`` hook)."""
        self._steps += 1
        if self._steps % self.stride == 0:
            self._grab(env)

    def _grab(self, env: gym.Env[Any, Any]) -> None:
        frame = env.render()
        if frame is not None:
            self.frames.append(np.asarray(frame))


@dataclass(frozen=True, eq=False)
class Trajectory:
    """One episode (Minari's layout: ``T`` steps, ``T + 1`` observations and infos).

    Attributes:
        actions: ``(T, *action_shape)``: the actions passed to ``env.step``.
        rewards: ``(T,)`` float64.
        terminations, truncations: ``(T,)`` bool; only the last step may be true (both
            false there too when ``max_steps`` cut the episode).
        final_observation: the last observation (the reset one if ``T = 0``).
        final_info: the last info (the reset one if ``T = 0``).
        episode_return: the sum of the rewards, added up step by step in order.
        seed: the reset seed.
        observations: ``(T + 1, *obs_shape)``: the reset observation, then one per step
            (``None``: not kept).
        infos: ``T + 1`` dicts: the reset info, then each step's (``None``: not kept).
    """

    actions: NDArray[Any]
    rewards: NDArray[np.float64]
    terminations: NDArray[np.bool_]
    truncations: NDArray[np.bool_]
    final_observation: Any
    final_info: dict[str, Any]
    episode_return: float
    seed: int | None
    observations: NDArray[Any] | None = None
    infos: tuple[dict[str, Any], ...] | None = None

    @property
    def length(self) -> int:
        """Number of steps T."""
        return len(self.rewards)

    @property
    def is_success(self) -> bool:
        """The last info's ``is_success`` (False if it has none)."""
        return bool(self.final_info.get("is_success", False))

    @property
    def terminated(self) -> bool:
        """The episode ended in a terminal state (its last step's ``terminated``)."""
        return bool(self.length and self.terminations[-1])

    @property
    def truncated(self) -> bool:
        """The env truncated the episode (its last step's ``truncated``)."""
        return bool(self.length and self.truncations[-1])

    @property
    def done(self) -> bool:
        """The env ended the episode (not ``max_steps``)."""
        return self.terminated or self.truncated


def rollout(
    env: gym.Env[Any, Any],
    policy: Policy,
    seed: int | None,
    *,
    reset_options: Mapping[str, Any] | None = None,
    max_steps: int | None = None,
    deterministic: bool = True,
    action_dtype: DTypeLike | None = None,
    keep_observations: bool = True,
    keep_infos: bool = True,
    on_reset: ResetHook | None = None,
    on_step: StepHook | None = None,
) -> Trajectory:
    """Run one episode of ``policy`` from ``env.reset(seed=seed, options=reset_options)``.

    The first ``predict`` gets ``state=None`` and ``episode_start=True`` (a stateful policy,
    such as the expert's controller, starts afresh); every later one gets the state the
    previous call returned and ``episode_start=False``. The episode runs until the env
    terminates or truncates it, or for ``max_steps`` steps.

    Args:
        env: the env (wrappers allowed; not closed here).
        policy: an object with SB3's ``predict`` (:class:`Policy`).
        seed: the reset seed (``None``: unseeded).
        reset_options: ``options`` of ``env.reset`` (copied).
        max_steps: stop after this many steps (>= 0) even if the env has not ended the
            episode (``None``: no limit).
        deterministic: passed to ``predict``.
        action_dtype: cast each action to this dtype before the step (``None``: step with
            the policy's own values and dtype).
        keep_observations: keep every observation (``False``: only the last, to save
            memory when only the returns are needed).
        keep_infos: keep every info (``False``: only the last).
        on_reset: called after the reset, ``on_reset(env, observation, info)``.
        on_step: called after every step, ``on_step(env, observation, action, reward,
            info)`` with the step's results and the action it was given.

    Returns:
        The :class:`Trajectory`.

    Raises:
        TypeError: ``policy`` has no ``predict``.
        ValueError: ``max_steps`` < 0.
        RolloutError: ``predict`` returned something other than ``(action, state)``, or an
            action that is not numeric or not of the action space's shape.
    """
    if not isinstance(policy, Policy):
        raise TypeError(
            f"policy must have Stable-Baselines3's predict(observation, state, episode_start, "
            f"deterministic), got {type(policy).__name__}; wrap a function of the observation "
            "in ias_gym.rollout.FunctionPolicy"
        )
    if max_steps is not None and max_steps < 0:
        raise ValueError(f"max_steps must be >= 0 or None, got {max_steps}")
    options = dict(reset_options) if reset_options is not None else None
    obs, info = env.reset(seed=seed, options=options)
    if on_reset is not None:
        on_reset(env, obs, info)
    shape = env.action_space.shape
    observations: list[Any] = [_kept(obs)] if keep_observations else []
    infos: list[dict[str, Any]] = [info] if keep_infos else []
    actions: list[NDArray[Any]] = []
    rewards: list[float] = []
    terminations: list[bool] = []
    truncations: list[bool] = []
    total = 0.0
    state: Any = None
    done = False
    while not done and (max_steps is None or len(actions) < max_steps):
        out = policy.predict(
            obs, state=state, episode_start=not actions, deterministic=deterministic
        )
        if not (isinstance(out, tuple) and len(out) == 2):
            raise RolloutError(
                f"{type(policy).__name__}.predict must return (action, state) as "
                f"Stable-Baselines3's does, got {type(out).__name__}"
            )
        raw, state = out
        action = _action(raw, action_dtype, shape, len(actions), policy)
        obs, reward, terminated, truncated, info = env.step(action)
        reward = float(reward)
        total += reward
        if on_step is not None:
            on_step(env, obs, action, reward, info)
        if keep_observations:
            observations.append(_kept(obs))
        if keep_infos:
            infos.append(info)
        actions.append(action)
        rewards.append(reward)
        terminations.append(bool(terminated))
        truncations.append(bool(truncated))
        done = bool(terminated or truncated)
    action_shape = shape if shape is not None else ()
    return Trajectory(
        actions=np.stack(actions) if actions else np.zeros((0, *action_shape)),
        rewards=np.asarray(rewards, dtype=np.float64),
        terminations=np.asarray(terminations, dtype=bool),
        truncations=np.asarray(truncations, dtype=bool),
        final_observation=obs,
        final_info=info,
        episode_return=total,
        seed=seed,
        observations=np.stack(observations) if keep_observations else None,
        infos=tuple(infos) if keep_infos else None,
    )


def _kept(observation: Any) -> Any:
    """A copy of an array observation (an env may reuse its buffer), else the object."""
    return observation.copy() if isinstance(observation, np.ndarray) else observation


def _action(
    raw: Any,
    dtype: DTypeLike | None,
    shape: tuple[int, ...] | None,
    step: int,
    policy: Policy,
) -> NDArray[Any]:
    """``raw`` as a fresh array (of ``dtype``), checked against the action space's shape."""
    try:
        action = np.array(raw, dtype=dtype)
    except (TypeError, ValueError) as exc:
        raise RolloutError(
            f"step {step}: {type(policy).__name__} returned an action that is not an array of "
            f"numbers ({type(raw).__name__}: {exc})"
        ) from None
    if action.dtype.kind not in "biuf":
        raise RolloutError(
            f"step {step}: {type(policy).__name__} returned an action of dtype {action.dtype}, "
            "not numbers"
        )
    if shape is not None and action.shape != shape:
        raise RolloutError(
            f"step {step}: {type(policy).__name__} returned an action of shape {action.shape}, "
            f"the env's action space needs {shape}"
        )
    return action


__all__ = [
    "FrameRecorder",
    "FunctionPolicy",
    "Policy",
    "ResetHook",
    "RolloutError",
    "StepHook",
    "Trajectory",
    "rollout",
]
