"""Offline RL on Minari datasets with d3rlpy (BC, IQL, CQL), beside the package's own BC.

The datasets are read only through ``minari.load_dataset`` (written by
:func:`ias_gym.skills.minari_export.export_minari` or anyone else) and checked against the
env they are meant for: :func:`load_offline_dataset` refuses a dataset of another env, an
empty one, or one whose observation or action shape differs from the env's, with an
:class:`~ias_gym.errors.OfflineDatasetError` that names the dataset. Every Minari transition
becomes one d3rlpy transition: a truncated episode keeps its final observation as the last
transition's next observation (a padding row that d3rlpy never samples as a transition),
a terminated one ends in a terminal transition.

:func:`train_offline` trains one algorithm (``bc``, ``iql``, ``cql``: d3rlpy's continuous
``BCConfig``, ``IQLConfig``, ``CQLConfig``; ``sb3_bc``: the package's own behaviour cloning,
:func:`ias_gym.learning.cloning.behaviour_clone`) for a number of gradient steps (epochs for
``sb3_bc``) under a seed; :func:`evaluate_offline` runs the learned policy through
:func:`ias_gym.evaluation.evaluate` (success is the env's ``is_success`` at the end of an
episode) and :func:`normalised_score` puts its mean return on the scale random = 0,
expert = 100 (D4RL's).

Nothing is saved or loaded here: d3rlpy's ``save``/``load_learnable`` pickle, so the results
are kept as JSON only (``train/offline_rl.py``). d3rlpy is the ``[offline]`` extra, imported
inside the functions.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import InputError, MissingDependencyError, OfflineDatasetError
from ias_gym.evaluation import evaluate, make_env

if TYPE_CHECKING:  # pragma: no cover
    from d3rlpy.dataset import MDPDataset

#: The algorithms :func:`train_offline` trains: d3rlpy's three and the package's own BC.
ALGORITHMS = ("bc", "iql", "cql", "sb3_bc")
#: The install hint of a missing d3rlpy or minari.
INSTALL_HINT = "pip install 'ias-gym[offline,datasets]'"
#: Minibatch size of every d3rlpy algorithm (CORL's for D4RL).
BATCH_SIZE = 256
#: IQL's expectile and advantage temperature for the Adroit tasks, pen-human among them
#: (Kostrikov et al. 2022, appendix: tau = 0.7, beta = 0.5, actor dropout 0.1).
IQL_EXPECTILE = 0.7
IQL_TEMPERATURE = 0.5
IQL_ACTOR_DROPOUT = 0.1
#: Hidden layers of every network [units] (d3rlpy's and CORL's default).
HIDDEN_UNITS = (256, 256)


def import_d3rlpy() -> Any:
    """d3rlpy, with its info messages (structlog: dataset and model summaries on every
    ``fit``) silenced; warnings still show.

    Raises:
        MissingDependencyError: d3rlpy is not installed (the message names the extra).
    """
    try:
        import d3rlpy
    except ImportError as exc:
        raise MissingDependencyError(f"offline RL needs d3rlpy: {INSTALL_HINT} ({exc})") from exc
    import logging

    import structlog

    structlog.configure(wrapper_class=structlog.make_filtering_bound_logger(logging.WARNING))
    return d3rlpy


def _import_minari() -> Any:
    try:
        import minari
    except ImportError as exc:
        raise MissingDependencyError(
            f"reading Minari datasets needs minari: {INSTALL_HINT} ({exc})"
        ) from exc
    return minari


@dataclass
class OfflineDataset:
    """A Minari dataset as d3rlpy and the package's BC take it.

    Attributes:
        dataset_id: the Minari id.
        env_id: the env the dataset was recorded on (and is checked against).
        mdp: the d3rlpy ``MDPDataset`` (``transition_count`` equals Minari's ``total_steps``).
        observations: ``(N, obs_dim)`` the observation of each transition (float32).
        actions: ``(N, act_dim)`` its action.
        episodes: Minari's episode count.
        terminated_episodes: episodes that ended in a termination (not a time limit).
    """

    dataset_id: str
    env_id: str
    mdp: MDPDataset
    observations: NDArray[np.float32]
    actions: NDArray[np.float32]
    episodes: int
    terminated_episodes: int

    @property
    def transitions(self) -> int:
        """Transitions (steps) in the dataset."""
        return len(self.actions)


def load_offline_dataset(dataset_id: str, env_id: str) -> OfflineDataset:
    """Load a Minari dataset (``minari.load_dataset``) and convert it for offline RL.

    Args:
        dataset_id: the Minari id, found under ``MINARI_DATASETS_PATH`` (default
            ``~/.minari/datasets``); nothing is downloaded.
        env_id: the env the dataset must have been recorded on.

    Raises:
        OfflineDatasetError: no such dataset, a dataset of another env (or of none), an
            empty one, or observation/action shapes other than the env's.
        UnknownEnvError: ``env_id`` is not registered.
        MissingDependencyError: minari or d3rlpy is not installed.
    """
    minari = _import_minari()
    d3rlpy = import_d3rlpy()
    env = make_env(env_id)
    try:
        obs_shape = env.observation_space.shape
        act_shape = env.action_space.shape
    finally:
        env.close()
    try:
        dataset = minari.load_dataset(dataset_id)
    except FileNotFoundError:
        raise OfflineDatasetError(
            f"Minari dataset {dataset_id!r} cannot be loaded: there is none of that id under "
            "MINARI_DATASETS_PATH (default ~/.minari/datasets); write one with "
            "`ias-gym skills export`"
        ) from None
    except ValueError as exc:  # a malformed id or metadata
        raise OfflineDatasetError(
            f"Minari dataset {dataset_id!r} cannot be loaded: {exc}"
        ) from None
    spec = dataset.spec.env_spec
    recorded = spec.id if spec is not None else None
    if recorded != env_id:
        raise OfflineDatasetError(
            f"Minari dataset {dataset_id!r} was recorded on {recorded!r}, not on {env_id!r}; "
            "give a dataset of this env"
        )
    if dataset.total_episodes == 0 or dataset.total_steps == 0:
        raise OfflineDatasetError(f"Minari dataset {dataset_id!r} is empty (no transitions)")
    for what, got, want in (
        ("observation", dataset.observation_space.shape, obs_shape),
        ("action", dataset.action_space.shape, act_shape),
    ):
        if got != want:
            raise OfflineDatasetError(
                f"Minari dataset {dataset_id!r} has {what} shape {got}, but {env_id} has {want}"
            )

    rows: dict[str, list[NDArray[Any]]] = {k: [] for k in ("obs", "act", "rew", "term", "out")}
    transition_obs: list[NDArray[Any]] = []
    terminated_episodes = 0
    for episode in dataset.iterate_episodes():
        steps = len(episode.actions)
        if steps == 0:
            continue
        obs = np.asarray(episode.observations, dtype=np.float32).reshape(steps + 1, -1)
        act = np.asarray(episode.actions, dtype=np.float32).reshape(steps, -1)
        rew = np.asarray(episode.rewards, dtype=np.float32).reshape(steps)
        terminated = bool(episode.terminations[-1])
        transition_obs.append(obs[:-1])
        if terminated:  # the last transition is terminal: its next observation is unused
            terminated_episodes += 1
            rows["obs"].append(obs[:-1])
            rows["act"].append(act)
            rows["rew"].append(rew)
            rows["term"].append(np.eye(1, steps, steps - 1, dtype=np.float32)[0])
            rows["out"].append(np.zeros(steps, dtype=np.float32))
        else:  # truncated: one padding row carries the final observation
            rows["obs"].append(obs)
            rows["act"].append(np.concatenate([act, act[-1:]]))
            rows["rew"].append(np.concatenate([rew, np.zeros(1, np.float32)]))
            rows["term"].append(np.zeros(steps + 1, dtype=np.float32))
            rows["out"].append(np.eye(1, steps + 1, steps, dtype=np.float32)[0])
    if not transition_obs:
        raise OfflineDatasetError(f"Minari dataset {dataset_id!r} is empty (no transitions)")
    mdp = d3rlpy.dataset.MDPDataset(
        observations=np.concatenate(rows["obs"]),
        actions=np.concatenate(rows["act"]),
        rewards=np.concatenate(rows["rew"]),
        terminals=np.concatenate(rows["term"]),
        timeouts=np.concatenate(rows["out"]),
        action_space=d3rlpy.ActionSpace.CONTINUOUS,
    )
    actions = np.concatenate(
        [r if t.any() else r[:-1] for r, t in zip(rows["act"], rows["term"], strict=True)]
    )
    return OfflineDataset(
        dataset_id=dataset_id,
        env_id=env_id,
        mdp=mdp,
        observations=np.concatenate(transition_obs),
        actions=actions,
        episodes=len(transition_obs),
        terminated_episodes=terminated_episodes,
    )


@dataclass
class OfflinePolicy:
    """A learned policy with SB3's ``predict`` (what :func:`ias_gym.evaluation.evaluate`
    runs): deterministic actions of a d3rlpy algorithm or an SB3 model.

    Attributes:
        act: maps ``(n, obs_dim)`` observations to ``(n, act_dim)`` actions.
        observation_shape: the env's observation shape (one observation or a batch).
    """

    act: Callable[[NDArray[np.float32]], NDArray[np.float32]]
    observation_shape: tuple[int, ...]

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[NDArray[np.float32], Any]:
        """The action(s) for one observation or a batch (SB3's signature)."""
        obs = np.asarray(observation, dtype=np.float32)
        single = obs.shape == self.observation_shape
        actions = self.act(obs.reshape(1, -1) if single else obs.reshape(len(obs), -1))
        return (actions[0] if single else actions), state


@dataclass
class TrainedPolicy:
    """What :func:`train_offline` returns.

    Attributes:
        algorithm: one of :data:`ALGORITHMS`.
        policy: the learned policy.
        steps: gradient steps taken.
        seconds: training wall time [s].
        config: the hyperparameters (JSON-ready).
    """

    algorithm: str
    policy: OfflinePolicy
    steps: int
    seconds: float
    config: dict[str, Any] = field(default_factory=dict)


def algorithm_config(algorithm: str) -> Any:
    """The d3rlpy config of ``bc``, ``iql`` or ``cql``: observations standardised
    (``StandardObservationScaler``), actions scaled to [-1, 1] by the dataset's range per
    component (``MinMaxActionScaler``: the expert's torques span a few hundredths of the
    action space), batch :data:`BATCH_SIZE`, d3rlpy's defaults otherwise; IQL with the
    paper's Adroit settings (:data:`IQL_EXPECTILE`, :data:`IQL_TEMPERATURE`,
    :data:`IQL_ACTOR_DROPOUT`).

    Raises:
        InputError: an unknown algorithm.
    """
    d3rlpy = import_d3rlpy()
    common: dict[str, Any] = {
        "batch_size": BATCH_SIZE,
        "observation_scaler": d3rlpy.preprocessing.StandardObservationScaler(),
        "action_scaler": d3rlpy.preprocessing.MinMaxActionScaler(),
    }
    encoder = d3rlpy.models.VectorEncoderFactory(hidden_units=list(HIDDEN_UNITS))
    if algorithm == "bc":
        return d3rlpy.algos.BCConfig(encoder_factory=encoder, **common)
    if algorithm == "iql":
        actor = d3rlpy.models.VectorEncoderFactory(
            hidden_units=list(HIDDEN_UNITS), dropout_rate=IQL_ACTOR_DROPOUT
        )
        return d3rlpy.algos.IQLConfig(
            expectile=IQL_EXPECTILE,
            weight_temp=IQL_TEMPERATURE,
            actor_encoder_factory=actor,
            critic_encoder_factory=encoder,
            value_encoder_factory=encoder,
            **common,
        )
    if algorithm == "cql":
        return d3rlpy.algos.CQLConfig(
            actor_encoder_factory=encoder, critic_encoder_factory=encoder, **common
        )
    raise InputError(f"unknown algorithm {algorithm!r}; choose one of {', '.join(ALGORITHMS)}")


def train_offline(
    data: OfflineDataset,
    algorithm: str,
    steps: int,
    seed: int,
    *,
    progress: bool = True,
    threads: int = 1,
) -> TrainedPolicy:
    """Train ``algorithm`` on ``data`` for ``steps`` gradient steps (``sb3_bc``: epochs).

    Deterministic for a given ``seed`` on CPU with the same number of torch threads.

    Args:
        data: the dataset (:func:`load_offline_dataset`).
        algorithm: one of :data:`ALGORITHMS`.
        steps: gradient steps (>= 1); for ``sb3_bc`` passes over the data (epochs).
        seed: seeds torch, numpy and the minibatches.
        progress: show a progress bar over the steps.
        threads: torch threads.

    Raises:
        InputError: an unknown algorithm or ``steps`` < 1.
    """
    import time

    import torch

    if algorithm not in ALGORITHMS:
        raise InputError(f"unknown algorithm {algorithm!r}; choose one of {', '.join(ALGORITHMS)}")
    if steps < 1:
        raise InputError(f"steps must be >= 1, got {steps}")
    torch.set_num_threads(threads)
    env = make_env(data.env_id)
    shape = tuple(env.observation_space.shape or ())
    start = time.perf_counter()
    try:
        if algorithm == "sb3_bc":
            return _train_sb3_bc(data, env, steps, seed, progress, shape, start)
        d3rlpy = import_d3rlpy()
        from tqdm import tqdm

        d3rlpy.seed(seed)
        config = algorithm_config(algorithm)
        algo = config.create(device="cpu:0")
        bar = tqdm(total=steps, desc=f"{algorithm} seed {seed}", unit="step", disable=not progress)

        def tick(_algo: Any, _epoch: int, _step: int) -> None:
            bar.update(1)

        try:
            algo.fit(
                data.mdp,
                n_steps=steps,
                n_steps_per_epoch=steps,
                logger_adapter=d3rlpy.logging.NoopAdapterFactory(),
                show_progress=False,
                save_interval=steps + 1,
                callback=tick,
            )
        finally:
            bar.close()
    finally:
        env.close()

    def act(obs: NDArray[np.float32]) -> NDArray[np.float32]:
        return np.asarray(algo.predict(obs), dtype=np.float32)

    return TrainedPolicy(
        algorithm,
        OfflinePolicy(act, shape),
        steps,
        time.perf_counter() - start,
        json_config(config),
    )


def _train_sb3_bc(
    data: OfflineDataset,
    env: gym.Env[Any, Any],
    epochs: int,
    seed: int,
    progress: bool,
    shape: tuple[int, ...],
    start: float,
) -> TrainedPolicy:
    """The package's BC (``train/bc.py``'s defaults) on the dataset's transitions."""
    import time

    from ias_gym.learning.cloning import behaviour_clone, predicted_actions
    from ias_gym.learning.normalisation import DEFAULT_NET_ARCH

    model = behaviour_clone(
        env, data.observations, data.actions, epochs=epochs, seed=seed, progress=progress
    )
    batches = math.ceil(data.transitions / 256)

    def act(obs: NDArray[np.float32]) -> NDArray[np.float32]:
        return predicted_actions(model, obs)

    config = {"epochs": epochs, "batch_size": 256, "lr": 1e-3, "net_arch": list(DEFAULT_NET_ARCH)}
    return TrainedPolicy(
        "sb3_bc", OfflinePolicy(act, shape), epochs * batches, time.perf_counter() - start, config
    )


def json_config(config: Any) -> dict[str, Any]:
    """A d3rlpy config as JSON-ready values (d3rlpy's own serialisation)."""
    import json

    serialised: dict[str, Any] = json.loads(config.serialize())
    return serialised


@dataclass(frozen=True)
class OfflineScore:
    """A policy's evaluation: success rate, mean return, and its normalised score.

    Attributes:
        episodes: evaluation episodes.
        success_rate: fraction of episodes the env counted as successes [0, 1].
        mean_return: mean undiscounted return [-].
        normalised_score: :func:`normalised_score` of ``mean_return`` [0 = random, 100 = expert].
        returns: each episode's return.
    """

    episodes: int
    success_rate: float
    mean_return: float
    normalised_score: float
    returns: list[float]


def normalised_score(mean_return: float, random_return: float, expert_return: float) -> float:
    """D4RL's normalisation: ``100 (R - R_random) / (R_expert - R_random)``.

    Raises:
        InputError: the expert's return is not above the random policy's.
    """
    if not expert_return > random_return:
        raise InputError(
            f"the expert's return {expert_return} must exceed the random one {random_return}"
        )
    return 100.0 * (mean_return - random_return) / (expert_return - random_return)


def evaluate_offline(
    policy: OfflinePolicy,
    env_id: str,
    episodes: int,
    seed: int,
    reference: tuple[float, float],
    *,
    progress: bool = True,
    name: str = "policy",
) -> OfflineScore:
    """Run ``policy`` on ``env_id`` for seeds ``seed .. seed + episodes - 1``.

    Args:
        policy: the learned policy.
        env_id: the env.
        episodes: evaluation episodes (>= 1).
        seed: the first seed.
        reference: the (random, expert) mean returns on the same seeds.
        progress: show a progress bar over episodes.
        name: the policy's name in the progress bar.
    """
    env = make_env(env_id)
    try:
        result = evaluate(env, policy, episodes, seed, name=name, progress=progress)
    finally:
        env.close()
    summary = result.summary()
    return OfflineScore(
        episodes=episodes,
        success_rate=float(summary["success_rate"]),
        mean_return=float(summary["mean_return"]),
        normalised_score=normalised_score(float(summary["mean_return"]), *reference),
        returns=[float(r) for r in result.returns],
    )


def mean_std(values: Sequence[float]) -> tuple[float, float]:
    """Mean and (population, as CORL reports) standard deviation."""
    array = np.asarray(values, dtype=np.float64)
    return float(array.mean()), float(array.std())
