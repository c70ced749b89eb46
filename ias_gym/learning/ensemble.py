"""An ensemble of cloned policies as one plain SB3 model: the mean of K actors, exactly.

Clones of one dataset that differ only in their initialisation and minibatch order agree
where the data are dense and disagree where they are sparse: the states a disturbance
pushes the policy into. Averaging their actions cancels much of that disagreement
(bagging's variance reduction; ensembles of imitation policies as in Menda et al. 2019,
"EnsembleDAgger").

:func:`ensemble_model` builds the average as *one* SB3 ``MlpPolicy`` whose hidden layers
are the members' side by side: the first layer stacks the members' first layers, every
further hidden layer is block-diagonal (member ``k``'s units see only member ``k``'s),
and the action layer sums the members' action layers divided by K. With elementwise
activations the blocks never mix, so the wide network computes exactly
``mean_k actor_k(obs)`` (to float rounding). It saves and loads like any cloned model (no
code of ours in the file, no unpickling) and acts at the cost of one wider network.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv

from ias_gym.learning.normalisation import policy_kwargs


def _actor_linears(model: PPO) -> list[torch.nn.Linear]:
    """The actor's hidden linear layers, then its action layer."""
    policy: Any = model.policy
    hidden = [m for m in policy.mlp_extractor.policy_net if isinstance(m, torch.nn.Linear)]
    return [*hidden, policy.action_net]


def activation(model: PPO) -> type[torch.nn.Module]:
    """The activation class of a model's hidden layers."""
    policy: Any = model.policy
    cls: type[torch.nn.Module] = policy.activation_fn
    return cls


def ensemble_model(members: Sequence[PPO], env: gym.Env[Any, Any] | VecEnv) -> PPO:
    """One PPO model whose deterministic action is the mean of the members' (module docstring).

    The members must share the env's spaces, the hidden layer sizes, the activation and
    the observation normalisation (clones of one dataset do:
    :func:`~ias_gym.learning.cloning.behaviour_clone` takes the statistics from the data).
    The ensemble's exploration noise (``log_std``) is the members' mean standard
    deviation; its critic has a member's layers and is freshly initialised (cloning does
    not fit one).

    Args:
        members: the cloned models (>= 1; one member gives a copy of itself).
        env: the env (or vec env) the model is for (its spaces).

    Returns:
        A new PPO model with hidden layers K times as wide.

    Raises:
        ValueError: no members, or members that differ in their spaces, layers,
            activation or observation normalisation.
    """
    if not members:
        raise ValueError("an ensemble needs at least one member")
    first = members[0]
    extractor: Any = first.policy.features_extractor
    mean, std = extractor.mean.numpy(), extractor.std.numpy()
    shapes = [[tuple(layer.weight.shape) for layer in _actor_linears(m)] for m in members]
    for k, member in enumerate(members[1:], start=1):
        other: Any = member.policy.features_extractor
        if shapes[k] != shapes[0]:
            raise ValueError(f"member {k} has layers {shapes[k]}, member 0 {shapes[0]}")
        if (member.observation_space, member.action_space) != (
            first.observation_space,
            first.action_space,
        ):
            raise ValueError(f"member {k} was made for other spaces than member 0")
        if not (
            torch.equal(other.mean, extractor.mean)
            and torch.equal(other.std, extractor.std)
            and other.clip == extractor.clip
        ):
            raise ValueError(
                f"member {k} normalises observations differently from member 0; clone the "
                "members on one dataset"
            )
        if activation(member) is not activation(first):
            raise ValueError(f"member {k} has another activation than member 0")
    n = len(members)
    hidden = [shape[0] for shape in shapes[0][:-1]]
    kwargs = policy_kwargs(mean, std, [n * h for h in hidden], clip=extractor.clip)
    # the critic (unfitted by cloning) keeps a member's size: only the actor is widened
    kwargs["net_arch"] = {"pi": [n * h for h in hidden], "vf": hidden}
    kwargs["activation_fn"] = activation(first)
    wide = PPO("MlpPolicy", env, policy_kwargs=kwargs, device="cpu", verbose=0)
    layers = [_actor_linears(m) for m in members]
    with torch.no_grad():
        for depth, target in enumerate(_actor_linears(wide)):
            target.weight.zero_()
            target.bias.zero_()
            for k in range(n):
                source = layers[k][depth]
                rows, cols = source.weight.shape
                last = depth == len(hidden)
                r = slice(0, rows) if last else slice(k * rows, (k + 1) * rows)
                c = slice(0, cols) if depth == 0 else slice(k * cols, (k + 1) * cols)
                scale = 1.0 / n if last else 1.0
                target.weight[r, c] += scale * source.weight
                target.bias[r] += scale * source.bias
        stds = torch.stack([m.policy.log_std.exp() for m in members])
        wide.policy.log_std.copy_(stds.mean(dim=0).log())
    return wide


def member_seed(seed: int, member: int) -> int:
    """Member ``member``'s cloning seed: ``seed`` itself for member 0 (an ensemble of one is
    the plain clone), otherwise a seed derived from both (never another run's member 0)."""
    if member == 0:
        return seed
    return int(np.random.SeedSequence([seed, member]).generate_state(1)[0] % 2**31)


def clone_ensemble(
    env: gym.Env[Any, Any] | VecEnv,
    observations: NDArray[Any],
    actions: NDArray[Any],
    members: int,
    seed: int = 0,
    **clone_kwargs: Any,
) -> PPO:
    """Clone ``members`` policies on the same pairs and return their mean as one model.

    Member ``k`` is :func:`~ias_gym.learning.cloning.behaviour_clone` with seed
    :func:`member_seed` ``(seed, k)`` (initialisation and minibatch order); the result is
    :func:`ensemble_model` of them (one member: that clone itself).

    Args:
        env: the env the model is for.
        observations: ``(N, obs_dim)``.
        actions: ``(N, act_dim)`` labels.
        members: ensemble size (>= 1).
        seed: the ensemble's seed.
        **clone_kwargs: further arguments of ``behaviour_clone`` (``epochs``, ``robust``,
            ...; not ``model`` or ``returns``).

    Raises:
        ValueError: ``members`` < 1, or what ``behaviour_clone`` raises.
    """
    from ias_gym.learning.cloning import behaviour_clone

    if members < 1:
        raise ValueError(f"an ensemble needs members >= 1, got {members}")
    clones = [
        behaviour_clone(env, observations, actions, seed=member_seed(seed, k), **clone_kwargs)
        for k in range(members)
    ]
    return clones[0] if members == 1 else ensemble_model(clones, env)
