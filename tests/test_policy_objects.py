"""The evaluation and recording loops take policy objects with SB3's ``predict``.

They pass ``episode_start=True`` on each episode's first step only (a stateful policy such
as the expert resets on it) and hand back the ``state`` the previous call returned.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.baselines.policies import RandomPolicy, ZeroPolicy, load_policy
from ias_gym.evaluation import evaluate
from ias_gym.skills import SkillDB
from ias_gym.skills.record import record_skills

ENV_ID = "IAS-PenRotate-v0"
SHORT = {"duration": 0.1, "settle_time": 0.05}  # 10 steps of 10 ms


class _Spy:
    """Zero actions; logs each call's (episode_start, state) and returns a step counter."""

    def __init__(self, space: gym.spaces.Box) -> None:
        self.space = space
        self.calls: list[tuple[bool, Any]] = []

    def predict(
        self,
        observation: Any,
        state: Any = None,
        episode_start: Any = None,
        deterministic: bool = True,
    ) -> tuple[np.ndarray, int]:
        self.calls.append((bool(episode_start), state))
        step = 0 if episode_start else int(state) + 1
        return np.zeros(self.space.shape, dtype=self.space.dtype), step


def _starts(calls: list[tuple[bool, Any]]) -> list[int]:
    return [i for i, (start, _) in enumerate(calls) if start]


def test_evaluate_marks_each_episode_start_and_threads_the_state() -> None:
    env = gym.make(ENV_ID, **SHORT)
    spy = _Spy(env.action_space)  # type: ignore[arg-type]
    result = evaluate(env, spy, episodes=2, seed=0, name="spy")
    env.close()
    assert result.policy == "spy" and result.env_id == ENV_ID
    first, second = result.lengths
    assert _starts(spy.calls) == [0, first]  # once per episode, on its first step
    assert len(spy.calls) == first + second
    # each later step gets the previous step's state back; each episode starts from None
    assert [s for _, s in spy.calls[:first]] == [None, *range(first - 1)]
    assert spy.calls[first][1] is None


def test_load_policy_returns_objects_with_predict() -> None:
    env = gym.make(ENV_ID, **SHORT)
    obs, _ = env.reset(seed=0)
    assert isinstance(load_policy("expert", env), ExpertPolicy)
    random = load_policy("random", env, seed=7)
    assert isinstance(random, RandomPolicy)
    again = RandomPolicy(gym.make(ENV_ID, **SHORT).action_space, seed=7)
    # the seed is applied once, when loaded: the same stream as a fresh space seeded alike
    for _ in range(3):
        np.testing.assert_array_equal(random.predict(obs)[0], again.predict(obs)[0])
    zero = ZeroPolicy(env.action_space)  # type: ignore[arg-type]
    action, state = zero.predict(obs, state="kept")
    assert state == "kept" and not action.any() and action.dtype == env.action_space.dtype
    env.close()


def test_record_skills_takes_the_policy_object(tmp_path: Path) -> None:
    env = gym.make(ENV_ID, **SHORT)
    spy = _Spy(env.action_space)  # type: ignore[arg-type]
    db_path = tmp_path / "skills.db"
    ids = record_skills(env, spy, 2, db_path, seed=1, progress=False, source="spy")
    env.close()
    with SkillDB(db_path) as db:
        skills = [db.get(i) for i in ids]
    lengths = [len(s.demonstration.actions) for s in skills]
    assert _starts(spy.calls) == [0, lengths[0]]
    assert [s.source for s in skills] == ["spy", "spy"] and [s.seed for s in skills] == [1, 2]
    assert [s for _, s in spy.calls[: lengths[0]]] == [None, *range(lengths[0] - 1)]
