"""Recording skills: roll out a policy on a pen task or a glove session, store each episode.

Each step the skill model is sampled from the unwrapped env's physics (paper sec. 3):
W from the fingertip contacts (eq. 16), the measured intensities c (eq. 3), and, when
rank W = 6, the grip transform G (eq. 8) built with the previous step's G so that the
null-space basis N stays continuous; from it ``c_h = N N^T c`` (eq. 7) and
``f_int = N^T c`` (eq. 10). Where rank W < 6 (a finger lost, a degenerate grasp), G does
not exist and those rows are NaN. The samples are taken after reset and after every step,
aligned with the observations.

The sampler follows the env's type (:func:`skill_model_recorder`): the pen-hand tasks
(``IAS-Pen*``, :class:`SkillModelRecorder`) or the glove env ``IAS-GloveGrasp-v0`` and its
subclasses (:class:`~ias_gym.skills.glove_session.GloveSkillModelRecorder`: a two-finger
pinch of soft fingers, W 6 x 8, whose two internal forces are the squeeze and the opposed
torsions). A glove session is recorded with the ``teleop`` policy (zero action); its skills
carry the env's person and the glove's id, and a glove skill (``skill`` env kwarg,
:data:`ias_gym.glove.skills.SKILLS`) is named after it.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

from ias_gym.baselines.policies import Policy, RandomPolicy, load_policy, policy_source
from ias_gym.errors import InputError
from ias_gym.glove.ids import check_id
from ias_gym.glove.skills import check_skill, parameters_of
from ias_gym.grasp.grip_transform import GraspRankError, GripTransform
from ias_gym.rollout import rollout
from ias_gym.runtime.jobs import SERIAL, Backend, iter_jobs, prepare_here, worker_resource
from ias_gym.skills.db import SkillDB
from ias_gym.skills.glove_session import GloveSkillModelRecorder, glove_session_source
from ias_gym.skills.skill import Demonstration, Skill, SkillModel, SkillModelSamples

if TYPE_CHECKING:
    from ias_gym.envs.pen_hand_env import PenHandEnv


class SkillSampler(Protocol):
    """What :func:`record_episode` needs of a skill-model sampler."""

    def sample(self, env: Any) -> None:
        """Append one sample of the unwrapped ``env``'s skill model (after reset / a step)."""

    def __len__(self) -> int: ...

    def model(self) -> SkillModel:
        """The samples so far as a :class:`SkillModel`."""
        ...


class SkillModelRecorder(SkillModelSamples):
    """Samples the skill model of a pen env, one :meth:`sample` per observation."""

    def __init__(self) -> None:
        super().__init__()
        self._previous: GripTransform | None = None

    def sample(self, env: PenHandEnv) -> None:
        """Append the current contact schedule, pen state and G(t)-derived forces.

        Args:
            env: the unwrapped pen env, just after ``reset`` or ``step``.
        """
        p = env.physics
        contacts = p.fingertip_contacts()
        W, active = p.wrench_matrix(contacts)
        c = p.contact_intensities(contacts)
        try:
            G: GripTransform | None = GripTransform.from_wrench_matrix(W, previous=self._previous)
        except GraspRankError:
            G = None
        if G is not None:
            c_h = G.split(c)[1]
            f_int = G.internal_forces(c)
        else:
            c_h = np.full(c.shape, np.nan)
            f_int = np.full(c.shape[0] - 6, np.nan)
        self._previous = G  # after a rank loss N restarts from a fresh SVD basis
        sliding = np.zeros(len(active), dtype=bool)
        sliding[list(env.reference().sliding)] = True
        self._append(
            time=env.time, pen=p, W=W, touching=active, sliding=sliding, c=c, c_h=c_h, f_int=f_int
        )


def stack_infos(infos: Sequence[Mapping[str, Any]]) -> dict[str, NDArray[Any]]:
    """Stack per-step ``info`` dicts into arrays (one row per dict).

    Numbers become float64 or int64 arrays, bools bool arrays, numeric arrays keep their
    dtype. Entries that are not numeric (strings, ``None``, objects) or that are missing or
    change shape in some step are left out: a demonstration holds numbers only.
    """
    if not infos:
        return {}
    out: dict[str, NDArray[Any]] = {}
    for key in infos[0]:
        if not all(key in info for info in infos):
            continue
        try:
            values = [np.asarray(info[key]) for info in infos]
        except (TypeError, ValueError):
            continue
        if values[0].dtype.kind not in "biuf" or any(
            v.shape != values[0].shape or v.dtype.kind != values[0].dtype.kind for v in values
        ):
            continue
        out[str(key)] = np.stack(values)
    return out


