"""Behaviour cloning of demonstrations into the actor (and critic) of a new SB3 PPO model.

:func:`behaviour_clone` fits the actor's Gaussian mean by the mean squared error of the
actions standardised per component, and sets ``log_std`` from the residual (at least
:data:`MIN_ACTION_NOISE`), so that PPO fine-tuning starts with an exploration noise the
task tolerates, not SB3's default of 1 (20x the expert's largest torque). Given the
demonstrations' returns, it fits the critic as well. Optimisation matters: 100 epochs over
~20k pairs (about 9k Adam steps) gave 100 % success on PenSlide, 30 epochs 2 %; network
size (64 or 256 units) and the normalisation floor did not matter. The model is built with
the fine-tuning hyperparameters (:data:`ias_gym.learning.finetune.FINE_TUNE_PPO`), ready
for :func:`ias_gym.learning.finetune.fine_tune`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray
from stable_baselines3 import PPO
from stable_baselines3.common.base_class import BaseAlgorithm
from stable_baselines3.common.vec_env import VecEnv
from tqdm import tqdm

from ias_gym.learning.demonstrations import GAMMA
from ias_gym.learning.finetune import FINE_TUNE_PPO, REWARD_SCALE
from ias_gym.learning.normalisation import (
    DEFAULT_NET_ARCH,
    OBS_CLIP,
    OBS_STD_FLOOR,
    observation_statistics,
    policy_kwargs,
)

FloatArray = NDArray[np.float32]

#: Smallest per-action standard deviation the cloning loss divides by [normalised torque].
ACTION_STD_FLOOR = 1e-3
#: Smallest exploration noise set after cloning [normalised torque]. Measured on PenSlide
#: with the cloned policy: rollouts with noise 1e-3 succeed in 55-83 % of the episodes,
#: with 3e-4 in 100 %, so PPO's first rollouts are those of the cloned policy.
MIN_ACTION_NOISE = 3e-4
#: Huber's constant: the loss is quadratic for errors within this many standard deviations
#: of the labels and linear beyond; 1.345 keeps 95 % of the least-squares efficiency under
#: Gaussian errors (Huber 1964; Hampel et al. 1986, "Robust Statistics", sec. 2.3) [-].
HUBER_DELTA = 1.345


def action_scale(actions: NDArray[Any]) -> torch.Tensor:
    """Per-component standard deviation of labels (at least :data:`ACTION_STD_FLOOR`): the
    scale the cloning loss standardises errors by."""
    spread = np.maximum(np.asarray(actions).std(axis=0), ACTION_STD_FLOOR)
    return torch.as_tensor(spread, dtype=torch.float32)


def cloning_loss(
    predicted: torch.Tensor, labels: torch.Tensor, scale: torch.Tensor, robust: bool = True
) -> torch.Tensor:
    """The cloning loss on errors standardised by ``scale``: Huber's
    (:data:`HUBER_DELTA`) if ``robust``, else the mean squared error."""
    error = (predicted - labels) / scale
    if robust:
        return torch.nn.functional.huber_loss(error, torch.zeros_like(error), delta=HUBER_DELTA)
    return (error**2).mean()


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
    model: PPO | None = None,
    robust: bool = False,
    obs_clip: float = OBS_CLIP,
) -> PPO:
    """Clone (observation, action) pairs into the actor of a new SB3 PPO model.

    The model is ``PPO("MlpPolicy", env)`` with an
    :class:`~ias_gym.learning.normalisation.ObservationNormalizer` holding the
    demonstrations' statistics and tanh hidden layers ``net_arch`` (actor and critic).
    The actor's mean is fitted by Adam (cosine-decayed ``lr``) on the mean squared error of
    the actions standardised per component; ``log_std`` is then set to the log of each
    component's residual standard deviation (at least :data:`MIN_ACTION_NOISE`). Given
    ``returns``, the critic is fitted to ``reward_scale * returns`` at the same time.

    Deterministic for a given ``seed`` on CPU with a fixed number of torch threads.

    Args:
        env: the env (or vec env) the model is for (its spaces; PPO trains on it later).
        observations: ``(N, obs_dim)``.
        actions: ``(N, act_dim)`` labels [action units].
        returns: ``(N,)`` discounted returns (unscaled) for the critic, optional.
        epochs: passes over the data.
        batch_size: minibatch size.
        lr: Adam's initial learning rate.
        net_arch: hidden layer sizes of the actor and the critic.
        std_floor: smallest observation standard deviation (see
            :func:`~ias_gym.learning.normalisation.observation_statistics`).
        reward_scale: the factor the training env multiplies rewards by
            (:func:`~ias_gym.learning.finetune.make_vec_env`); the critic is fitted in
            those units [-].
        seed: seeds the model and the minibatch order.
        progress: show a progress bar over epochs.
        ppo_kwargs: further keyword arguments of ``PPO`` (default
            :data:`~ias_gym.learning.finetune.FINE_TUNE_PPO`).
        robust: fit by Huber's loss (:data:`HUBER_DELTA`) instead of the squared error,
            on the same standardised actions: the fit is the same where the errors are
            small, and a few labels far from the rest (the expert's near-saturated torques
            while a pen slips away from the learner's grasp, hundreds of standard
            deviations out) pull it no harder than any other badly fitted label.
        model: continue fitting this model's actor (warm start; its observation
            normalisation, network and hyperparameters kept, ``net_arch``, ``std_floor``,
            ``obs_clip`` and ``ppo_kwargs`` unused) instead of building a new model.
        obs_clip: the new model's normalised observations are clipped to +- this
            (:class:`~ias_gym.learning.normalisation.ObservationNormalizer`) [-].

    Returns:
        The PPO model with the cloned actor (save it with ``model.save(path)``).

    Raises:
        ValueError: no data, observations and actions (or returns) of different lengths,
            or ``epochs`` / ``batch_size`` < 1.
    """
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
    if model is None:
        mean, std = observation_statistics(obs, std_floor)
        kwargs = {**FINE_TUNE_PPO, "gamma": GAMMA, **dict(ppo_kwargs or {})}
        model = PPO(
            "MlpPolicy",
            env,
            policy_kwargs=policy_kwargs(mean, std, net_arch, clip=obs_clip),
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
    act_scale = action_scale(act)
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
            loss_pi = cloning_loss(policy.action_net(latent_pi), act_t[idx], act_scale, robust)
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
    """Mean squared error between a model's deterministic actions and ``actions``.

    Args:
        model: an SB3 model.
        observations: ``(N, obs_dim)``.
        actions: ``(N, act_dim)`` reference actions [action units].

    Returns:
        The error [action units squared].
    """
    diff = predicted_actions(model, observations) - np.asarray(actions, dtype=np.float32)
    return float(np.mean(diff**2))
