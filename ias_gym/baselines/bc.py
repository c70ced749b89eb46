"""Behaviour cloning from the skill database into a Stable-Baselines3 PPO policy.

The learner is an ordinary SB3 ``PPO("MlpPolicy", ...)`` model, so that a cloned policy
saves, loads (``ias-gym evaluate --policy FILE.zip``) and fine-tunes with PPO like any
other. Two things make it work on the pen tasks:

- **Observation normalisation inside the policy.** The observations span six orders of
  magnitude (pen position errors of 0.1 mm next to joint velocities of rad/s), so they are
  standardised with a fixed mean and standard deviation computed from the demonstrations
  (:class:`ObservationNormalizer`, the policy's features extractor). The statistics are
  part of the saved model (its ``policy_kwargs`` and ``state_dict``): no ``VecNormalize``
  file to carry along, ``evaluate`` loads only the zip.
- **Demonstrations with noise injection (DART, Laskey et al. 2017).** Plain cloning at a
  10 ms control period compounds its errors: the learner drifts into states the expert
  never visited. :func:`record_noisy_expert` steps the env with the expert's action plus
  Gaussian noise but stores the expert's *clean* action as the label, so the
  demonstrations show how the expert recovers from the perturbations a learner makes.
  The expert is privileged (it reads the simulation, not the observation) and needs no
  changes for this.

:func:`behaviour_clone` fits the actor's Gaussian mean by a standardised mean-squared error
and sets its ``log_std`` from the residual, so that PPO fine-tuning starts with an
exploration noise of the size of the cloning error, not SB3's default of 1 (20x the
expert's largest action). When the demonstrations' returns are given, the critic is fitted
to them as well, so that PPO's first advantages are not those of a random value function.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, NamedTuple

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

try:
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.base_class import BaseAlgorithm
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv
except ImportError as exc:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "behaviour cloning needs torch and stable-baselines3: pip install 'ias-gym[train]'"
    ) from exc

from ias_gym.skills.db import SkillDB
from ias_gym.skills.record import record_episode

FloatArray = NDArray[np.float32]

#: Discount factor of PPO and of the demonstrations' returns [-].
GAMMA = 0.99
#: Rewards are multiplied by this while training (values of order one, not 100s) [-].
REWARD_SCALE = 1.0 - GAMMA
#: Hidden layers of the actor and of the critic.
DEFAULT_NET_ARCH: tuple[int, ...] = (256, 256)
#: Smallest standard deviation an observation is divided by (same units as the feature).
OBS_STD_FLOOR = 1e-4
#: Normalised observations are clipped to +- this (a state far outside the data).
OBS_CLIP = 10.0
#: Smallest per-action standard deviation the cloning loss divides by [normalised torque].
ACTION_STD_FLOOR = 1e-3
#: Bounds of the exploration noise set after cloning [normalised torque].
MIN_ACTION_NOISE = 1e-3
#: Fine-tuning hyperparameters of PPO (small steps: the cloned policy is already good).
FINE_TUNE_PPO: Mapping[str, Any] = {
    "learning_rate": 3e-5,
    "n_steps": 1024,
    "batch_size": 256,
    "n_epochs": 5,
    "clip_range": 0.1,
    "target_kl": 0.02,
    "gae_lambda": 0.95,
    "max_grad_norm": 0.5,
}


class ObservationNormalizer(BaseFeaturesExtractor):
    """Fixed standardisation ``clip((obs - mean) / std)``, part of the saved policy.

    Args:
        observation_space: a flat ``Box``.
        mean: per-feature mean (length = observation size); default 0.
        std: per-feature standard deviation (> 0); default 1.
        clip: normalised features are clipped to ``[-clip, clip]``.
    """

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
        self.register_buffer("mean", mean_t)
        self.register_buffer("std", std_t)
        self.clip = float(clip)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        """Normalised, clipped, flattened observations."""
        x = (observations.flatten(start_dim=1) - self.mean) / self.std
        return torch.clamp(x, -self.clip, self.clip)


class Demonstrations(NamedTuple):
    """Step-aligned training pairs from stored demonstrations (final observations dropped).

    Attributes:
        observations: ``(N, obs_dim)`` the observation each action was taken in.
        actions: ``(N, act_dim)`` the demonstrator's actions (labels).
        returns: ``(N,)`` discounted return-to-go from each step (see
            :func:`discounted_returns`).
    """

    observations: FloatArray
    actions: FloatArray
    returns: FloatArray


def discounted_returns(
    rewards: NDArray[Any], gamma: float = GAMMA, bootstrap: bool = True
) -> FloatArray:
    """Discounted return-to-go ``G_t = r_t + gamma G_{t+1}`` of one episode.

    Args:
        rewards: ``(T,)`` rewards.
        gamma: discount factor.
        bootstrap: the episode was truncated (not terminated): the tail is estimated as the
            last reward received forever, ``G_T = r_{T-1} / (1 - gamma)``, which is what
            PPO's value targets bootstrap to at a time limit.
    """
    rewards = np.asarray(rewards, dtype=np.float64)
    out = np.empty_like(rewards)
    tail = rewards[-1] * gamma / (1.0 - gamma) if bootstrap and len(rewards) else 0.0
    for t in range(len(rewards) - 1, -1, -1):
        tail = rewards[t] + gamma * tail
        out[t] = tail
    return out.astype(np.float32)


def load_demonstrations(
    db_path: str | Path,
    task: str,
    max_episodes: int | None = None,
    *,
    source: str | None = "expert",
    success_only: bool = True,
    gamma: float = GAMMA,
) -> Demonstrations:
    """(observation, action, return) triples of a task's demonstrations in a skill database.

    Args:
        db_path: the skill database file.
        task: env id, e.g. ``"IAS-PenSlide-v0"``.
        max_episodes: use at most this many skills (the lowest ids); ``None``: all.
        source: only skills whose source starts with this (``"expert"`` also matches the
            noise-injected ``"expert+noise:..."`` of :func:`record_noisy_expert`);
            ``None``: any source.
        success_only: only skills whose episode succeeded.
        gamma: discount factor of the returns.

    Raises:
        FileNotFoundError: there is no such database file.
        ValueError: no skill matches.
    """
    path = Path(db_path)
    if not path.is_file():
        raise FileNotFoundError(f"no skill database at {path}")
    obs: list[NDArray[Any]] = []
    actions: list[NDArray[Any]] = []
    returns: list[FloatArray] = []
    with SkillDB(path) as db:
        summaries = db.list_skills(task=task, success=True if success_only else None)
        if source is not None:
            summaries = [s for s in summaries if s.source.startswith(source)]
        if max_episodes is not None:
            summaries = summaries[:max_episodes]
        if not summaries:
            raise ValueError(
                f"{path} holds no {'successful ' if success_only else ''}skills of {task!r}"
                f"{'' if source is None else f' from source {source!r}*'}; its tasks: "
                f"{db.tasks()}"
            )
        for summary in summaries:
            demo = db.get(summary.id).demonstration
            obs.append(demo.observations[:-1].reshape(demo.length, -1))
            actions.append(demo.actions.reshape(demo.length, -1))
            truncated = bool(demo.truncations[-1]) and not bool(demo.terminations[-1])
            returns.append(discounted_returns(demo.rewards, gamma, bootstrap=truncated))
    return Demonstrations(
        np.concatenate(obs).astype(np.float32),
        np.concatenate(actions).astype(np.float32),
        np.concatenate(returns),
    )


class GaussianActionNoise(gym.ActionWrapper[Any, Any, Any]):
    """Adds ``N(0, noise^2)`` to every action before the env sees it (the env then clips).

    The noise has its own generator, re-seeded from the env's reset seed, so a recording is
    reproducible.

    Args:
        env: the env to perturb.
        noise: standard deviation per action component [action units].
    """

    def __init__(self, env: gym.Env[Any, Any], noise: float) -> None:
        super().__init__(env)
        if noise < 0 or not math.isfinite(noise):
            raise ValueError(f"noise must be a finite standard deviation >= 0, got {noise}")
        self.noise = float(noise)
        self._rng = np.random.default_rng()

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[Any, dict[str, Any]]:
        """Reset the env and, given a seed, the noise generator (from a derived seed)."""
        if seed is not None:
            self._rng = np.random.default_rng([seed, 0x0DA27])
        return super().reset(seed=seed, options=options)

    def action(self, action: Any) -> Any:
        """The action plus Gaussian noise (same dtype)."""
        a = np.asarray(action)
        return (a + self._rng.normal(0.0, self.noise, a.shape)).astype(a.dtype)


def record_noisy_expert(
    env_id: str,
    episodes: int,
    db_path: str | Path,
    noise: float,
    seed: int = 0,
    progress: bool = True,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
) -> list[int]:
    """Record expert demonstrations with noise injection (DART) into a skill database.

    Each step the env is driven by the expert's action plus ``N(0, noise^2)``; the stored
    action is the expert's clean one, the stored observations, rewards and skill model
    are those of the perturbed rollout. Stored with source ``"expert+noise:<noise>"`` (or
    ``"expert"`` when ``noise`` is 0), every episode (successful or not), episode ``i``
    with reset seed ``seed + i``.

    Args:
        env_id: a registered ``IAS-Pen*`` id.
        episodes: number of episodes (>= 1).
        db_path: the skill database (created if missing).
        noise: standard deviation of the injected noise [normalised torque].
        seed: seed of the first episode.
        progress: show a progress bar.
        env_kwargs: configuration overrides for ``gym.make``.

    Returns:
        The new skills' ids.
    """
    from tqdm import tqdm

    from ias_gym.baselines.expert import ExpertPolicy

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    kwargs = dict(env_kwargs or {})
    source = "expert" if noise == 0 else f"expert+noise:{noise:g}"
    ids: list[int] = []
    with SkillDB(db_path) as db:
        env = GaussianActionNoise(gym.make(env_id, **kwargs), noise)
        try:
            expert = ExpertPolicy(env)
            bar = tqdm(
                range(episodes), desc=f"{env_id} / {source}", unit="episode", disable=not progress
            )
            successes = 0
            for episode in bar:
                expert.reset()
                skill = record_episode(
                    env,
                    lambda obs: expert.predict(obs)[0],
                    seed=seed + episode,
                    source=source,
                    env_kwargs=kwargs,
                )
                ids.append(db.add(skill))
                successes += skill.is_success
                bar.set_postfix(success=f"{successes}/{episode + 1}", refresh=False)
        finally:
            env.close()
    return ids


def observation_statistics(
    observations: NDArray[Any], std_floor: float = OBS_STD_FLOOR
) -> tuple[FloatArray, FloatArray]:
    """Per-feature mean and standard deviation (at least ``std_floor``) of observations."""
    obs = np.asarray(observations, dtype=np.float64).reshape(len(observations), -1)
    mean = obs.mean(axis=0)
    std = np.maximum(obs.std(axis=0), std_floor)
    return mean.astype(np.float32), std.astype(np.float32)


def policy_kwargs(
    mean: NDArray[Any],
    std: NDArray[Any],
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    log_std_init: float = 0.0,
) -> dict[str, Any]:
    """``policy_kwargs`` of an SB3 ``MlpPolicy`` with :class:`ObservationNormalizer` inside.

    Works for PPO (``log_std_init``) and, without that key, for SAC.
    """
    return {
        "net_arch": {"pi": list(net_arch), "vf": list(net_arch)},
        "activation_fn": torch.nn.Tanh,
        "features_extractor_class": ObservationNormalizer,
        "features_extractor_kwargs": {
            "mean": [float(x) for x in np.ravel(mean)],
            "std": [float(x) for x in np.ravel(std)],
        },
        "log_std_init": float(log_std_init),
    }


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


def behaviour_clone(
    env: gym.Env[Any, Any] | VecEnv,
    observations: NDArray[Any],
    actions: NDArray[Any],
    returns: NDArray[Any] | None = None,
    *,
    epochs: int = 100,
    batch_size: int = 256,
    lr: float = 1e-3,
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    std_floor: float = OBS_STD_FLOOR,
    reward_scale: float = REWARD_SCALE,
    seed: int = 0,
    progress: bool = True,
    ppo_kwargs: Mapping[str, Any] | None = None,
) -> PPO:
    """Clone (observation, action) pairs into the actor of a new SB3 PPO model.

    The model is ``PPO("MlpPolicy", env)`` with an :class:`ObservationNormalizer` holding
    the demonstrations' statistics and tanh hidden layers ``net_arch`` (actor and critic).
    The actor's mean is fitted by Adam (cosine-decayed ``lr``) on the mean squared error of
    the actions standardised per component; ``log_std`` is then set to the log of each
    component's residual standard deviation (at least :data:`MIN_ACTION_NOISE`). Given
    ``returns``, the critic is fitted to ``reward_scale * returns`` at the same time.

    Deterministic for a given ``seed`` on CPU with a fixed number of torch threads.

    Args:
        env: the env (or vec env) the model is for (its spaces; PPO trains on it later).
        observations: ``(N, obs_dim)``.
        actions: ``(N, act_dim)`` labels.
        returns: ``(N,)`` discounted returns (unscaled) for the critic, optional.
        epochs: passes over the data.
        batch_size: minibatch size.
        lr: Adam's initial learning rate.
        net_arch: hidden layer sizes of the actor and the critic.
        std_floor: smallest observation standard deviation (see
            :func:`observation_statistics`).
        reward_scale: the factor the training env multiplies rewards by
            (:func:`make_vec_env`); the critic is fitted in those units.
        seed: seeds the model and the minibatch order.
        progress: show a progress bar over epochs.
        ppo_kwargs: further keyword arguments of ``PPO`` (default :data:`FINE_TUNE_PPO`).

    Returns:
        The PPO model with the cloned actor (save it with ``model.save(path)``).
    """
    from tqdm import tqdm

    obs = np.asarray(observations, dtype=np.float32).reshape(len(observations), -1)
    act = np.asarray(actions, dtype=np.float32).reshape(len(actions), -1)
    if len(obs) != len(act) or len(obs) == 0:
        raise ValueError(
            f"need as many observations as actions (> 0), got {len(obs)} and {len(act)}"
        )
    if returns is not None and len(returns) != len(obs):
        raise ValueError(f"need one return per observation, got {len(returns)} for {len(obs)}")
    if epochs < 1 or batch_size < 1:
        raise ValueError(f"epochs and batch_size must be >= 1, got {epochs} and {batch_size}")
    mean, std = observation_statistics(obs, std_floor)
    kwargs = {**FINE_TUNE_PPO, "gamma": GAMMA, **dict(ppo_kwargs or {})}
    model = PPO(
        "MlpPolicy",
        env,
        policy_kwargs=policy_kwargs(mean, std, net_arch),
        seed=seed,
        device="cpu",
        verbose=0,
        **kwargs,
    )
    policy = model.policy
    torch.manual_seed(seed)
    generator = torch.Generator().manual_seed(seed)

    obs_t = torch.as_tensor(obs)
    act_t = torch.as_tensor(act)
    act_scale = torch.as_tensor(np.maximum(act.std(axis=0), ACTION_STD_FLOOR))
    fit_value = returns is not None
    if fit_value:
        ret_t = torch.as_tensor(np.asarray(returns, dtype=np.float32) * reward_scale)
        ret_scale = float(ret_t.std()) + 1e-6
        with torch.no_grad():  # start at the mean: Adam's small steps need not travel there
            policy.value_net.bias.fill_(float(ret_t.mean()))
    params = [
        *policy.mlp_extractor.policy_net.parameters(),
        *policy.action_net.parameters(),
    ]
    if fit_value:
        params += [*policy.mlp_extractor.value_net.parameters(), *policy.value_net.parameters()]
    optimizer = torch.optim.Adam(params, lr=lr)
    batches = math.ceil(len(obs) / batch_size)
    scheduler = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=epochs * batches)

    policy.train()
    bar = tqdm(range(epochs), desc="behaviour cloning", unit="epoch", disable=not progress)
    for _ in bar:
        order = torch.randperm(len(obs), generator=generator)
        total_pi = total_vf = 0.0
        for start in range(0, len(obs), batch_size):
            idx = order[start : start + batch_size]
            features = policy.extract_features(obs_t[idx])
            latent_pi, latent_vf = policy.mlp_extractor(features)
            error = (policy.action_net(latent_pi) - act_t[idx]) / act_scale
            loss_pi = (error**2).mean()
            loss = loss_pi
            if fit_value:
                value = policy.value_net(latent_vf).squeeze(-1)
                loss_vf = (((value - ret_t[idx]) / ret_scale) ** 2).mean()
                loss = loss + loss_vf
                total_vf += float(loss_vf) * len(idx)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            scheduler.step()
            total_pi += float(loss_pi) * len(idx)
        postfix = {"action_loss": f"{total_pi / len(obs):.3g}"}
        if fit_value:
            postfix["value_loss"] = f"{total_vf / len(obs):.3g}"
        bar.set_postfix(postfix, refresh=False)
    policy.eval()

    with torch.no_grad():
        residual = predicted_actions(model, obs, clip=False) - act
        noise = np.maximum(residual.std(axis=0), MIN_ACTION_NOISE)
        policy.log_std.copy_(torch.as_tensor(np.log(noise), dtype=torch.float32))
    return model


def predicted_actions(
    model: BaseAlgorithm, observations: NDArray[Any], clip: bool = True
) -> FloatArray:
    """The deterministic actions of an SB3 model for a batch of observations.

    Args:
        model: an SB3 model.
        observations: ``(N, obs_dim)``.
        clip: clip to the action space as ``predict`` does (``False``: the raw mean).
    """
    obs = np.asarray(observations, dtype=np.float32)
    if clip:
        return np.asarray(model.predict(obs, deterministic=True)[0], dtype=np.float32)
    policy: Any = model.policy
    with torch.no_grad():
        obs_t = torch.as_tensor(obs)
        out = policy.get_distribution(obs_t).distribution.mean
    return np.asarray(out.numpy(), dtype=np.float32)


def action_mse(model: BaseAlgorithm, observations: NDArray[Any], actions: NDArray[Any]) -> float:
    """Mean squared error between a model's deterministic actions and ``actions``."""
    diff = predicted_actions(model, observations) - np.asarray(actions, dtype=np.float32)
    return float(np.mean(diff**2))
