"""Observation normalisation inside an SB3 policy, and the ``policy_kwargs`` that put it there.

The pen tasks' observations span six orders of magnitude (pen position errors of 0.1 mm next
to joint velocities in rad/s); they are standardised with a fixed mean and standard
deviation (:class:`ObservationNormalizer`, the policy's features extractor), which the saved
model carries (its ``policy_kwargs`` and ``state_dict``): no ``VecNormalize`` file,
``evaluate`` loads only the zip. The statistics come from the demonstrations
(:func:`observation_statistics`) or, for agents trained from scratch, from random rollouts
(:func:`rollout_statistics`).

Saved models name :class:`ObservationNormalizer` by its class path; the safe loader
(:data:`ias_gym.safe_sb3.FEATURES_EXTRACTORS`) allow-lists this module's path and the one
it had before (``ias_gym.baselines.bc``), so models saved then still load.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from ias_gym.baselines.policies import RandomPolicy
from ias_gym.rollout import rollout

FloatArray = NDArray[np.float32]

#: Hidden layers of the actor and of the critic.
DEFAULT_NET_ARCH: tuple[int, ...] = (256, 256)
#: Smallest standard deviation an observation is divided by (same units as the feature).
OBS_STD_FLOOR = 1e-4
#: Normalised observations are clipped to +- this (a state far outside the data) [-].
OBS_CLIP = 10.0


class ObservationNormalizer(BaseFeaturesExtractor):
    """Fixed standardisation ``clip((obs - mean) / std)``, part of the saved policy.

    Args:
        observation_space: a flat ``Box``.
        mean: per-feature mean (length = observation size; units of each feature);
            default 0.
        std: per-feature standard deviation (> 0; units of each feature); default 1.
        clip: normalised features are clipped to ``[-clip, clip]`` [-].

    Raises:
        ValueError: ``mean`` or ``std`` does not have one value per feature, or a ``std``
            is not > 0.
    """

    mean: torch.Tensor  # buffers: saved in the state_dict, never trained
    std: torch.Tensor

    def __init__(
        self,
        observation_space: gym.spaces.Box,
        mean: Sequence[float] | None = None,
        std: Sequence[float] | None = None,
        clip: float = OBS_CLIP,
    ) -> None:
        size = int(np.prod(observation_space.shape))
        super().__init__(observation_space, features_dim=size)
        mean_t = torch.zeros(size) if mean is None else torch.as_tensor(mean, dtype=torch.float32)
        std_t = torch.ones(size) if std is None else torch.as_tensor(std, dtype=torch.float32)
        if mean_t.shape != (size,) or std_t.shape != (size,):
            raise ValueError(
                f"mean and std need {size} values (the observation size), got "
                f"{tuple(mean_t.shape)} and {tuple(std_t.shape)}"
            )
        if not bool(torch.all(std_t > 0)):
            raise ValueError("every std must be > 0")
        if not (np.isfinite(clip) and clip > 0):
            raise ValueError(f"clip must be finite and > 0, got {clip}")
        self.register_buffer("mean", mean_t)
        self.register_buffer("std", std_t)
        self.clip = float(clip)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        """Normalised, clipped, flattened observations."""
        x = (observations.flatten(start_dim=1) - self.mean) / self.std
        return torch.clamp(x, -self.clip, self.clip)


def observation_statistics(
    observations: NDArray[Any], std_floor: float = OBS_STD_FLOOR
) -> tuple[FloatArray, FloatArray]:
    """Per-feature mean and standard deviation (at least ``std_floor``) of observations.

    Args:
        observations: ``(N, ...)`` observations, flattened per row.
        std_floor: smallest standard deviation returned (units of each feature).
    """
    obs = np.asarray(observations, dtype=np.float64).reshape(len(observations), -1)
    mean = obs.mean(axis=0)
    std = np.maximum(obs.std(axis=0), std_floor)
    return mean.astype(np.float32), std.astype(np.float32)


def rollout_statistics(
    env_id: str,
    steps: int = 2000,
    seed: int = 0,
    std_floor: float = OBS_STD_FLOOR,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Observation mean and standard deviation under uniformly random actions.

    For agents trained from scratch: the same in-policy normalisation as the cloned ones,
    without any knowledge of the expert.

    Args:
        env_id: a registered id.
        steps: environment steps to collect (episodes are restarted as they end).
        seed: seed of the first episode and of the actions.
        std_floor: smallest standard deviation (see :func:`observation_statistics`).
        env_kwargs: configuration overrides for ``gym.make``.
    """
    env = gym.make(env_id, **dict(env_kwargs or {}))
    policy = RandomPolicy(env.action_space, seed)  # one stream of actions over the episodes
    rows: list[Any] = []
    episode, budget = 0, max(steps, 1)  # the reset observation at least
    while len(rows) < budget:  # episode i from seed + i; its final observation is replaced
        trajectory = rollout(  # by the next episode's reset one, as a vector env does
            env, policy, seed + episode, max_steps=budget - len(rows) - 1, keep_infos=False
        )
        assert trajectory.observations is not None
        rows.extend(trajectory.observations[:-1] if trajectory.done else trajectory.observations)
        episode += 1
    env.close()
    return observation_statistics(np.stack(rows), std_floor)


def policy_kwargs(
    mean: NDArray[Any],
    std: NDArray[Any],
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    log_std_init: float = 0.0,
    clip: float = OBS_CLIP,
) -> dict[str, Any]:
    """``policy_kwargs`` of an SB3 ``MlpPolicy`` with :class:`ObservationNormalizer` inside.

    For PPO and SAC alike: actor and critic(s) get separate hidden layers ``net_arch``
    (tanh), both behind the same fixed normalisation.

    Args:
        mean: observation mean (see :func:`observation_statistics`).
        std: observation standard deviation (> 0).
        net_arch: hidden layer sizes.
        log_std_init: initial log standard deviation of the Gaussian actions (PPO's is
            in action units; SAC's before its tanh squashing).
        clip: normalised observations are clipped to +- this [-].
    """
    return {
        "net_arch": list(net_arch),
        "activation_fn": torch.nn.Tanh,
        "features_extractor_class": ObservationNormalizer,
        "features_extractor_kwargs": {
            "mean": [float(x) for x in np.ravel(mean)],
            "std": [float(x) for x in np.ravel(std)],
            "clip": float(clip),
        },
        "log_std_init": float(log_std_init),
    }
