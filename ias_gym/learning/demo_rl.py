"""Demonstration-augmented RL: SAC with the expert's transitions in its replay buffer.

The recipe is RLPD's core (Ball, Smith, Kostrikov & Levine 2023, "Efficient Online
Reinforcement Learning with Offline Data"): every minibatch is half demonstrations, half the
agent's own transitions ("symmetric sampling", :class:`DemoReplayBuffer`), on SB3's SAC. Two
choices are ours, both because the pen tasks tolerate very little action noise (measured for
cloning: a Gaussian of 1e-3 on the normalised torque already drops the pen in 17-45 % of the
episodes, :data:`~ias_gym.learning.cloning.MIN_ACTION_NOISE`):

- the entropy target is that of a Gaussian of ``exploration_std`` per action component
  (:func:`target_entropy`), not SB3's ``-dim(A)``, whose noise (std ~0.3 on actions of
  ~0.05) drops the pen within a few steps;
- the actor can start as a clone of the demonstrations (``pretrain_epochs``), fitted on its
  squashed mean by Huber's loss as :func:`~ias_gym.learning.cloning.behaviour_clone` does;
  the critic then learns on the clone's transitions for ``critic_warmup`` steps before the
  actor moves (Nair et al. 2020, AWAC, and Uchendu et al. 2023 on fine-tuning from a prior
  policy: an untrained critic destroys the prior in its first updates);
- the actor's loss can carry a cloning term on the demonstrations, weighted as in TD3+BC
  (Fujimoto & Gu 2021; :class:`CloningTermAdam`): measured on development seeds without
  it, SAC lost the pretrained policy (70 % of development episodes) within 5000 steps after
  the warm-up (0 %).

Not RLPD's: its critic ensemble, LayerNorm and update-to-data ratio of 20 (SB3's SAC has
one critic pair and no LayerNorm; ``gradient_steps`` sets the ratio).

Training episodes draw their dynamics as DAgger's do (:class:`~ias_gym.learning.
randomised_dynamics.RandomisedDynamicsEnv`), so the two methods are compared on one task
distribution; ``train/sac_demos.py`` runs it and evaluates on the robustness suite.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from numpy.typing import NDArray
from stable_baselines3 import SAC
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.type_aliases import ReplayBufferSamples

from ias_gym.learning.cloning import action_scale, cloning_loss
from ias_gym.learning.expert_labelling import LabelledEpisode
from ias_gym.learning.normalisation import DEFAULT_NET_ARCH, observation_statistics, policy_kwargs


@dataclass(frozen=True)
class Transitions:
    """Stored transitions ``(s, a, r, s', done)``.

    Attributes:
        observations: ``(N, obs_dim)``.
        actions: ``(N, act_dim)`` the executed actions [normalised torque].
        rewards: ``(N,)`` as the training env returns them (scaled).
        next_observations: ``(N, obs_dim)``.
        dones: ``(N,)`` the episode terminated there (a time limit is not an end: SAC
            bootstraps through it).
    """

    observations: NDArray[np.float32]
    actions: NDArray[np.float32]
    rewards: NDArray[np.float32]
    next_observations: NDArray[np.float32]
    dones: NDArray[np.float32]

    def __len__(self) -> int:
        return len(self.actions)


def episode_transitions(
    episodes: Sequence[LabelledEpisode], reward_scale: float = 1.0
) -> Transitions:
    """The transitions of collected episodes (what was executed, not the expert's labels).

    Args:
        episodes: episodes of :func:`~ias_gym.learning.expert_labelling.collect_episode`.
        reward_scale: factor on the rewards (that of the training env) [-].

    Raises:
        ValueError: no episodes or no steps.
    """
    parts: list[tuple[NDArray[Any], ...]] = []
    for episode in episodes:
        t = episode.trajectory
        if t.observations is None or t.length == 0:
            continue
        obs = np.asarray(t.observations, dtype=np.float32).reshape(t.length + 1, -1)
        dones = np.zeros(t.length, dtype=np.float32)
        dones[-1] = float(t.terminated)
        parts.append(
            (
                obs[:-1],
                np.asarray(t.actions, dtype=np.float32).reshape(t.length, -1),
                (reward_scale * np.asarray(t.rewards)).astype(np.float32),
                obs[1:],
                dones,
            )
        )
    if not parts:
        raise ValueError("no demonstration steps: the episodes are empty")
    return Transitions(*(np.concatenate(column) for column in zip(*parts, strict=True)))


class DemoReplayBuffer(ReplayBuffer):
    """SB3's replay buffer, each minibatch a ``demo_fraction`` of fixed demonstrations.

    Until the agent has stored a transition, minibatches are all demonstrations. The
    positional arguments (``buffer_size``, the spaces, ``device``, ``n_envs``,
    ``optimize_memory_usage``, ``handle_timeout_termination``) are SB3's ``ReplayBuffer``'s.

    Args:
        demonstrations: the demonstrations' transitions.
        demo_fraction: share of each minibatch drawn from them (RLPD: 0.5) [-].
    """

    def __init__(
        self,
        buffer_size: int,
        observation_space: gym.spaces.Space[Any],
        action_space: gym.spaces.Space[Any],
        device: torch.device | str = "auto",
        n_envs: int = 1,
        optimize_memory_usage: bool = False,
        handle_timeout_termination: bool = True,
        *,
        demonstrations: Transitions,
        demo_fraction: float = 0.5,
    ) -> None:
        super().__init__(
            buffer_size,
            observation_space,
            action_space,
            device,
            n_envs=n_envs,
            optimize_memory_usage=optimize_memory_usage,
            handle_timeout_termination=handle_timeout_termination,
        )
        if not 0.0 <= demo_fraction <= 1.0:
            raise ValueError(f"demo_fraction must be in [0, 1], got {demo_fraction}")
        if len(demonstrations) == 0:
            raise ValueError("no demonstrations")
        self.demonstrations = demonstrations
        self.demo_fraction = float(demo_fraction)
        self._demo_rng = np.random.default_rng(0)

    def seed_demonstrations(self, seed: int) -> None:
        """Seed the draws of demonstration transitions."""
        self._demo_rng = np.random.default_rng([seed, 0xDE30])

    def sample(self, batch_size: int, env: Any = None) -> ReplayBufferSamples:
        """A minibatch: ``round(demo_fraction * batch_size)`` demonstrations, the rest the
        agent's own (all demonstrations while the agent has none)."""
        stored = self.buffer_size if self.full else self.pos
        n_demo = batch_size if stored == 0 else round(self.demo_fraction * batch_size)
        d = self.demonstrations
        idx = self._demo_rng.integers(len(d), size=n_demo)
        demo = ReplayBufferSamples(
            *(
                self.to_torch(x)
                for x in (
                    d.observations[idx],
                    d.actions[idx],
                    d.next_observations[idx],
                    d.dones[idx].reshape(-1, 1),
                    d.rewards[idx].reshape(-1, 1),
                )
            )
        )
        if n_demo == batch_size:
            return demo
        own = super().sample(batch_size - n_demo, env)
        return ReplayBufferSamples(
            torch.cat([demo.observations, own.observations]),
            torch.cat([demo.actions, own.actions]),
            torch.cat([demo.next_observations, own.next_observations]),
            torch.cat([demo.dones, own.dones]),
            torch.cat([demo.rewards, own.rewards]),
        )


def target_entropy(act_dim: int, exploration_std: float) -> float:
    """The entropy of a ``act_dim``-dimensional Gaussian of std ``exploration_std`` [nats].

    SAC's temperature is tuned so that the policy keeps this entropy; the tanh squashing of
    small actions is close to the identity, so it is the exploration noise's size.
    """
    return act_dim * 0.5 * math.log(2 * math.pi * math.e * exploration_std**2)


class CriticWarmup(BaseCallback):
    """Freeze the actor for the first ``steps`` env steps: the critic learns the prior
    policy's values before the actor follows it. (Freezing by ``requires_grad``: SB3 resets
    the optimisers' learning rates on every update.)"""

    def __init__(self, steps: int) -> None:
        super().__init__()
        self.steps = int(steps)

    def _freeze(self, frozen: bool) -> None:
        model: Any = self.model
        for parameter in model.actor.parameters():
            parameter.requires_grad_(not frozen)

    def _on_training_start(self) -> None:
        if self.num_timesteps < self.steps:
            self._freeze(True)

    def _on_step(self) -> bool:
        if self.num_timesteps == self.steps:
            self._freeze(False)
        return True

    def _on_training_end(self) -> None:
        self._freeze(False)


#: TD3+BC's weight of the Q term against the cloning term, ``lambda = alpha / mean |Q|``
#: (Fujimoto & Gu 2021, "A Minimalist Approach to Offline Reinforcement Learning") [-].
TD3_BC_ALPHA = 2.5


def _squashed_mean(actor: Any, observations: torch.Tensor) -> torch.Tensor:
    """SAC's deterministic action: the tanh of the actor's Gaussian mean."""
    features = actor.extract_features(observations, actor.features_extractor)
    result: torch.Tensor = torch.tanh(actor.mu(actor.latent_pi(features)))
    return result


class CloningTermAdam(torch.optim.Adam):
    """Adam for SAC's actor that adds a cloning term's gradient before every step.

    SAC's actor step minimises ``alpha log pi - Q``; this adds ``mean|Q| / TD3_BC_ALPHA``
    times Huber's loss of the actor's action on a minibatch of demonstrations (standardised
    per component), TD3+BC's balance of the two terms, so that the actor keeps to the
    demonstrations where the critic has no better advice (SB3's SAC has no such term, and
    its training loop is one function: adding the gradient at the optimiser's step leaves it
    untouched). While the actor is frozen (:class:`CriticWarmup`) nothing is added.
    """

    def __init__(
        self,
        params: Any,
        model: SAC,
        observations: NDArray[Any],
        actions: NDArray[Any],
        *,
        lr: float,
        batch_size: int = 256,
        seed: int = 0,
    ) -> None:
        super().__init__(params, lr=lr)
        self.model = model
        self.observations = torch.as_tensor(np.asarray(observations, dtype=np.float32))
        self.actions = torch.as_tensor(np.asarray(actions, dtype=np.float32))
        self.scale = action_scale(actions)
        self.batch_size = batch_size
        self.generator = torch.Generator().manual_seed(seed)
        self.last_weight = 0.0

    def step(self, closure: Any = None) -> Any:
        """Add the cloning term's gradient, then Adam's step."""
        model: Any = self.model
        if any(p.requires_grad for group in self.param_groups for p in group["params"]):
            idx = torch.randint(len(self.actions), (self.batch_size,), generator=self.generator)
            obs = self.observations[idx]
            with torch.enable_grad():
                action = _squashed_mean(model.actor, obs)
                with torch.no_grad():
                    q = torch.min(torch.cat(model.critic(obs, action), dim=1), dim=1).values
                self.last_weight = float(q.abs().mean()) / TD3_BC_ALPHA
                loss = cloning_loss(action, self.actions[idx], self.scale)
                (self.last_weight * loss).backward()
        return super().step(closure)


def add_cloning_term(
    model: SAC, observations: NDArray[Any], actions: NDArray[Any], seed: int = 0
) -> None:
    """Give SAC's actor the cloning term of :class:`CloningTermAdam` on these pairs."""
    actor: Any = model.actor
    lr = actor.optimizer.param_groups[0]["lr"]
    actor.optimizer = CloningTermAdam(
        actor.parameters(), model, observations, actions, lr=lr, seed=seed
    )


def pretrain_actor(
    model: SAC,
    observations: NDArray[Any],
    actions: NDArray[Any],
    epochs: int,
    *,
    batch_size: int = 256,
    lr: float = 1e-3,
    seed: int = 0,
) -> None:
    """Fit SAC's actor mean (after tanh) to demonstrated actions by Huber's loss.

    The errors are standardised per action component and the learning rate decays to 0 on a
    cosine, as in :func:`~ias_gym.learning.cloning.behaviour_clone`; the log-std head is
    left alone (the entropy target sets it).
    """
    actor: Any = model.actor
    obs_t = torch.as_tensor(np.asarray(observations, dtype=np.float32))
    act_t = torch.as_tensor(np.asarray(actions, dtype=np.float32))
    scale = action_scale(actions)
    params = [*actor.latent_pi.parameters(), *actor.mu.parameters()]
    optimizer = torch.optim.Adam(params, lr=lr)
    batches = math.ceil(len(obs_t) / batch_size)  # decayed to 0 as behaviour_clone's
    scheduler = torch.optim.lr_scheduler.CosineAnnealingLR(optimizer, T_max=epochs * batches)
    generator = torch.Generator().manual_seed(seed)
    for _ in range(epochs):
        order = torch.randperm(len(obs_t), generator=generator)
        for start in range(0, len(obs_t), batch_size):
            idx = order[start : start + batch_size]
            loss = cloning_loss(_squashed_mean(actor, obs_t[idx]), act_t[idx], scale)
            optimizer.zero_grad()
            loss.backward()
            optimizer.step()
            scheduler.step()


def make_sac(
    env: Any,
    demonstrations: Transitions,
    *,
    seed: int = 0,
    demo_fraction: float = 0.5,
    exploration_std: float = 1e-3,
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    lr: float = 3e-4,
    batch_size: int = 256,
    gradient_steps: int = 1,
    buffer_size: int = 300_000,
    learning_starts: int = 1000,
) -> SAC:
    """SAC on ``env`` with the demonstrations in its replay buffer (module docstring).

    The observation normalisation (inside the policy, as in every model of the package)
    comes from the demonstrations' observations.

    Args:
        env: the training env (a gym env or SB3 vec env).
        demonstrations: their transitions (rewards in the env's scale).
        seed: SAC's seed and the demonstration draws'.
        demo_fraction: share of each minibatch from the demonstrations [-].
        exploration_std: the Gaussian noise the entropy target corresponds to
            [normalised torque].
        net_arch: hidden layers of the actor and the critics.
        lr: Adam's learning rate of actor, critics and temperature.
        batch_size: minibatch size.
        gradient_steps: gradient steps per env step (the update-to-data ratio).
        buffer_size: the agent's own transitions kept.
        learning_starts: env steps before the first update.
    """
    mean, std = observation_statistics(demonstrations.observations)
    kwargs = policy_kwargs(mean, std, net_arch)
    kwargs.pop("log_std_init")  # SAC's actor predicts its log std (set below)
    act_dim = int(np.prod(env.action_space.shape))
    model = SAC(
        "MlpPolicy",
        env,
        learning_rate=lr,
        batch_size=batch_size,
        gradient_steps=gradient_steps,
        buffer_size=buffer_size,
        learning_starts=learning_starts,
        target_entropy=target_entropy(act_dim, exploration_std),
        replay_buffer_class=DemoReplayBuffer,
        replay_buffer_kwargs={"demonstrations": demonstrations, "demo_fraction": demo_fraction},
        policy_kwargs=kwargs,
        seed=seed,
        device="cpu",
        verbose=0,
    )
    buffer: Any = model.replay_buffer
    buffer.seed_demonstrations(seed)
    actor: Any = model.actor
    with torch.no_grad():  # start at the target's noise, not SB3's std of 1 before the tanh
        actor.log_std.weight.zero_()
        actor.log_std.bias.fill_(math.log(exploration_std))
    return model
