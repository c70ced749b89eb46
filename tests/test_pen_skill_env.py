"""IAS-PenSkill-v0: spaces, determinism, the skill draw, pickling, gym.make from a database."""

from __future__ import annotations

import pickle
import sqlite3
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from transfer_fixtures import synthetic_skill

import ias_gym  # noqa: F401  (registers the ids)
from ias_gym.baselines.expert import ExpertPolicy
from ias_gym.envs.pen_skill_env import PenSkillEnv
from ias_gym.envs.skill_reference import SkillReference
from ias_gym.errors import InputError
from ias_gym.glove.skills import SKILLS
from ias_gym.skills.check import check_database
from ias_gym.skills.db import SkillDB
from ias_gym.skills.transfer import shipped_skill_db, transfer_reference
from ias_gym.skills.workspace import HandWorkspace

WS = HandWorkspace(0.005, 0.2)


def references() -> list[SkillReference]:
    return [
        transfer_reference(synthetic_skill(lift=0.02, tilt=0.15), workspace=WS, duration=1.0),
        transfer_reference(synthetic_skill(lift=0.01, tilt=-0.1), workspace=WS, duration=1.0),
    ]


@pytest.fixture(scope="module")
def skill_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("penskill") / "skills.db"
    with SkillDB(path) as db:
        db.add(synthetic_skill(lift=0.02, tilt=0.15, duration=1.5))
        db.add(synthetic_skill(lift=0.01, tilt=-0.1, duration=1.5))
    return path


def test_spaces_and_the_observations_reference_block() -> None:
    env = PenSkillEnv(references=references(), duration=0.5)
    assert env.action_space.shape == (12,)
    assert env.observation_space.shape == (78,)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs) and np.all(np.isfinite(obs))
    # the reference now and 5, 10 steps ahead
    skill, part = env.skill, {k: obs[s] for k, s in env.observation_layout.items()}
    assert np.allclose(part["reference_position"], skill.position[0])
    assert np.allclose(part["reference_axis"], skill.axis[0])
    assert np.allclose(part["reference_position_ahead_5"], skill.position[5])
    assert np.allclose(part["reference_position_ahead_10"], skill.position[10])
    assert part["grasp_margin_reference"][0] == pytest.approx(skill.margin[0])
    check_env(env, skip_render_check=True)  # its determinism check compares the infos
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert env.observation_space.contains(obs) and isinstance(reward, float)
    assert isinstance(terminated, bool) and isinstance(truncated, bool)
    assert info["contact_forces"].shape == (4, 3) and info["internal_forces"].shape == (12,)


def test_the_same_seed_gives_the_same_skill_and_rollout() -> None:
    def rollout(seed: int) -> tuple[int, np.ndarray]:
        env = PenSkillEnv(references=references(), duration=0.3)
        obs, info = env.reset(seed=seed)
        expert = ExpertPolicy(env)
        observations = [obs]
        for _ in range(30):
            obs, *_ = env.step(expert.predict(obs)[0])
            observations.append(obs)
        return info["skill_index"], np.array(observations)

    a, b = rollout(4), rollout(4)
    assert a[0] == b[0] and np.array_equal(a[1], b[1])
    draws = {rollout(seed)[0] for seed in range(8)}
    assert draws == {0, 1}  # the draw uses the seeded generator and reaches every skill


def test_reset_option_picks_the_skill_and_refuses_a_bad_index() -> None:
    env = PenSkillEnv(references=references(), duration=0.3)
    for index in (1, 0, 1):
        _, info = env.reset(seed=0, options={"skill": index})
        assert info["skill_index"] == index
    with pytest.raises(InputError, match="not an index"):
        env.reset(options={"skill": 2})


def test_an_env_without_references_or_at_another_period_is_refused() -> None:
    with pytest.raises(InputError, match="at least one skill reference"):
        PenSkillEnv(reader=lambda *args: [])
    with pytest.raises(InputError, match=r"sampled every 0\.01 s"):
        PenSkillEnv(references=references(), control_dt=0.02)


def test_pickle_restores_the_episode() -> None:
    env = PenSkillEnv(references=references(), duration=0.5)
    obs, _ = env.reset(seed=1)
    expert = ExpertPolicy(env)
    for _ in range(10):
        obs = env.step(expert.predict(obs)[0])[0]
    clone = pickle.loads(pickle.dumps(env))
    action = expert.predict(obs)[0]
    a = env.step(action)
    b = clone.step(action)
    assert np.array_equal(a[0], b[0]) and a[1] == b[1]
    assert clone.skill.skill_id == env.skill.skill_id


def test_gym_make_reads_the_skills_of_a_database(skill_db: Path) -> None:
    env = gym.make("IAS-PenSkill-v0", skill_db=str(skill_db), duration=0.5)
    assert len(env.unwrapped.references) == 2
    assert {r.skill_id for r in env.unwrapped.references} == {1, 2}
    only = gym.make("IAS-PenSkill-v0", skill_db=str(skill_db), skill_ids=[2], duration=0.5)
    assert [r.skill_id for r in only.unwrapped.references] == [2]
    with pytest.raises(InputError, match="no skills with ids"):
        gym.make("IAS-PenSkill-v0", skill_db=str(skill_db), skill_ids=[7])


def test_the_skill_reader_is_injected_and_given_the_hand_and_its_grid() -> None:
    """Another store than a skill database: the env asks its reader, not the database."""
    calls = []

    def reader(skill_db, skill_ids, hand, control_dt, duration):  # type: ignore[no-untyped-def]
        calls.append((skill_db, skill_ids, hand, control_dt, duration))
        return references()

    env = gym.make(
        "IAS-PenSkill-v0", skill_db="a-store", skill_ids=[5], reader=reader, duration=0.5
    )
    assert calls == [("a-store", [5], "ias4f", 0.01, 0.5)]
    assert [r.skill_id for r in env.unwrapped.references] == [r.skill_id for r in references()]


def test_gym_make_uses_the_shipped_human_skills_by_default() -> None:
    env = gym.make("IAS-PenSkill-v0", duration=0.5, hand="ias3f")
    refs = env.unwrapped.references
    assert env.action_space.shape == (9,)  # the three-finger hand
    assert len({r.person for r in refs}) >= 2  # glove sessions of several people
    assert {r.name for r in refs} == set(SKILLS)  # every skill class of the glove library
    assert all(r.person and r.skill_id > 0 for r in refs)


def test_the_shipped_database_is_checked_and_readable_without_a_journal() -> None:
    path = shipped_skill_db()
    problems: list[tuple[int, str | None]] = []
    assert check_database(path, lambda i, problem: problems.append((i, problem))) == 0
    assert len(problems) == 12 and all(p is None for _, p in problems)
    # a rollback journal: a WAL database cannot be opened read-only where the reader cannot
    # create its -shm file (an installed package)
    with sqlite3.connect(f"file:{path}?mode=ro", uri=True) as conn:
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
