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

**Randomised dynamics.** Every training episode draws one family of the robustness suite
(:data:`ias_gym.robustness.DISTURBANCES`) uniformly, and that family's parameters uniformly
from :class:`Randomisation`'s ranges, which contain the suite's fixed classes with a
margin (the fixed value in brackets):

============================  ==================================  ==================
family                        env kwargs (uniform)                suite class
============================  ==================================  ==================
``nominal``                   none                                ``nominal``
``friction``                  ``friction_scale`` 0.6 - 1.4        0.7, 1.3
``mass``                      ``mass_scale`` 0.6 - 1.4            0.7, 1.3
``push``                      ``push_force`` 0.1 - 0.4 N,         0.3 N, 0.05 s
                              ``push_duration`` 0.03 - 0.07 s
``observation_noise``         x 0 - 1.5 of the class's sigmas     x 1 (0.02 N,
                              (force, joint angle, velocity)      1 mrad, 0.02 rad/s)
``action_delay``              ``action_delay`` 0 - 2 steps        1 step
``action_noise``              ``action_noise`` 0 - 0.003          0.002
``internal_force_steps``      ``internal_force_step`` 0 - 0.15 N  0.1 N
============================  ==================================  ==================

**Measured** (IAS-PenSlide-v0, ``train/dagger.py``'s docstring and docs/dagger_results.json):
with ~15-25k expert labels neither DAgger nor behaviour cloning comes near the expert's
>= 99 %; DAgger stays below BC at equal labels and Adam steps (its learners drop the pen
within 0.1-0.5 s, so its iterations add few labels), and training episodes of the
``action_delay`` family break the cloning (drop that family with ``Randomisation(families=
...)``).

An episode's dynamics and reset seed depend only on the run's seed and the episode's
index (:func:`episode_dynamics`), and every training reset seed is below
:data:`HELD_OUT_SEED_START`, so evaluation seeds from there on are never trained on.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from stable_baselines3 import PPO
from tqdm import tqdm

from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.envs.pen_hand_env import PenHandEnv
from ias_gym.errors import InputError
from ias_gym.learning.cloning import behaviour_clone
from ias_gym.learning.normalisation import DEFAULT_NET_ARCH
from ias_gym.robustness import DISTURBANCES
from ias_gym.rollout import Policy, Trajectory, rollout

FloatArray = NDArray[np.float32]

#: Training reset seeds are drawn below this; evaluate on seeds from here on (held out).
HELD_OUT_SEED_START = 100_000
#: The families a training episode draws from (the robustness suite's classes, grouped).
FAMILIES: tuple[str, ...] = (
    "nominal",
    "friction",
    "mass",
    "push",
    "observation_noise",
    "action_delay",
    "action_noise",
    "internal_force_steps",
)
#: The suite's observation-noise class: the sigmas a draw of that family scales.
OBSERVATION_NOISE: Mapping[str, float] = DISTURBANCES["observation_noise"]


@dataclass(frozen=True)
class Randomisation:
    """The ranges training dynamics are drawn from (see the module docstring's table).

    Each range is ``(low, high)``, drawn uniformly (``action_delay``: a whole number of
    steps, both ends included).

    Attributes:
        families: the families drawn from, uniformly (names of :data:`FAMILIES`).
        friction_scale: the pen's friction coefficient x this [-].
        mass_scale: the pen's mass and inertia x this [-].
        push_force: the push's magnitude [N].
        push_duration: the push's duration [s].
        observation_noise_scale: factor on the suite's observation-noise sigmas [-].
        action_delay: control steps between an action and its effect [-].
        action_noise: sigma of the noise on the normalised action [-].
        internal_force_step: size of the internal-force reference steps [N].
    """

    families: tuple[str, ...] = FAMILIES
    friction_scale: tuple[float, float] = (0.6, 1.4)
    mass_scale: tuple[float, float] = (0.6, 1.4)
    push_force: tuple[float, float] = (0.1, 0.4)
    push_duration: tuple[float, float] = (0.03, 0.07)
    observation_noise_scale: tuple[float, float] = (0.0, 1.5)
    action_delay: tuple[int, int] = (0, 2)
    action_noise: tuple[float, float] = (0.0, 0.003)
    internal_force_step: tuple[float, float] = (0.0, 0.15)

    def __post_init__(self) -> None:
        unknown = [f for f in self.families if f not in FAMILIES]
        if unknown or not self.families:
            raise InputError(
                f"unknown randomisation families {unknown or list(self.families)}; "
                f"known: {', '.join(FAMILIES)}"
            )
        for name in (
            "friction_scale",
            "mass_scale",
            "push_force",
            "push_duration",
            "observation_noise_scale",
            "action_delay",
            "action_noise",
            "internal_force_step",
        ):
            low, high = getattr(self, name)
            if not (math.isfinite(low) and math.isfinite(high) and 0 <= low <= high):
                raise InputError(
                    f"{name} range must be finite with 0 <= low <= high, got {low, high}"
                )
        if self.friction_scale[0] <= 0 or self.mass_scale[0] <= 0 or self.push_duration[0] <= 0:
            raise InputError("friction_scale, mass_scale and push_duration ranges must be > 0")

    def sample(self, rng: np.random.Generator) -> tuple[str, dict[str, Any]]:
        """One episode's ``(family, env kwargs)``."""
        family = self.families[int(rng.integers(len(self.families)))]

        def uniform(bounds: tuple[float, float]) -> float:
            return float(rng.uniform(bounds[0], bounds[1]))

        kwargs: dict[str, Any]
        if family == "nominal":
            kwargs = {}
        elif family == "friction":
            kwargs = {"friction_scale": uniform(self.friction_scale)}
        elif family == "mass":
            kwargs = {"mass_scale": uniform(self.mass_scale)}
        elif family == "push":
            kwargs = {
                "push_force": uniform(self.push_force),
                "push_duration": uniform(self.push_duration),
            }
        elif family == "observation_noise":
            scale = uniform(self.observation_noise_scale)
            kwargs = {name: scale * sigma for name, sigma in OBSERVATION_NOISE.items()}
        elif family == "action_delay":
            low, high = self.action_delay
            kwargs = {"action_delay": int(rng.integers(low, high + 1))}
        elif family == "action_noise":
            kwargs = {"action_noise": uniform(self.action_noise)}
        else:
            kwargs = {"internal_force_step": uniform(self.internal_force_step)}
        return family, kwargs


#: The default ranges (the module docstring's table).
DEFAULT_RANDOMISATION = Randomisation()
#: No randomisation: every episode nominal.
NOMINAL = Randomisation(families=("nominal",))


@dataclass(frozen=True)
class EpisodeDynamics:
    """What one training episode runs under.

    Attributes:
        family: the drawn family (a name of :data:`FAMILIES`).
        env_kwargs: the env kwargs it was drawn as.
        seed: the episode's reset seed (< :data:`HELD_OUT_SEED_START`).
    """

    family: str
    env_kwargs: dict[str, Any]
    seed: int


def episode_dynamics(
    seed: int, episode: int, randomisation: Randomisation = DEFAULT_RANDOMISATION
) -> EpisodeDynamics:
    """The dynamics and reset seed of training episode ``episode`` of the run ``seed``.

    A function of ``(seed, episode)`` alone (its own generator), so a run is reproducible
    and any episode can be recomputed.

    Args:
        seed: the run's seed (>= 0).
        episode: the episode's index in the run (>= 0).
        randomisation: the ranges.
    """
    rng = np.random.default_rng([seed, episode, 0xDA99E])
    family, kwargs = randomisation.sample(rng)
    return EpisodeDynamics(family, kwargs, int(rng.integers(HELD_OUT_SEED_START)))


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

    Attributes:
        observations: the observations labelled, one per step (what ``predict`` was given).
        labels: the expert's actions on them.
        expert_acted: per step, whether the expert's action was the one executed.
    """

    def __init__(
        self,
        env: gym.Env[Any, Any],
        learner: Policy | None,
        beta: float,
        seed: int = 0,
        expert_noise: float = 0.0,
    ) -> None:
        if not 0.0 <= beta <= 1.0:
            raise InputError(f"beta must be in [0, 1], got {beta}")
        if not (math.isfinite(expert_noise) and expert_noise >= 0):
            raise InputError(f"expert_noise must be finite and >= 0, got {expert_noise}")
        if learner is None and beta < 1.0:
            raise InputError("without a learner the expert must always act (beta = 1)")
        self.expert = ExpertPolicy(env)
        self.learner = learner
        self.beta = float(beta)
        self.expert_noise = float(expert_noise)
        self._rng = np.random.default_rng([seed, 0xC01])
        self.observations: list[NDArray[Any]] = []
        self.labels: list[FloatArray] = []
        self.expert_acted: list[bool] = []

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
        expert_acts = self.learner is None or bool(self._rng.random() < self.beta)
        self.expert_acted.append(expert_acts)
        if expert_acts:
            if self.expert_noise:
                noise = self._rng.normal(0.0, self.expert_noise, np.shape(label))
                return np.clip(label + noise, -1.0, 1.0).astype(np.float32), state
            return label, state
        assert self.learner is not None
        action, state = self.learner.predict(
            observation, state=state, episode_start=episode_start, deterministic=True
        )
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
    """

    dynamics: EpisodeDynamics
    trajectory: Trajectory
    observations: NDArray[np.float64]
    labels: FloatArray
    expert_fraction: float


def collect_episode(
    env_id: str,
    dynamics: EpisodeDynamics,
    learner: Policy | None,
    beta: float,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    expert_noise: float = 0.0,
) -> LabelledEpisode:
    """Run one episode of the mixture under ``dynamics``, the expert labelling every state.

    Args:
        env_id: a pen task.
        dynamics: the env kwargs and reset seed (:func:`episode_dynamics`).
        learner: the learner (``None``: the expert acts alone, ``beta`` must be 1).
        beta: probability the expert acts on a step [-].
        env_kwargs: further env kwargs (the drawn ones win).
        expert_noise: noise on the expert's executed actions (:class:`ShadowExpert`).

    Returns:
        The episode with its labels.
    """
    env = gym.make(env_id, **{**dict(env_kwargs or {}), **dynamics.env_kwargs})
    try:
        shadow = ShadowExpert(env, learner, beta, dynamics.seed, expert_noise)
        trajectory = rollout(env, shadow, dynamics.seed, action_dtype=np.float32, keep_infos=False)
    finally:
        env.close()
    obs_dim = int(np.prod(env.observation_space.shape or ()))
    observations = np.asarray(shadow.observations, dtype=np.float64).reshape(-1, obs_dim)
    labels = np.asarray(shadow.labels, dtype=np.float32).reshape(len(observations), -1)
    fraction = float(np.mean(shadow.expert_acted)) if shadow.expert_acted else 1.0
    return LabelledEpisode(dynamics, trajectory, observations, labels, fraction)


@dataclass(frozen=True)
class IterationRecord:
    """What one DAgger iteration did.

    Attributes:
        iteration: its index (0: expert rollouts only).
        beta: probability the expert acted on a step [-].
        episodes: episodes collected.
        labels_added: pairs added (the steps visited).
        dataset_size: pairs after aggregation.
        rollout_success_rate: fraction of its episodes that succeeded (mixture acting) [-].
        expert_fraction: fraction of its steps where the expert's action was executed [-].
        families: episodes per drawn family.
        gradient_steps: the cloning's Adam steps this iteration.
        family_successes: successful episodes per drawn family.
        collect_s: wall time of the rollouts [s].
        train_s: wall time of the cloning [s].
    """

    iteration: int
    beta: float
    episodes: int
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


def check_pen_task(env_id: str) -> None:
    """Raise :class:`~ias_gym.errors.InputError` unless ``env_id`` is a pen task with an expert.

    Raises:
        InputError: an unknown id, or an env that is not an ``IAS-Pen*`` task.
    """
    try:
        spec = gym.spec(env_id)
    except gym.error.Error:
        raise InputError(
            f"unknown env id {env_id!r}; DAgger needs a pen task such as "
            "IAS-PenSlide-v0 or IAS-PenRotate-v0"
        ) from None
    entry = spec.entry_point
    env_class = gym.envs.registration.load_env_creator(entry) if isinstance(entry, str) else entry
    if not (isinstance(env_class, type) and issubclass(env_class, PenHandEnv)):
        raise InputError(
            f"{env_id} is not a pen task (the analytic expert controls IAS-PenSlide-v0 and "
            "IAS-PenRotate-v0 only)"
        )


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
    randomisation: Randomisation = DEFAULT_RANDOMISATION,
    env_kwargs: Mapping[str, Any] | None = None,
    epochs: int = 100,
    max_gradient_steps: int | None = None,
    batch_size: int = 256,
    lr: float = 1e-3,
    net_arch: Sequence[int] = DEFAULT_NET_ARCH,
    warm_start: bool = False,
    keep_models: bool = False,
    progress: bool = True,
    on_iteration: Callable[[IterationRecord, PPO], None] | None = None,
) -> DaggerResult:
    """Train a policy by DAgger with the analytic expert as teacher (module docstring).

    Iteration ``i`` collects ``episodes_per_iteration`` episodes (training episode ``k`` of
    the run under :func:`episode_dynamics` ``(seed, k)``), with the mixture of ``beta_i``
    (:func:`beta_schedule`), adds every visited state with the expert's label, and clones a
    new learner on the whole dataset (:func:`~ias_gym.learning.cloning.behaviour_clone`,
    observation statistics of the dataset, seeded by ``seed``).

    Args:
        env_id: a pen task (``IAS-PenSlide-v0``, ``IAS-PenRotate-v0``).
        iterations: DAgger iterations (>= 1; 1 is behaviour cloning on expert rollouts).
        episodes_per_iteration: episodes collected per iteration (>= 1).
        seed: the run's seed (>= 0).
        beta_decay: ``beta_i = beta_decay ** i`` for ``i >= 1`` (0: the learner alone) [-].
        initial_episodes: expert episodes of iteration 0 (``None``:
            ``episodes_per_iteration``).
        expert_noise: sigma of the noise on the expert's executed actions, labels clean
            (DART; :class:`ShadowExpert`) [normalised torque].
        randomisation: the ranges of the training dynamics (:data:`NOMINAL`: none).
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
        keep_models: keep the learner of every iteration in the result (not with
            ``warm_start``, which trains one learner on).
        progress: a progress bar over the episodes.
        on_iteration: called after each iteration with its record and the new learner.

    Returns:
        The last learner, the dataset and the history.

    Raises:
        InputError: ``env_id`` is not a pen task, ``iterations`` or
            ``episodes_per_iteration`` < 1, ``seed`` < 0, ``beta_decay`` outside [0, 1],
            ``keep_models`` with ``warm_start``.
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
    first = episodes_per_iteration if initial_episodes is None else initial_episodes
    if first < 1:
        raise InputError(f"initial_episodes must be >= 1, got {initial_episodes}")
    if not 0.0 <= beta_decay <= 1.0:
        raise InputError(f"beta_decay must be in [0, 1], got {beta_decay}")
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
                )
                dataset.extend(episode.observations, episode.labels)
                episodes.append(episode)
                bar.update(1)
                bar.set_postfix(iteration=iteration, beta=f"{beta:.2g}", pairs=len(dataset))
            collect_s = time.perf_counter() - start
            start = time.perf_counter()
            n_epochs = cloning_epochs(len(dataset), epochs, batch_size, max_gradient_steps)
            learner = behaviour_clone(
                probe,
                dataset.observations,
                dataset.actions,
                epochs=n_epochs,
                batch_size=batch_size,
                lr=lr,
                net_arch=net_arch,
                seed=seed + iteration if warm_start else seed,
                progress=False,
                model=learner if warm_start else None,
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
                labels_added=steps,
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
    episode ``k`` runs under :func:`episode_dynamics` ``(seed, k)``, as DAgger's do.

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
            take = min(len(episode.labels), labels - len(dataset))
            dataset.extend(episode.observations[:take], episode.labels[:take])
            episodes.append(episode)
            bar.update(take)
    finally:
        bar.close()
    return dataset, episodes


def cloning_epochs(size: int, epochs: int, batch_size: int, max_gradient_steps: int | None) -> int:
    """``epochs``, lowered (to >= 1) so that cloning ``size`` pairs in minibatches of
    ``batch_size`` makes at most ``max_gradient_steps`` Adam steps (``None``: no cap)."""
    if max_gradient_steps is None:
        return epochs
    per_epoch = math.ceil(size / batch_size)
    return max(1, min(epochs, max_gradient_steps // max(per_epoch, 1)))


__all__ = [
    "DEFAULT_RANDOMISATION",
    "FAMILIES",
    "HELD_OUT_SEED_START",
    "NOMINAL",
    "DaggerResult",
    "Dataset",
    "EpisodeDynamics",
    "IterationRecord",
    "LabelledEpisode",
    "Randomisation",
    "ShadowExpert",
    "beta_schedule",
    "check_pen_task",
    "cloning_epochs",
    "collect_episode",
    "dagger",
    "episode_dynamics",
    "expert_dataset",
]
