"""Training pairs from the skill database: (observation, action, discounted return).

:func:`load_demonstrations` reads a task's stored demonstrations (by default the expert's,
noise-injected ones included, successful episodes only: with the labels of episodes the
noise made fail, cloning reached 0 %) and aligns each action with the observation it was
taken in; :func:`discounted_returns` gives the critic its targets.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ias_gym.errors import InputError, MissingFileError
from ias_gym.skills.db import SkillDB

FloatArray = NDArray[np.float32]

#: Discount factor of PPO and of the demonstrations' returns [-].
GAMMA = 0.99


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
        gamma: discount factor [-].
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
        db_path: the skill database file (opened read-only).
        task: env id, e.g. ``"IAS-PenSlide-v0"``.
        max_episodes: use at most this many skills (the lowest ids); ``None``: all.
        source: only skills whose source starts with this (``"expert"`` also matches the
            noise-injected ``"expert+noise:..."`` of
            :func:`ias_gym.learning.dart.record_noisy_expert`); ``None``: any source.
        success_only: only skills whose episode succeeded.
        gamma: discount factor of the returns [-].

    Raises:
        MissingFileError: there is no such database file (a ``FileNotFoundError``).
        InputError: no skill matches (a ``ValueError``).
        SkillDBError: the file is not a skill database.
    """
    path = Path(db_path)
    if not path.is_file():
        raise MissingFileError(
            f"no skill database at {path}; record one (ias-gym skills record --db PATH, or "
            "--record here)"
        )
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
            raise InputError(
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