def skill_model_recorder(env: gym.Env[Any, Any]) -> SkillSampler:
    """A fresh skill-model sampler for the unwrapped ``env``, chosen by its type.

    Raises:
        TypeError: neither a pen-hand env nor a glove env (no physics to read a model from).
    """
    # MuJoCo envs: imported when a rollout needs them, so that importing the skills package
    # (the database) does not load MuJoCo
    from ias_gym.envs.glove_grasp import GloveGraspEnv
    from ias_gym.envs.pen_hand_env import PenHandEnv

    if isinstance(env, GloveGraspEnv):  # IAS-GloveGrasp-v0 and the envs built on it
        return GloveSkillModelRecorder()
    if isinstance(env, PenHandEnv):
        return SkillModelRecorder()
    raise TypeError(
        "skills are recorded from IAS pen environments (IAS-PenSlide-v0, IAS-PenRotate-v0) "
        f"and glove environments (IAS-GloveGrasp-v0), got {type(env).__name__}"
    )


def record_episode(
    env: gym.Env[Any, Any],
    policy: Policy,
    *,
    seed: int | None,
    source: str,
    name: str | None = None,
    person_id: str | None = None,
    env_kwargs: Mapping[str, Any] | None = None,
) -> Skill:
    """Roll out one episode and return it as a (not yet stored) :class:`Skill`.

    A glove session (``IAS-GloveGrasp-v0`` or an env built on it) is stored with the
    env's person as ``person_id`` and with the glove named in its source
    (:func:`~ias_gym.skills.glove_session.glove_session_source`: ``teleop`` becomes
    ``glove:<glove_id>``).

    Args:
        env: an ``IAS-Pen*`` or glove env (wrappers allowed; the skill model reads the
            unwrapped one).
        policy: an object with SB3's ``predict``; its first call gets
            ``episode_start=True`` (a stateful one, the expert, starts afresh).
        seed: reset seed.
        source: provenance (see :func:`~ias_gym.baselines.policies.policy_source`).
        name: skill name; default ``"<task> <source> seed <seed>"`` (glove sessions:
            ``"<task> <source> <person> seed <seed>"``; a glove skill: its name, e.g.
            ``"tilt_left"``).
        person_id: who demonstrated it, if a person did (glove env: default and must be
            the env's person).
        env_kwargs: keyword arguments ``env`` was made with (stored for re-creating it).

    Raises:
        TypeError: neither a pen-hand nor a glove env (no physics to read the model from).
        ValueError: ``person_id`` is not the glove env's person.
    """
    from ias_gym.envs.glove_grasp import GloveGraspEnv  # as in skill_model_recorder

    unwrapped = env.unwrapped
    recorder = skill_model_recorder(unwrapped)
    task = env.spec.id if env.spec is not None else type(unwrapped).__name__
    glove_env = unwrapped if isinstance(unwrapped, GloveGraspEnv) else None
    if glove_env is not None:
        person = glove_env.person.person_id
        if person_id is not None and person_id != person:
            raise ValueError(
                f"person {person_id!r} was given, but the glove env's hand and calibration belong "
                f"to {person!r}; choose the person with env kwargs "
                f'{{"person_id": "{person_id}"}}'
            )
        person_id = person

    def sample(env: gym.Env[Any, Any], *_: Any) -> None:  # after the reset and every step
        recorder.sample(unwrapped)

    trajectory = rollout(
        env,
        policy,
        seed,
        action_dtype=env.action_space.dtype or np.float32,
        on_reset=sample,
        on_step=sample,
    )
    if glove_env is not None and glove_env.glove is not None:  # the glove the reset opened
        source = glove_session_source(source, glove_env.glove.glove_id)
    assert trajectory.observations is not None and trajectory.infos is not None
    demo = Demonstration(
        observations=trajectory.observations,
        actions=trajectory.actions,
        rewards=trajectory.rewards,
        terminations=trajectory.terminations,
        truncations=trajectory.truncations,
        infos=stack_infos(trajectory.infos),
    )
    default_name = None
    if glove_env is not None:  # a glove skill is named after it
        default_name = glove_env.config.skill or f"{task} {source} {person_id} seed {seed}"
    return Skill(
        name=name or default_name or f"{task} {source} seed {seed}",
        task=task,
        source=source,
        demonstration=demo,
        model=recorder.model(),
        is_success=trajectory.is_success,
        seed=seed,
        person_id=person_id,
        env_kwargs=dict(env_kwargs or {}),
        person_params=(
            None if glove_env is None else parameters_of(glove_env.person, glove_env.style)
        ),
    )


