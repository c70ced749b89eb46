"""Behaviour cloning from the skill database into a Stable-Baselines3 PPO policy.

The learner is an ordinary SB3 ``PPO("MlpPolicy", ...)`` model, so that a cloned policy
saves, loads (``ias-gym evaluate --policy FILE.zip``) and fine-tunes with PPO like any
other. What the pen tasks need (measured on 50 held-out seeds; ``train/`` has the
commands):

- **Demonstrations with noise injection (DART, Laskey et al. 2017).** The tasks are
  unforgiving: Gaussian noise of 0.002 (1 mN m) on the expert's normalised torques drops
  the pen within about a second. Cloned from 50 clean expert episodes, a policy with a
  training error of 1e-4 drops it within 0.3 s (0 % success on both tasks): it leaves the
  narrow band of states the expert visits, where it has never seen a correction.
  :func:`record_noisy_expert` steps the env with the expert's action plus noise but
  stores the expert's clean action, so the demonstrations show the expert's corrections:
  noise 0.0005-0.001 gave 94-100 % (PenSlide) and 88-98 % (PenRotate). Only successful
  episodes are used: with the labels of episodes the noise made fail, 0 %.
- **Enough optimisation.** 100 epochs over ~20k pairs (about 9k Adam steps): 100 %;
  30 epochs: 2 %. Network size (64 or 256 units) and the normalisation floor did not
  matter.
- **Observation normalisation inside the policy.** The observations span six orders of
  magnitude (pen position errors of 0.1 mm next to joint velocities in rad/s); they are
  standardised with a fixed mean and standard deviation from the demonstrations
  (:class:`ObservationNormalizer`, the policy's features extractor), which the saved
  model carries (its ``policy_kwargs`` and ``state_dict``): no ``VecNormalize`` file,
  ``evaluate`` loads only the zip.

:func:`behaviour_clone` fits the actor's Gaussian mean by the mean squared error of the
actions standardised per component, and sets ``log_std`` from the residual (at least
:data:`MIN_ACTION_NOISE`), so that PPO fine-tuning starts with an exploration noise the
task tolerates, not SB3's default of 1 (20x the expert's largest torque). Given the
demonstrations' returns, it fits the critic as well. :func:`fine_tune` then runs PPO with
tiny steps (:data:`FINE_TUNE_PPO`), the actor frozen while the critic warms up, and
:class:`KeepBestPolicy` keeps the best policy on held-out validation seeds: within 100k
steps PPO did not improve on the cloned policy, and its last iterate was often worse.
"""

from __future__ import annotations

import math
import time
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
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.monitor import Monitor
    from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
    from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv
except ImportError as exc:  # pragma: no cover - depends on the installed extras
    raise ImportError(
        "behaviour cloning needs torch and stable-baselines3: pip install 'ias-gym[train]'"
    ) from exc

from ias_gym.skills.db import SkillDB

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
#: Smallest exploration noise set after cloning [normalised torque]. Measured on PenSlide
#: with the cloned policy: rollouts with noise 1e-3 succeed in 55-83 % of the episodes,
#: with 3e-4 in 100 %, so PPO's first rollouts are those of the cloned policy.
MIN_ACTION_NOISE = 3e-4
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


class ObservationNormalizer(BaseFeaturesExtractor):
    """Fixed standardisation ``clip((obs - mean) / std)``, part of the saved policy.

    Args:
        observation_space: a flat ``Box``.
        mean: per-feature mean (length = observation size); default 0.
        std: per-feature standard deviation (> 0); default 1.
        clip: normalised features are clipped to ``[-clip, clip]``.
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
    tail = rewards[-1] / (1.0 - gamma) if bootstrap and len(rewards) else 0.0  # V(s_T)
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
    with SkillDB(path, readonly=True) as db:
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
    from ias_gym.skills import record_skills

    return record_skills(
        env_id,
        "expert",
        episodes,
        db_path,
        seed,
        progress,
        env_kwargs=env_kwargs,
        wrapper=lambda env: GaussianActionNoise(env, noise),
        source="expert" if noise == 0 else f"expert+noise:{noise:g}",
    )


def observation_statistics(
    observations: NDArray[Any], std_floor: float = OBS_STD_FLOOR
) -> tuple[FloatArray, FloatArray]:
    """Per-feature mean and standard deviation (at least ``std_floor``) of observations."""
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
    env.action_space.seed(seed)
    obs, _ = env.reset(seed=seed)
    rows = [obs]
    episode = 0
    for _ in range(steps - 1):
        obs, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            episode += 1
            obs, _ = env.reset(seed=seed + episode)
        rows.append(obs)
    env.close()
    return observation_statistics(np.stack(rows), std_floor)


def policy_kwargs(
    mean: NDArray[Any],
    std: NDArray[Any],
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    log_std_init: float = 0.0,
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
    """
    return {
        "net_arch": list(net_arch),
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
                total_vf += float(loss_vf.detach()) * len(idx)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            scheduler.step()
            total_pi += float(loss_pi.detach()) * len(idx)
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


class WallClockLimit(BaseCallback):
    """Stops SB3 training once ``seconds`` have passed since this callback was created."""

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
            obs, info = env.reset(seed=seed)
            total, done = 0.0, False
            while not done:
                action = self.model.predict(obs, deterministic=True)[0]
                obs, reward, terminated, truncated, info = env.step(action)
                total += float(reward)
                done = terminated or truncated
            successes.append(bool(info["is_success"]))
            returns.append(total)
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
        model: a PPO model with an env (e.g. from :func:`behaviour_clone` given a vec env).
        steps: environment steps in all (SB3 rounds each phase up to whole rollouts).
        critic_warmup: steps with the actor frozen.
        progress: show progress bars.
        callback: SB3 callback for both phases (e.g. :class:`WallClockLimit`).
        keep_best: validates after the warm-up and during the rest; at the end the model
            holds the best policy it saw (the cloned one included).
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
