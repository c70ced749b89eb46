"""DAgger (Ross, Gordon & Bagnell 2011) with the analytic expert as teacher, under randomised
dynamics.

Behaviour cloning learns the expert's actions on the states the expert visits; a cloned
policy that errs drifts into states it has never seen labelled. DAgger collects data with
the learner in the loop and has the expert label the states the *learner* visits, then
retrains on everything gathered so far. :func:`dagger` runs the loop on SB3 policies
(the PPO actor of :func:`~ias_gym.learning.cloning.behaviour_clone`, with the observation
normalisation inside the saved model):

- iteration 0: expert rollouts (``beta = 1``), behaviour cloning on them; where the
  expert acts its executed action may carry noise, its label stays clean (noise
  injection, DART: Laskey et al. 2017; ``expert_noise``), so the data show corrections;
- iteration ``i >= 1``: rollouts of the mixture ``pi_i = beta_i expert + (1 - beta_i)
  learner`` (a coin per step, ``beta_i = beta_decay ** i``, Ross et al.'s "beta_i = p^(i-1)"
  shifted by the expert-only iteration); the expert labels every visited state; the labels
  are added to the dataset (aggregation) and the learner is cloned afresh on all of it.

The expert labels the states while they are visited
(:class:`~ias_gym.learning.expert_labelling.ShadowExpert`; its module says how a
stateful, privileged teacher labels), and every training episode runs under dynamics drawn
from the robustness suite's families
(:class:`~ias_gym.learning.randomised_dynamics.Randomisation`, whose module has the table
of ranges), its reset seed below the held-out evaluation seeds.

Only the states where the expert's grasp model held teach, and the clones fit Huber's
loss: without either, a few labels of a learner's failing episode decide the fit
(:mod:`~ias_gym.learning.expert_labelling`, :func:`~ias_gym.learning.cloning.behaviour_clone`).
``ensemble`` clones several learners per iteration and acts with their mean
(:mod:`~ias_gym.learning.ensemble`). ``takeover`` gates the mixture: the expert acts on any
step where the learner's action is further than the gate from the label (HG-DAgger, Kelly
et al. 2019), so the learner's episodes stay where the expert can still recover and their
labels are those recoveries. The measured results, with their seeds, are in
docs/results-learning.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from stable_baselines3 import PPO
from tqdm import tqdm

from ias_gym.errors import InputError
from ias_gym.learning.cloning import behaviour_clone
from ias_gym.learning.ensemble import clone_ensemble
from ias_gym.learning.expert_labelling import Dataset, check_pen_task, collect_episode
from ias_gym.learning.normalisation import DEFAULT_NET_ARCH, OBS_CLIP
from ias_gym.learning.randomised_dynamics import (
    DEFAULT_RANDOMISATION,
    Randomisation,
    episode_dynamics,
)


@dataclass(frozen=True)
class IterationRecord:
    """What one DAgger iteration did.

    Attributes:
        iteration: its index (0: expert rollouts only).
        beta: probability the expert acted on a step [-].
        episodes: episodes collected.
        env_steps: env steps of those episodes (every visited state, held or not).
        labels_added: pairs added (the visited states where the expert's grasp model held,
            :meth:`~ias_gym.learning.expert_labelling.LabelledEpisode.teaching_pairs`).
        dataset_size: pairs after aggregation.
        rollout_success_rate: fraction of its episodes that succeeded (mixture acting) [-].
        expert_fraction: fraction of its steps where the expert's action was executed [-].
        families: episodes per drawn family.
        gradient_steps: the cloning's Adam steps this iteration (per ensemble member).
        family_successes: successful episodes per drawn family.
        collect_s: wall time of the rollouts [s].
        train_s: wall time of the cloning [s].
    """

    iteration: int
    beta: float
    episodes: int
    env_steps: int
    labels_added: int
    dataset_size: int
    rollout_success_rate: float
    expert_fraction: float
    families: dict[str, int]
    gradient_steps: int
    family_successes: dict[str, int]
    collect_s: float
    train_s: float

    def as_json(self) -> dict[str, Any]:
        """A JSON object (keys with units)."""
        return {
            "iteration": self.iteration,
            "beta": self.beta,
            "episodes": self.episodes,
            "env_steps": self.env_steps,
            "labels_added": self.labels_added,
            "dataset_size": self.dataset_size,
            "rollout_success_rate": self.rollout_success_rate,
            "expert_fraction": self.expert_fraction,
            "families": dict(self.families),
            "family_successes": dict(self.family_successes),
            "gradient_steps": self.gradient_steps,
            "collect_s": self.collect_s,
            "train_s": self.train_s,
        }


@dataclass
class DaggerResult:
    """A DAgger run's outcome.

    Attributes:
        model: the last learner (SB3 PPO; ``model.save(path)``).
        dataset: the aggregated pairs.
        history: one record per iteration.
        models: the learner after each iteration (when asked to keep them).
    """

    model: PPO
    dataset: Dataset
    history: list[IterationRecord] = field(default_factory=list)
    models: list[PPO] = field(default_factory=list)


def beta_schedule(iteration: int, beta_decay: float) -> float:
    """``beta_i``: 1 at iteration 0 (expert only), ``beta_decay ** i`` after [-]."""
    return 1.0 if iteration == 0 else float(beta_decay**iteration)


def dagger(
    env_id: str,
    iterations: int,
    episodes_per_iteration: int,
    seed: int = 0,
    *,
    beta_decay: float = 0.5,
    initial_episodes: int | None = None,
    expert_noise: float = 0.0,
    takeover: float | None = None,
    randomisation: Randomisation = DEFAULT_RANDOMISATION,
    env_kwargs: Mapping[str, Any] | None = None,
    epochs: int = 100,
    max_gradient_steps: int | None = None,
    batch_size: int = 256,
    lr: float = 1e-3,
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    warm_start: bool = False,
    robust: bool = True,
    obs_clip: float = OBS_CLIP,
    ensemble: int = 1,
    keep_models: bool = False,
    progress: bool = True,
    on_iteration: Callable[[IterationRecord, PPO], None] | None = None,
) -> DaggerResult:
    """Train a policy by DAgger with the analytic expert as teacher (module docstring).

    Iteration ``i`` collects ``episodes_per_iteration`` episodes (training episode ``k`` of
    the run under :func:`~ias_gym.learning.randomised_dynamics.episode_dynamics`
    ``(seed, k)``), with the mixture of ``beta_i`` (:func:`beta_schedule`), adds every
    visited state with the expert's label, and clones a new learner on the whole dataset
    (:func:`~ias_gym.learning.cloning.behaviour_clone`, observation statistics of the
    dataset, seeded by ``seed``).

    Args:
        env_id: a pen task (``IAS-PenSlide-v0``, ``IAS-PenRotate-v0``).
        iterations: DAgger iterations (>= 1; 1 is behaviour cloning on expert rollouts).
        episodes_per_iteration: episodes collected per iteration (>= 1).
        seed: the run's seed (>= 0).
        beta_decay: ``beta_i = beta_decay ** i`` for ``i >= 1`` (0: the learner alone) [-].
        initial_episodes: expert episodes of iteration 0 (``None``:
            ``episodes_per_iteration``).
        expert_noise: sigma of the noise on the expert's executed actions, labels clean
            (DART; :class:`~ias_gym.learning.expert_labelling.ShadowExpert`) [normalised torque].
        takeover: the expert acts wherever the learner's action is further than this from
            its label in any joint (HG-DAgger's gate,
            :class:`~ias_gym.learning.expert_labelling.ShadowExpert`); ``None``: the coin of
            ``beta`` alone [normalised torque].
        randomisation: the ranges of the training dynamics
            (:data:`~ias_gym.learning.randomised_dynamics.NOMINAL`: none).
        env_kwargs: further env kwargs of every episode (e.g. a shorter ``duration``).
        epochs: cloning passes over the dataset per iteration.
        max_gradient_steps: cap on the cloning's Adam steps per iteration (fewer epochs on
            a large dataset; ``None``: no cap).
        batch_size: cloning minibatch.
        lr: cloning learning rate (Adam, cosine-decayed).
        net_arch: hidden layers of the actor.
        warm_start: continue fitting the previous iteration's learner on the aggregated
            dataset (its observation normalisation, from iteration 0's data, kept) instead
            of cloning a new one; the optimisation then accumulates over the iterations.
        robust: clone by Huber's loss (:func:`~ias_gym.learning.cloning.behaviour_clone`'s
            ``robust``); ``False``: the squared error, which a few of the expert's
            near-saturated labels on the learner's failing states can dominate.
        obs_clip: the learners' normalised observations are clipped to +- this
            (:class:`~ias_gym.learning.normalisation.ObservationNormalizer`) [-].
        ensemble: clone this many learners per iteration (seeds
            :func:`~ias_gym.learning.ensemble.member_seed`) and act with their mean
            (:func:`~ias_gym.learning.ensemble.clone_ensemble`, one SB3 model); 1: one clone.
        keep_models: keep the learner of every iteration in the result (not with
            ``warm_start``, which trains one learner on).
        progress: a progress bar over the episodes.
        on_iteration: called after each iteration with its record and the new learner.

    Returns:
        The last learner, the dataset and the history.

    Raises:
        InputError: ``env_id`` is not a pen task, ``iterations`` or
            ``episodes_per_iteration`` < 1, ``seed`` < 0, ``beta_decay`` outside [0, 1],
            ``ensemble`` < 1, ``keep_models`` or ``ensemble`` > 1 with ``warm_start``,
            ``takeover`` or ``obs_clip`` not finite and > 0.
    """
    check_pen_task(env_id)
    if iterations < 1:
        raise InputError(f"iterations must be >= 1, got {iterations}")
    if episodes_per_iteration < 1:
        raise InputError(f"episodes_per_iteration must be >= 1, got {episodes_per_iteration}")
    if seed < 0:
        raise InputError(f"seed must be >= 0, got {seed}")
    if warm_start and keep_models:
        raise InputError("keep_models needs warm_start=False (a warm start trains one learner on)")
    if ensemble < 1:
        raise InputError(f"ensemble must be >= 1, got {ensemble}")
    if warm_start and ensemble > 1:
        raise InputError("an ensemble needs warm_start=False (its members are cloned afresh)")
    first = episodes_per_iteration if initial_episodes is None else initial_episodes
    if first < 1:
        raise InputError(f"initial_episodes must be >= 1, got {initial_episodes}")
    if not 0.0 <= beta_decay <= 1.0:
        raise InputError(f"beta_decay must be in [0, 1], got {beta_decay}")
    if takeover is not None and not (math.isfinite(takeover) and takeover > 0):
        raise InputError(f"takeover must be finite and > 0, got {takeover}")
    if not (math.isfinite(obs_clip) and obs_clip > 0):
        raise InputError(f"obs_clip must be finite and > 0, got {obs_clip}")
    probe = gym.make(env_id, **dict(env_kwargs or {}))
    obs_dim = int(np.prod(probe.observation_space.shape or ()))
    act_dim = int(np.prod(probe.action_space.shape or ()))
    dataset = Dataset.empty(obs_dim, act_dim)
    learner: PPO | None = None
    result: DaggerResult | None = None
    history: list[IterationRecord] = []
    models: list[PPO] = []
    bar = tqdm(
        total=first + (iterations - 1) * episodes_per_iteration,
        desc=f"DAgger {env_id}",
        unit="episode",
        disable=not progress,
    )
    try:
        for iteration in range(iterations):
            beta = beta_schedule(iteration, beta_decay)
            start = time.perf_counter()
            episodes = []
            count = first if iteration == 0 else episodes_per_iteration
            for k in range(count):
                index = k if iteration == 0 else first + (iteration - 1) * count + k
                dynamics = episode_dynamics(seed, index, randomisation)
                acting = None if learner is None or beta >= 1.0 else learner
                episode = collect_episode(
                    env_id,
                    dynamics,
                    acting,
                    1.0 if acting is None else beta,
                    env_kwargs=env_kwargs,
                    expert_noise=expert_noise,
                    takeover=takeover,
                )
                dataset.extend(*episode.teaching_pairs())
                episodes.append(episode)
                bar.update(1)
                bar.set_postfix(iteration=iteration, beta=f"{beta:.2g}", pairs=len(dataset))
            collect_s = time.perf_counter() - start
            start = time.perf_counter()
            n_epochs = cloning_epochs(len(dataset), epochs, batch_size, max_gradient_steps)
            fit: dict[str, Any] = {
                "epochs": n_epochs,
                "batch_size": batch_size,
                "lr": lr,
                "progress": False,
                "obs_clip": obs_clip,
            }
            if warm_start:
                learner = behaviour_clone(
                    probe,
                    dataset.observations,
                    dataset.actions,
                    seed=seed + iteration,
                    model=learner,
                    robust=robust,
                    **fit,
                )
            else:
                learner = clone_ensemble(
                    probe,
                    dataset.observations,
                    dataset.actions,
                    ensemble,
                    seed,
                    net_arch=net_arch,
                    robust=robust,
                    **fit,
                )
            families: dict[str, int] = {}
            family_successes: dict[str, int] = {}
            for e in episodes:
                name = e.dynamics.family
                families[name] = families.get(name, 0) + 1
                family_successes[name] = family_successes.get(name, 0) + e.trajectory.is_success
            steps = sum(len(e.labels) for e in episodes)
            record = IterationRecord(
                iteration=iteration,
                beta=beta,
                episodes=len(episodes),
                env_steps=steps,
                labels_added=sum(int(e.held.sum()) for e in episodes),
                dataset_size=len(dataset),
                rollout_success_rate=float(np.mean([e.trajectory.is_success for e in episodes])),
                expert_fraction=float(
                    sum(e.expert_fraction * len(e.labels) for e in episodes) / max(steps, 1)
                ),
                families=families,
                gradient_steps=n_epochs * math.ceil(len(dataset) / batch_size),
                family_successes=family_successes,
                collect_s=collect_s,
                train_s=time.perf_counter() - start,
            )
            history.append(record)
            if keep_models:
                models.append(learner)
            if on_iteration is not None:
                on_iteration(record, learner)
    finally:
        bar.close()
        probe.close()
    assert learner is not None
    result = DaggerResult(learner, dataset, history, models)
    return result


def cloning_epochs(size: int, epochs: int, batch_size: int, max_gradient_steps: int | None) -> int:
    """``epochs``, lowered (to >= 1) so that cloning ``size`` pairs in minibatches of
    ``batch_size`` makes at most ``max_gradient_steps`` Adam steps (``None``: no cap)."""
    if max_gradient_steps is None:
        return epochs
    per_epoch = math.ceil(size / batch_size)
    return max(1, min(epochs, max_gradient_steps // max(per_epoch, 1)))


__all__ = [
    "DaggerResult",
    "IterationRecord",
    "beta_schedule",
    "cloning_epochs",
    "dagger",
]