def record_skills(
    env: gym.Env[Any, Any],
    policy: Policy,
    episodes: int,
    db_path: str | Path,
    seed: int = 0,
    progress: bool = True,
    *,
    source: str,
    env_kwargs: Mapping[str, Any] | None = None,
    person_id: str | None = None,
) -> list[int]:
    """Roll out ``policy`` in ``env`` for ``episodes`` episodes and store each as a skill.

    Every episode is stored (successful or not, with ``is_success`` in its row) as soon as
    it ends, each in its own transaction: an interrupted run keeps the finished episodes.
    Episode ``i`` is reset with seed ``seed + i`` and starts the policy afresh
    (``episode_start=True``), as :func:`ias_gym.evaluation.evaluate` does.

    Args:
        env: an ``IAS-Pen*`` or glove env, possibly wrapped (e.g. action noise: the stored
            action is the policy's, before the wrapper); not closed here.
        policy: an object with SB3's ``predict``, loaded for ``env``
            (:func:`~ias_gym.baselines.policies.load_policy`).
        episodes: number of episodes (>= 1).
        db_path: the skill database file (created if missing).
        seed: seed of the first episode.
        progress: show a tqdm progress bar (on stderr).
        source: provenance to store (:func:`~ias_gym.baselines.policies.policy_source`).
        env_kwargs: the keyword arguments ``env`` was made with (stored with each skill).
        person_id: stored as the skills' person id (glove envs: the env's person).

    Returns:
        The new skills' ids, in episode order.

    Raises:
        InputError: ``person_id`` or ``env_kwargs["person_id"]`` is not a valid id
            (:func:`~ias_gym.glove.ids.check_id`), checked before the database is opened.
        ValueError: ``episodes`` < 1, a person other than the glove env's
            (:func:`record_episode`).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    kwargs = dict(env_kwargs or {})
    # Person ids name profile files: refuse a hostile one before anything is created.
    if person_id is not None:
        check_id(person_id, "person_id")
    if "person_id" in kwargs:
        check_id(kwargs["person_id"], "env kwargs person_id")
    env_id = env.spec.id if env.spec is not None else type(env.unwrapped).__name__
    ids: list[int] = []
    with SkillDB(db_path) as db:  # opened first: a bad path fails before any rollout
        bar = tqdm(
            range(episodes), desc=f"{env_id} / {source}", unit="episode", disable=not progress
        )
        successes = 0
        for episode in bar:
            skill = record_episode(
                env,
                policy,
                seed=seed + episode,
                source=source,
                person_id=person_id,
                env_kwargs=kwargs,
            )
            ids.append(db.add(skill))
            successes += skill.is_success
            bar.set_postfix(success=f"{successes}/{episode + 1}", refresh=False)
    return ids


def _is_glove_env(env_id: str) -> bool:
    """``env_id`` is registered as ``IAS-GloveGrasp-v0``'s env or one built on it."""
    from ias_gym.envs.glove_grasp import GloveGraspEnv  # as in skill_model_recorder

    try:
        entry = gym.spec(env_id).entry_point
        creator = gym.envs.registration.load_env_creator(entry) if isinstance(entry, str) else entry
    except (gym.error.Error, ImportError, AttributeError, ValueError):
        return False  # gym.make reports an unknown id
    return isinstance(creator, type) and issubclass(creator, GloveGraspEnv)


