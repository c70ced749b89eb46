"""The analytic expert's labels for DAgger: the shadow expert, the labelled episodes and
the aggregated dataset of (observation, expert action) pairs.

**How the expert labels a state.** :class:`~ias_gym.baselines.expert.ExpertPolicy` is
privileged and stateful: it ignores the observation, reads the simulator (contacts,
Jacobians, the task's reference) and keeps a memory along the episode (the last feasible
internal forces, the servo forces it commanded the step before, the previous grasp and
hand Jacobians for their rates). So it cannot label an isolated stored observation
afterwards; it labels the states *while they are visited*: :class:`ShadowExpert` runs the
expert "in the shadow" of every step, on the same env, whatever acts. Its memory then
follows the visited trajectory (what it would have commanded there, not what was
executed), which is the standard way with a stateful teacher. A label is the expert's
clean action: the env's action noise and delay act after it, its observation noise is in
the measurements the expert reads too.

**Which labels teach.** A label is kept only where the expert's grasp model holds: its
internal-force problem had a solution at that state. Where it has none (no finger touches
the pen, or the contacts cannot carry the pen's wrench: the pen is falling), the expert
has no action for the state; its controller then asks for torques at the actuators' limits,
labels hundreds of standard deviations from every other, and in a squared-error fit a
handful of them outweigh all the rest (measured: the 9 unheld states of one dropped
episode, 0.03 % of a DAgger dataset, took the clone from 8 of 8 nominal episodes to 0).

:func:`collect_episode` runs one episode of the mixture of expert and learner under drawn
dynamics (:func:`~ias_gym.learning.randomised_dynamics.episode_dynamics`) with the expert
labelling every state; :func:`expert_dataset` collects expert rollouts only, the
behaviour-cloning baseline of a DAgger run with as many labels; :class:`Dataset` holds the
aggregated pairs.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.envs.pen_hand_env import PenHandEnv
from ias_gym.errors import InputError
from ias_gym.learning.randomised_dynamics import (
    DEFAULT_RANDOMISATION,
    EpisodeDynamics,
    Randomisation,
    episode_dynamics,
)
from ias_gym.rollout import Policy, Trajectory, rollout

FloatArray = NDArray[np.float32]


class ShadowExpert:
    """The rollout policy of a DAgger episode: the expert labels every step, the mixture acts.

    Every ``predict`` first asks the expert for its action on the env's current state (the
    label, stepping the expert's memory along the visited trajectory), then acts with it
    with probability ``beta`` and with the learner's action otherwise (a coin per step).

    Args:
        env: the pen env the episode runs in (the expert reads its simulator).
        learner: the learner (SB3's ``predict``); ``None``: the expert always acts.
        beta: probability that the expert acts on a step [-].
        seed: seeds the coins and the noise.
        expert_noise: sigma of Gaussian noise added to the expert's action when it is the
            one executed (noise injection, DART: Laskey et al. 2017; the label stays clean)
            [normalised torque].
        takeover: where the learner's action differs from the label by more than this in
            any joint, the expert acts whatever the coin says (the gate of HG-DAgger, Kelly
            et al. 2019, and SafeDAgger, Zhang & Cho 2017): the episode keeps to states the
            expert can still recover from, and their labels are the recoveries the learner
            lacks; ``None``: no gate [normalised torque].

    Attributes:
        observations: the observations labelled, one per step (what ``predict`` was given).
        labels: the expert's actions on them.
        expert_acted: per step, whether the expert's action was the one executed.
        held: per step, whether the expert's grasp model held (its internal-force problem
            had a solution); a label where it did not teaches nothing (module docstring).
    """

    def __init__(
        self,
        env: gym.Env[Any, Any],
        learner: Policy | None,
        beta: float,
        seed: int = 0,
        expert_noise: float = 0.0,
        takeover: float | None = None,
    ) -> None:
        if not 0.0 <= beta <= 1.0:
            raise InputError(f"beta must be in [0, 1], got {beta}")
        if not (math.isfinite(expert_noise) and expert_noise >= 0):
            raise InputError(f"expert_noise must be finite and >= 0, got {expert_noise}")
        if takeover is not None and not (math.isfinite(takeover) and takeover > 0):
            raise InputError(f"takeover must be finite and > 0, got {takeover}")
        if learner is None and beta < 1.0:
            raise InputError("without a learner the expert must always act (beta = 1)")
        self.expert = ExpertPolicy(env)
        self.learner = learner
        self.beta = float(beta)
        self.expert_noise = float(expert_noise)
        self.takeover = takeover
        self._rng = np.random.default_rng([seed, 0xC01])
        self.observations: list[NDArray[Any]] = []
        self.labels: list[FloatArray] = []
        self.expert_acted: list[bool] = []
        self.held: list[bool] = []

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[Any], Any]:
        """The executed action for ``observation`` (SB3's signature); records the label."""
        label, _ = self.expert.predict(observation, episode_start=episode_start)
        self.observations.append(np.array(observation, copy=True))
        self.labels.append(np.asarray(label, dtype=np.float32).copy())
        last = self.expert.controller.last
        self.held.append(last is not None and bool(last.feasible))
        expert_acts = self.learner is None or bool(self._rng.random() < self.beta)
        action = None
        gated = False
        if self.learner is not None and (not expert_acts or self.takeover is not None):
            action, state = self.learner.predict(
                observation, state=state, episode_start=episode_start, deterministic=True
            )
            if self.takeover is not None:
                gated = bool(np.max(np.abs(np.asarray(action) - label)) > self.takeover)
        expert_acts = expert_acts or gated
        self.expert_acted.append(expert_acts)
        if expert_acts:
            if self.expert_noise:
                noise = self._rng.normal(0.0, self.expert_noise, np.shape(label))
                return np.clip(label + noise, -1.0, 1.0).astype(np.float32), state
            return label, state
        return np.asarray(action), state


@dataclass
class Dataset:
    """The aggregated (observation, expert action) pairs.

    Attributes:
        observations: ``(N, obs_dim)``.
        actions: ``(N, act_dim)`` the expert's labels [normalised torque].
    """

    observations: NDArray[np.float64]
    actions: FloatArray

    @classmethod
    def empty(cls, obs_dim: int, act_dim: int) -> Dataset:
        """No pairs yet."""
        return cls(np.zeros((0, obs_dim)), np.zeros((0, act_dim), dtype=np.float32))

    def __len__(self) -> int:
        return len(self.actions)

    def extend(self, observations: NDArray[Any], actions: NDArray[Any]) -> None:
        """Append pairs (aggregation)."""
        self.observations = np.concatenate([self.observations, np.asarray(observations)])
        self.actions = np.concatenate([self.actions, np.asarray(actions, dtype=np.float32)])


@dataclass(frozen=True)
class LabelledEpisode:
    """One collected episode.

    Attributes:
        dynamics: what it ran under.
        trajectory: the rollout.
        observations: ``(T, obs_dim)`` the visited observations (the trajectory's but the last).
        labels: ``(T, act_dim)`` the expert's actions on them.
        expert_fraction: fraction of steps the expert's action was executed [-].
        held: ``(T,)`` whether the expert's grasp model held at each state
            (:class:`ShadowExpert`); :meth:`teaching_pairs` keeps those.
    """

    dynamics: EpisodeDynamics
    trajectory: Trajectory
    observations: NDArray[np.float64]
    labels: FloatArray
    expert_fraction: float
    held: NDArray[np.bool_]

    def teaching_pairs(self) -> tuple[NDArray[np.float64], FloatArray]:
        """The (observation, label) pairs of the states where the expert's grasp model held."""
        return self.observations[self.held], self.labels[self.held]


def collect_episode(
    env_id: str,
    dynamics: EpisodeDynamics,
    learner: Policy | None,
    beta: float,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    expert_noise: float = 0.0,
    takeover: float | None = None,
) -> LabelledEpisode:
    """Run one episode of the mixture under ``dynamics``, the expert labelling every state.

    Args:
        env_id: a pen task.
        dynamics: the env kwargs and reset seed
            (:func:`~ias_gym.learning.randomised_dynamics.episode_dynamics`).
        learner: the learner (``None``: the expert acts alone, ``beta`` must be 1).
        beta: probability the expert acts on a step [-].
        env_kwargs: further env kwargs (the drawn ones win).
        expert_noise: noise on the expert's executed actions (:class:`ShadowExpert`).
        takeover: the gate of :class:`ShadowExpert` (``None``: none) [normalised torque].

    Returns:
        The episode with its labels.
    """
    env = gym.make(env_id, **{**dict(env_kwargs or {}), **dynamics.env_kwargs})
    try:
        shadow = ShadowExpert(env, learner, beta, dynamics.seed, expert_noise, takeover)
        trajectory = rollout(env, shadow, dynamics.seed, action_dtype=np.float32, keep_infos=False)
    finally:
        env.close()
    obs_dim = int(np.prod(env.observation_space.shape or ()))
    observations = np.asarray(shadow.observations, dtype=np.float64).reshape(-1, obs_dim)
    labels = np.asarray(shadow.labels, dtype=np.float32).reshape(len(observations), -1)
    fraction = float(np.mean(shadow.expert_acted)) if shadow.expert_acted else 1.0
    held = np.asarray(shadow.held, dtype=bool).reshape(len(observations))
    return LabelledEpisode(dynamics, trajectory, observations, labels, fraction, held)


def check_pen_task(env_id: str) -> None:
    """Raise :class:`~ias_gym.errors.InputError` unless ``env_id`` is a pen task with an expert.

    Raises:
        InputError: an unknown id, or an env that is not an ``IAS-Pen*`` task.
    """
    try:
        spec = gym.spec(env_id)
    except gym.error.Error:
        raise InputError(
            f"unknown env id {env_id!r}; the expert labels pen tasks such as "
            "IAS-PenSlide-v0 or IAS-PenRotate-v0"
        ) from None
    entry = spec.entry_point
    env_class = gym.envs.registration.load_env_creator(entry) if isinstance(entry, str) else entry
    if not (isinstance(env_class, type) and issubclass(env_class, PenHandEnv)):
        raise InputError(
            f"{env_id} is not a pen task (the analytic expert controls IAS-PenSlide-v0 and "
            "IAS-PenRotate-v0 only)"
        )


def expert_dataset(
    env_id: str,
    labels: int,
    seed: int = 0,
    *,
    randomisation: Randomisation = DEFAULT_RANDOMISATION,
    env_kwargs: Mapping[str, Any] | None = None,
    expert_noise: float = 0.0,
    progress: bool = True,
) -> tuple[Dataset, list[LabelledEpisode]]:
    """Expert rollouts under the training dynamics, cut at exactly ``labels`` pairs.

    The behaviour-cloning baseline of a DAgger run with the same number of expert labels:
    episode ``k`` runs under
    :func:`~ias_gym.learning.randomised_dynamics.episode_dynamics` ``(seed, k)``, as
    DAgger's do.

    Args:
        env_id: a pen task.
        labels: pairs wanted (>= 1).
        seed: the run's seed (>= 0).
        randomisation: the ranges of the dynamics.
        env_kwargs: further env kwargs of every episode.
        expert_noise: noise on the expert's executed actions, labels clean (DART).
        progress: a progress bar over the pairs.

    Returns:
        The dataset and the episodes it came from.
    """
    check_pen_task(env_id)
    if labels < 1:
        raise InputError(f"labels must be >= 1, got {labels}")
    probe = gym.make(env_id, **dict(env_kwargs or {}))
    dataset = Dataset.empty(
        int(np.prod(probe.observation_space.shape or ())),
        int(np.prod(probe.action_space.shape or ())),
    )
    probe.close()
    episodes: list[LabelledEpisode] = []
    bar = tqdm(total=labels, desc=f"expert labels {env_id}", unit="pair", disable=not progress)
    try:
        while len(dataset) < labels:
            episode = collect_episode(
                env_id,
                episode_dynamics(seed, len(episodes), randomisation),
                None,
                1.0,
                env_kwargs=env_kwargs,
                expert_noise=expert_noise,
            )
            observations, actions = episode.teaching_pairs()
            take = min(len(actions), labels - len(dataset))
            dataset.extend(observations[:take], actions[:take])
            episodes.append(episode)
            bar.update(take)
    finally:
        bar.close()
    return dataset, episodes


__all__ = [
    "Dataset",
    "LabelledEpisode",
    "ShadowExpert",
    "check_pen_task",
    "collect_episode",
    "expert_dataset",
]
