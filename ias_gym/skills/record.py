"""Recording skills: roll out a policy on a pen task and store each episode as a skill.

Each step the skill model is sampled from the unwrapped env's physics (paper sec. 3):
W from the fingertip contacts (eq. 16), the measured intensities c (eq. 3), and, when
rank W = 6, the grip transform G (eq. 8) built with the previous step's G so that the
null-space basis N stays continuous; from it ``c_h = N N^T c`` (eq. 7) and
``f_int = N^T c`` (eq. 10). Where rank W < 6 (a finger lost, a degenerate grasp), G does
not exist and those rows are NaN. The samples are taken after reset and after every step,
aligned with the observations.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

from ias_gym.grasp.grip_transform import GraspRankError, GripTransform
from ias_gym.skills.db import SkillDB
from ias_gym.skills.skill import Demonstration, Skill, SkillModel

if TYPE_CHECKING:
    from ias_gym.envs.pen_hand_env import PenHandEnv

Policy = Callable[[NDArray[Any]], Any]


class SkillModelRecorder:
    """Samples the skill model of a pen env, one :meth:`sample` per observation."""

    def __init__(self) -> None:
        self._rows: dict[str, list[NDArray[Any]]] = {}
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
        position, rpy = p.pen_pose()
        velocity, omega = p.pen_twist()
        row = {
            "time": np.float64(env.time),
            "touching": np.asarray(active, dtype=bool),
            "sliding": sliding,
            "pen_position": position,
            "pen_rpy": rpy,
            "pen_velocity": velocity,
            "pen_omega": omega,
            "c": c,
            "c_h": c_h,
            "f_ext": W @ c,
            "f_int": f_int,
        }
        for key, value in row.items():
            self._rows.setdefault(key, []).append(np.array(value, copy=True))

    def __len__(self) -> int:
        return len(self._rows.get("time", ()))

    def model(self) -> SkillModel:
        """The samples so far as a :class:`SkillModel`."""
        if not self._rows:
            raise ValueError("no samples recorded; call sample() after reset and each step")
        return SkillModel(**{key: np.stack(rows) for key, rows in self._rows.items()})


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


def policy_source(policy_spec: str) -> str:
    """Provenance string of a policy spec: ``expert``, ``random`` or ``policy:<abs path>``."""
    if policy_spec in ("expert", "random"):
        return policy_spec
    return f"policy:{Path(policy_spec).resolve()}"


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

    Args:
        env: an ``IAS-Pen*`` env (wrappers allowed; the skill model reads the unwrapped one).
        policy: ``obs -> action``; a stateful expert must be fresh for this episode.
        seed: reset seed.
        source: provenance (see :func:`policy_source`).
        name: skill name; default ``"<task> <source> seed <seed>"``.
        person_id: who demonstrated it, if a person did.
        env_kwargs: keyword arguments ``env`` was made with (stored for re-creating it).

    Raises:
        TypeError: the env is not a pen-hand env (no physics to read the skill model from).
    """
    from ias_gym.envs.pen_hand_env import PenHandEnv

    unwrapped = env.unwrapped
    if not isinstance(unwrapped, PenHandEnv):
        raise TypeError(
            f"skills are recorded from IAS pen environments, got {type(unwrapped).__name__}"
        )
    task = env.spec.id if env.spec is not None else type(unwrapped).__name__
    recorder = SkillModelRecorder()
    obs, info = env.reset(seed=seed)
    recorder.sample(unwrapped)
    observations, infos = [obs], [info]
    actions: list[NDArray[Any]] = []
    rewards: list[float] = []
    terminations: list[bool] = []
    truncations: list[bool] = []
    done = False
    action_dtype = env.action_space.dtype or np.float32
    while not done:
        action = np.asarray(policy(obs), dtype=action_dtype)
        obs, reward, terminated, truncated, info = env.step(action)
        recorder.sample(unwrapped)
        observations.append(obs)
        infos.append(info)
        actions.append(action)
        rewards.append(float(reward))
        terminations.append(bool(terminated))
        truncations.append(bool(truncated))
        done = terminated or truncated
    demo = Demonstration(
        observations=np.stack(observations),
        actions=np.stack(actions),
        rewards=np.asarray(rewards, dtype=np.float64),
        terminations=np.asarray(terminations, dtype=bool),
        truncations=np.asarray(truncations, dtype=bool),
        infos=stack_infos(infos),
    )
    return Skill(
        name=name or f"{task} {source} seed {seed}",
        task=task,
        source=source,
        demonstration=demo,
        model=recorder.model(),
        is_success=bool(info.get("is_success", False)),
        seed=seed,
        person_id=person_id,
        env_kwargs=dict(env_kwargs or {}),
    )


def record_skills(
    env_id: str,
    policy_spec: str,
    episodes: int,
    db_path: str | Path,
    seed: int = 0,
    progress: bool = True,
    *,
    env_kwargs: Mapping[str, Any] | None = None,
    person_id: str | None = None,
    wrapper: Callable[[gym.Env[Any, Any]], gym.Env[Any, Any]] | None = None,
    source: str | None = None,
) -> list[int]:
    """Roll out ``policy_spec`` for ``episodes`` episodes and store each as a skill.

    Every episode is stored (successful or not, with ``is_success`` in its row) as soon as
    it ends, each in its own transaction: an interrupted run keeps the finished episodes.
    Episode ``i`` is reset with seed ``seed + i``; the expert is re-created per episode, as
    :func:`ias_gym.evaluation.evaluate` does.

    Args:
        env_id: a registered id, e.g. ``"IAS-PenRotate-v0"``.
        policy_spec: ``"expert"``, ``"random"`` or a path to a saved SB3 model.
        episodes: number of episodes (>= 1).
        db_path: the skill database file (created if missing).
        seed: seed of the first episode.
        progress: show a tqdm progress bar (on stderr).
        env_kwargs: configuration overrides for ``gym.make`` (e.g. ``{"duration": 0.5}``).
        person_id: stored as the skills' person id.
        wrapper: wraps the env the policy acts in (e.g. action noise); the stored action is
            the policy's, before the wrapper.
        source: provenance to store (default: from ``policy_spec``).

    Returns:
        The new skills' ids, in episode order.
    """
    from tqdm import tqdm

    from ias_gym.evaluation import load_policy

    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes}")
    kwargs = dict(env_kwargs or {})
    source = source or policy_source(policy_spec)
    ids: list[int] = []
    with SkillDB(db_path) as db:  # opened first: a bad path fails before any rollout
        env = gym.make(env_id, **kwargs)
        if wrapper is not None:
            env = wrapper(env)
        try:
            act = load_policy(policy_spec, env, seed)
            bar = tqdm(
                range(episodes), desc=f"{env_id} / {source}", unit="episode", disable=not progress
            )
            successes = 0
            for episode in bar:
                if policy_spec == "expert":
                    act = load_policy(policy_spec, env, seed)  # a fresh controller per episode
                skill = record_episode(
                    env,
                    act,
                    seed=seed + episode,
                    source=source,
                    person_id=person_id,
                    env_kwargs=kwargs,
                )
                ids.append(db.add(skill))
                successes += skill.is_success
                bar.set_postfix(success=f"{successes}/{episode + 1}", refresh=False)
        finally:
            env.close()
    return ids
