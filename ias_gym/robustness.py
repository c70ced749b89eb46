"""The disturbance suite: one policy's success rate under each class of disturbance.

Each class is a set of env kwargs of the pen tasks (:mod:`ias_gym.envs.disturbances`), so a
class is also just ``gym.make(env_id, **DISTURBANCES[name])``. :func:`run_robustness` evaluates
a policy (an object with SB3's ``predict``, loaded for each class's env by a function the
caller gives, e.g. one calling :func:`ias_gym.baselines.policies.load_policy`) on the same
seeds in every class; ``ias-gym robustness`` prints the table. Why the
classes and their sizes: docs/robustness.md.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ias_gym.baselines.policies import PolicyFactory
from ias_gym.errors import InputError
from ias_gym.evaluation import (
    EpisodeJob,
    check_env_id,
    check_run,
    evaluate,
    make_env,
)
from ias_gym.evaluation_results import EpisodeOutcome
from ias_gym.rates import Rate
from ias_gym.runtime.jobs import SERIAL, Backend, prepare_here, run_jobs

#: The classes: name -> env kwargs. A person does not know mu or the pen's mass either.
DISTURBANCES: dict[str, dict[str, Any]] = {
    "nominal": {},
    "friction_x0.7": {"friction_scale": 0.7},
    "friction_x1.3": {"friction_scale": 1.3},
    "mass_x0.7": {"mass_scale": 0.7},
    "mass_x1.3": {"mass_scale": 1.3},
    "push_0.3N_50ms": {"push_force": 0.3, "push_duration": 0.05},
    "observation_noise": {
        "force_noise": 0.02,  # [N]
        "joint_angle_noise": 0.001,  # [rad]
        "joint_velocity_noise": 0.02,  # [rad/s]
    },
    "action_delay_1_step": {"action_delay": 1},
    "action_noise_0.002": {"action_noise": 0.002},
    "internal_force_steps_0.1N": {"internal_force_step": 0.1},
}


@dataclass(frozen=True)
class RobustnessRow:
    """One class's outcome.

    Attributes:
        disturbance: the class's name (a key of :data:`DISTURBANCES`).
        successes: how many episodes succeeded.
        episodes: how many episodes.
        env_kwargs: the env kwargs of the class.
    """

    disturbance: str
    successes: int
    episodes: int
    env_kwargs: dict[str, Any]

    @property
    def rate(self) -> Rate:
        """The success rate with its 95 % Wilson interval."""
        return Rate(self.successes, self.episodes)

    @property
    def success_rate(self) -> float:
        """Fraction of successful episodes [-]."""
        return self.rate.value

    def as_json(self) -> dict[str, Any]:
        """The JSON object of ``ias-gym robustness --json`` (with the 95 % Wilson interval,
        ``ci95_low``, ``ci95_high``)."""
        return {
            "disturbance": self.disturbance,
            **self.rate.to_dict(),
            "episodes": self.episodes,
            "env_kwargs": self.env_kwargs,
        }


def check_classes(names: Sequence[str] | None) -> list[str]:
    """The class names to run (``None``: all), each checked.

    Raises:
        InputError: an unknown name (the message lists the known ones).
    """
    if names is None:
        return list(DISTURBANCES)
    unknown = [n for n in names if n not in DISTURBANCES]
    if unknown or not names:
        raise InputError(
            f"unknown disturbance class {unknown or names!r}; known: {', '.join(DISTURBANCES)}"
        )
    return list(names)


def run_robustness(
    env_id: str,
    load: PolicyFactory,
    episodes: int = 100,
    seed: int = 0,
    classes: Sequence[str] | None = None,
    env_kwargs: dict[str, Any] | None = None,
    progress: bool = False,
    *,
    name: str | None = None,
) -> list[RobustnessRow]:
    """Evaluate a policy in each disturbance class on seeds ``seed .. seed + episodes - 1``.

    Each class is its own env, so the policy is given as ``load``: a function that loads
    it for an env, called once per class (e.g. ``lambda env: load_policy("expert", env)``,
    :func:`ias_gym.baselines.policies.load_policy`).

    Args:
        env_id: a pen task, e.g. ``"IAS-PenRotate-v0"``.
        load: ``env -> policy`` (an object with SB3's ``predict``) for each class's env.
        episodes: episodes per class (>= 1).
        seed: seed of the first episode (>= 0); every class runs the same seeds.
        classes: names of :data:`DISTURBANCES` (``None``: all of them).
        env_kwargs: further env kwargs for every class (a class's own win).
        progress: a progress bar per class.
        name: the policy's name in the progress bar.

    Returns:
        One row per class, in the order asked.

    Raises:
        InputError: an unknown class, env id or env kwarg (:func:`~ias_gym.evaluation.
            make_env`), bad ``episodes``/``seed``, or what ``load`` raises.
    """
    rows = []
    for disturbance in check_classes(classes):
        kwargs = {**(env_kwargs or {}), **DISTURBANCES[disturbance]}
        env = make_env(env_id, **kwargs)
        try:
            result = evaluate(
                env, load(env), episodes=episodes, seed=seed, name=name, progress=progress
            )
        finally:
            env.close()
        rows.append(
            RobustnessRow(
                disturbance,
                sum(map(bool, result.successes)),
                len(result.successes),
                DISTURBANCES[disturbance],
            )
        )
    return rows


@dataclass(frozen=True)
class DisturbanceJob:
    """One seeded episode in one disturbance class: the job :func:`run_robustness_spec` maps
    over ``(class, seed)`` pairs (``job((class, seed)) -> EpisodeOutcome``), on any backend.

    Attributes:
        env_id: a pen task.
        policy: a policy spec (:func:`~ias_gym.baselines.policies.load_policy`).
        env_kwargs: env kwargs of every class (a class's own win).
        trust_pickle: as for :func:`~ias_gym.baselines.policies.load_policy`.
    """

    env_id: str
    policy: str = "expert"
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    trust_pickle: bool = False

    def episode_job(self, disturbance: str) -> EpisodeJob:
        """The :class:`~ias_gym.evaluation.EpisodeJob` of one class."""
        kwargs = {**self.env_kwargs, **DISTURBANCES[disturbance]}
        return EpisodeJob(self.env_id, self.policy, kwargs, self.trust_pickle)

    def __call__(self, item: tuple[str, int]) -> EpisodeOutcome:
        """Run the episode of ``item = (class name, seed)``."""
        disturbance, seed = item
        return self.episode_job(disturbance)(seed)


def run_robustness_spec(
    env_id: str,
    policy: str = "expert",
    episodes: int = 100,
    seed: int = 0,
    classes: Sequence[str] | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
    progress: bool = False,
    *,
    trust_pickle: bool = False,
    backend: Backend | None = None,
) -> list[RobustnessRow]:
    """:func:`run_robustness` of a policy spec, its episodes run on ``backend``.

    Every ``(class, seed)`` episode is one :class:`DisturbanceJob`, with the policy seeded
    by the episode's seed (:func:`~ias_gym.evaluation.seed_policy`): the rows are the same
    on every backend, bit for bit.

    Args:
        env_id: a pen task, e.g. ``"IAS-PenRotate-v0"``.
        policy: ``"expert"``, ``"random"`` or the path of a saved SB3 model.
        episodes: episodes per class (>= 1).
        seed: seed of the first episode (>= 0); every class runs the same seeds.
        classes: names of :data:`DISTURBANCES` (``None``: all of them).
        env_kwargs: further env kwargs for every class (a class's own win).
        progress: one progress bar over all episodes (on stderr).
        trust_pickle: load a model file with SB3's own ``load`` (runs code from the file).
        backend: where the episodes run (:class:`~ias_gym.runtime.jobs.Backend`; default: here).

    Returns:
        One row per class, in the order asked.

    Raises:
        InputError: an unknown class, env id or env kwarg, bad ``episodes``/``seed``, or a
            policy that cannot be loaded for the env.
        WorkerError: a worker process died twice running the same episode.
    """
    names = check_classes(classes)
    check_run(episodes, seed)
    check_env_id(env_id)
    job = DisturbanceJob(env_id, policy, dict(env_kwargs or {}), trust_pickle)
    backend = backend or SERIAL
    first = job.episode_job(names[0])
    prepare_here(first.key(), first.build, backend)  # a bad kwarg or policy fails at once
    items = [(name, s) for name in names for s in range(seed, seed + episodes)]
    outcomes = run_jobs(job, items, backend, desc=f"{env_id} / {policy}", progress=progress)
    rows = []
    for k, name in enumerate(names):
        successes = [o.is_success for o in outcomes[k * episodes : (k + 1) * episodes]]
        rows.append(RobustnessRow(name, sum(successes), episodes, DISTURBANCES[name]))
    return rows


def summary_row(rows: Sequence[RobustnessRow]) -> dict[str, Any]:
    """The last JSON line: the minimum success rate over the classes (``"disturbance": "all"``)."""
    worst = min(rows, key=lambda r: r.success_rate)
    return {
        "disturbance": "all",
        "success_rate": worst.success_rate,
        "episodes": sum(r.episodes for r in rows),
        "worst": worst.disturbance,
    }