def record_skills_spec(
    env_id: str,
    policy_spec: str,
    episodes: int,
    db_path: str | Path,
    seed: int = 0,
    progress: bool = True,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    person_id: str | None = None,
    skill: str | None = None,
    trust_pickle: bool = False,
    backend: Backend | None = None,
) -> list[int]:
    """Record ``episodes`` episodes of a policy spec into a skill database, the episodes
    run on ``backend`` (here, local worker processes or Ray; :class:`RecordJob`).

    Workers send the recorded :class:`Skill` objects (plain arrays) back; this process is
    the database's only writer and stores them in seed order, each in its own transaction,
    as soon as the ones before it are in (an interrupted run keeps them). Episode ``i`` is
    reset with seed ``seed + i`` and the ``random`` policy's sampling is seeded with it
    too, so the database holds the same skills on every backend (ids and creation times
    aside).

    On a glove env, ``person_id`` chooses the env's person (``env_kwargs["person_id"]``)
    unless the env kwargs name one, and ``skill`` the skill the person performs
    (``env_kwargs["skill"]``; the skills are then named after it).

    Args:
        env_id: a registered id, e.g. ``"IAS-PenRotate-v0"`` or ``"IAS-GloveGrasp-v0"``.
        policy_spec: ``"expert"`` (pen tasks), ``"teleop"`` (glove envs: zero action, the
            glove alone drives the hand), ``"random"`` or a path to a saved SB3 model.
        episodes: number of episodes (>= 1).
        db_path: the skill database file (created if missing).
        seed: seed of the first episode.
        progress: show a tqdm progress bar (on stderr).
        env_kwargs: configuration overrides for ``gym.make`` (e.g. ``{"duration": 0.5}``).
        person_id: stored as the skills' person id (glove envs: the env's person).
        skill: a glove skill (:data:`~ias_gym.glove.skills.SKILLS`; glove envs only).
        trust_pickle: load a model file with SB3's own ``load`` (runs code from the file).
        backend: where the episodes run (:class:`~ias_gym.runtime.jobs.Backend`; default: here).

    Returns:
        The new skills' ids, in episode order.

    Raises:
        InputError: ``person_id`` or ``env_kwargs["person_id"]`` is not a valid id, or
            ``skill`` is not a glove skill, or is given for an env that is not a glove env,
            or differs from ``env_kwargs["skill"]``: checked before the env is made.
        ValueError: ``episodes`` < 1, ``expert`` on a glove env, ``teleop`` on a pen env
            (:func:`~ias_gym.baselines.policies.load_policy`), a person other than the glove
            env's (:func:`record_episode`).
        WorkerError: a worker process died twice recording the same episode (the
            episodes before it are stored).
    """
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    kwargs = dict(env_kwargs or {})
    # Person ids name profile files: refuse a hostile one before anything is created.
    if person_id is not None:
        check_id(person_id, "person_id")
    if "person_id" in kwargs:
        check_id(kwargs["person_id"], "env kwargs person_id")
    if _is_glove_env(env_id):
        if person_id is not None:
            kwargs.setdefault("person_id", person_id)
        if skill is not None:
            check_skill(skill, "--skill")
            if kwargs.setdefault("skill", skill) != skill:
                raise InputError(
                    f"--skill {skill!r} differs from env kwargs skill {kwargs['skill']!r}"
                )
    elif skill is not None:
        raise InputError(f"--skill is for glove envs (IAS-GloveGrasp-v0), not {env_id}")
    gym.spec(env_id)  # an unknown id fails here, before the database or a worker
    job = RecordJob(env_id, policy_spec, kwargs, person_id, trust_pickle)
    backend = backend or SERIAL
    prepare_here(job.key(), job.build, backend)  # a bad kwarg or policy fails at once
    seeds = range(seed, seed + episodes)
    ids: list[int] = []
    with SkillDB(db_path) as db:  # opened before any rollout: a bad path costs none
        desc = f"{env_id} / {policy_source(policy_spec)}"
        for recorded in iter_jobs(job, seeds, backend, desc=desc, progress=progress):
            ids.append(db.add(recorded))
    return ids


@dataclass(frozen=True)
class RecordJob:
    """One recorded episode of a policy spec on an env spec: the job
    :func:`record_skills_spec` maps over seeds (``job(seed) -> Skill``, not stored).

    The process that runs it makes the env and loads the policy (once per process,
    :func:`~ias_gym.runtime.jobs.worker_resource`), seeds the ``random`` policy's sampling
    with the episode's seed, and records the episode (:func:`record_episode`).

    Attributes:
        env_id: a registered id.
        policy: a policy spec (:func:`~ias_gym.baselines.policies.load_policy`).
        env_kwargs: configuration overrides for ``gym.make`` (stored with each skill).
        person_id: stored as the skills' person id.
        trust_pickle: as for :func:`~ias_gym.baselines.policies.load_policy`.
    """

    env_id: str
    policy: str = "expert"
    env_kwargs: Mapping[str, Any] = field(default_factory=dict)
    person_id: str | None = None
    trust_pickle: bool = False

    def build(self) -> tuple[gym.Env[Any, Any], Policy]:
        """Make the env and load the policy for it."""
        env = gym.make(self.env_id, **self.env_kwargs)
        try:
            return env, load_policy(self.policy, env, None, trust_pickle=self.trust_pickle)
        except BaseException:
            env.close()
            raise

    def key(self) -> tuple[str, str, str, str, bool]:
        """What identifies the env and policy a worker builds for this job."""
        kwargs = json.dumps(dict(self.env_kwargs), sort_keys=True, default=repr)
        return ("record", self.env_id, kwargs, self.policy, self.trust_pickle)

    def __call__(self, seed: int) -> Skill:
        """Record the episode of ``seed``."""
        env, policy = worker_resource(self.key(), self.build)
        if isinstance(policy, RandomPolicy):  # as ias_gym.evaluation.seed_policy does
            policy.space.seed(seed)
        return record_episode(
            env,
            policy,
            seed=seed,
            source=policy_source(self.policy),
            person_id=self.person_id,
            env_kwargs=self.env_kwargs,
        )
