"""Learning across human skills (train/pen_skill_bc.py), tiny: the split, then the pipeline.

The split must keep every held-out skill and person out of the training group (a property
over random libraries); the pipeline (DART demonstrations of the expert on
``IAS-PenSkill-v0`` restricted to the training skills, cloning, safe save and load) must
run on either hand with short episodes and give a policy that acts in the env.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

import cloudpickle  # noqa: E402
from stable_baselines3 import PPO  # noqa: E402

from ias_gym.baselines.policies import load_policy  # noqa: E402
from ias_gym.glove.skills import SKILLS  # noqa: E402
from ias_gym.learning.cloning import action_mse, behaviour_clone  # noqa: E402
from ias_gym.learning.dart import record_noisy_expert  # noqa: E402
from ias_gym.learning.demonstrations import load_demonstrations  # noqa: E402
from ias_gym.learning.skill_split import GROUPS, split_skills  # noqa: E402
from ias_gym.skills.db import SkillDB, SkillSummary  # noqa: E402
from ias_gym.skills.transfer import shipped_skill_db  # noqa: E402

ENV_ID = "IAS-PenSkill-v0"
ROOT = Path(__file__).resolve().parents[1]
HELDOUT_SKILLS = ("seesaw_fast", "lift_place")
PERSONS = ("p1", "p2", "p3", "hx-1", "hx-2")
#: The group of a session by (its person is held out, its skill is held out).
GROUP_OF = {
    (False, False): "train",
    (False, True): "heldout_skill",
    (True, False): "heldout_person",
    (True, True): "heldout_both",
}


def _summary(i: int, name: str, person: str | None, success: bool) -> SkillSummary:
    return SkillSummary(
        id=i,
        name=name,
        task="IAS-GloveGrasp-v0",
        source="glove:sim-glove-0",
        person_id=person,
        created="",
        package_version="",
        seed=0,
        env_kwargs={},
        is_success=success,
        episode_return=0.0,
        length=1,
        duration=0.0,
    )


@settings(max_examples=200, deadline=None)
@given(
    rows=st.lists(
        st.tuples(
            st.sampled_from(SKILLS),
            st.sampled_from((*PERSONS, None, "")),
            st.booleans(),
        ),
        max_size=40,
    ),
    heldout_skills=st.sets(st.sampled_from(SKILLS)),
    heldout_persons=st.sets(st.sampled_from(PERSONS)),
)
def test_split_keeps_held_out_skills_and_persons_out_of_training(
    rows: list[tuple[str, str | None, bool]],
    heldout_skills: set[str],
    heldout_persons: set[str],
) -> None:
    summaries = [_summary(i + 1, *row) for i, row in enumerate(rows)]
    split = split_skills(summaries, sorted(heldout_skills), sorted(heldout_persons))
    by_id = {s.id: s for s in summaries}
    groups = [split.group(g) for g in GROUPS]
    everything = [i for ids in groups for i in ids]
    # A partition of the successful human sessions: each in exactly one group.
    assert sorted(everything) == sorted(s.id for s in summaries if s.person_id and s.is_success)
    for name, ids in zip(GROUPS, groups, strict=True):
        for i in ids:
            person_out = by_id[i].person_id in heldout_persons
            skill_out = by_id[i].name in heldout_skills
            assert name == GROUP_OF[(person_out, skill_out)]
    for i in split.train:
        assert by_id[i].name not in heldout_skills
        assert by_id[i].person_id not in heldout_persons


def test_training_library_of_the_shipped_skills_excludes_held_out_skills() -> None:
    with SkillDB(shipped_skill_db(), readonly=True) as db:
        split = split_skills(db.list_skills(), HELDOUT_SKILLS, ["p2"])
    env = gym.make(ENV_ID, skill_ids=list(split.train))
    refs = env.unwrapped.references  # type: ignore[attr-defined]
    assert {r.name for r in refs} == set(SKILLS) - set(HELDOUT_SKILLS)
    assert {r.person for r in refs} == {"p1"}
    assert len(split.heldout_skill) == 2 and len(split.heldout_person) == 4
    env.close()


@pytest.mark.parametrize(("hand", "k"), [("ias4f", 4), ("ias3f", 3)])
def test_pipeline_records_clones_saves_and_acts(
    hand: str, k: int, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    torch.set_num_threads(1)
    with SkillDB(shipped_skill_db(), readonly=True) as db:
        split = split_skills(db.list_skills(), HELDOUT_SKILLS, ["p2"])
    kwargs: dict[str, Any] = {
        "hand": hand,
        "skill_ids": list(split.train),
        "duration": 0.3,
        "settle_time": 0.1,
    }
    db_path = tmp_path / "demos.db"
    ids = record_noisy_expert(ENV_ID, 3, db_path, 0.001, progress=False, env_kwargs=kwargs)
    assert len(ids) == 3
    with SkillDB(db_path, readonly=True) as db:  # what was recorded ran the training skills
        assert all(db.get(i).env_kwargs["skill_ids"] == list(split.train) for i in ids)
    demos = load_demonstrations(db_path, ENV_ID)
    env = gym.make(ENV_ID, **kwargs)
    obs_dim = 9 * k + 13 + 29  # joints (6 k), pen (12), tip forces (3 k), time, the skill's
    assert env.observation_space.shape == (obs_dim,)
    assert demos.observations.shape[1] == obs_dim
    assert demos.actions.shape[1] == 3 * k

    untrained = behaviour_clone(
        env, demos.observations, demos.actions, epochs=1, lr=1e-12, progress=False
    )
    model = behaviour_clone(env, *demos, epochs=30, batch_size=32, progress=False)
    before = action_mse(untrained, demos.observations, demos.actions)
    after = action_mse(model, demos.observations, demos.actions)
    assert after < before / 10

    path = tmp_path / "bc.zip"
    model.save(path)

    def no_unpickling(*args: object, **kwargs: object) -> None:
        raise AssertionError("the policy file was unpickled")

    # SB3's own load unpickles (cloudpickle.loads on the zip's data, torch.load of the
    # optimiser state): none of them may run.
    monkeypatch.setattr(pickle, "loads", no_unpickling)
    monkeypatch.setattr(pickle, "load", no_unpickling)
    monkeypatch.setattr(cloudpickle, "loads", no_unpickling)
    monkeypatch.setattr(PPO, "load", no_unpickling)
    policy = load_policy(str(path), env)
    monkeypatch.undo()
    obs, _ = env.reset(seed=5)
    expected = model.predict(obs, deterministic=True)[0]
    for _ in range(5):
        action = policy.predict(obs, deterministic=True)[0]
        assert action.shape == (3 * k,) and env.action_space.contains(action)
        obs, *_ = env.step(action)
        assert obs.shape == (obs_dim,)
    np.testing.assert_allclose(
        policy.predict(env.reset(seed=5)[0], deterministic=True)[0], expected, atol=1e-6
    )
    env.close()


def run_script(args: list[str], timeout: float) -> subprocess.CompletedProcess[str]:
    """``train/pen_skill_bc.py ARGS`` in a subprocess, the repo on its path."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH")) if p)
    return subprocess.run(
        [sys.executable, str(ROOT / "train" / "pen_skill_bc.py"), *args],
        capture_output=True,
        text=True,
        timeout=timeout,
        check=False,
        env={**os.environ, "PYTHONPATH": path},
    )


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        ((), "overwrite"),  # results.json is there
        (("--heldout-seed", "5150"), "training persons' seed"),  # the training persons' own
        (("--heldout-persons", "0"), "population size 0"),
        (("--randomise", "mass,gravity"), "unknown randomisation families ['gravity']"),
        (("--skills", "lift_hold,juggle"), "unknown skills ['juggle']"),
        (("--synthetic-skills", "-1"), "--synthetic-skills must be >= 0"),
        (("--dagger-iterations", "0"), "must be >= 1"),
        (("--skills", "lift_hold", "--heldout-skills", "lift_place"), "not among --skills"),
        (("--dagger-iterations", "2", "--takeover", "nan"), "--takeover must be finite"),
        (("--ensemble", "3"), "--ensemble act only in DAgger"),  # a BC run would ignore it
        (("--train-db", "/nonexistent/library.db"), "--train-db: no skill database"),
    ],
)
def test_script_refuses_bad_input_before_work(
    tmp_path: Path, extra: tuple[str, ...], expected: str
) -> None:
    (tmp_path / "results.json").write_text("{}")
    args = ["--heldout-seed", "1", "--set", "development", "--out", str(tmp_path)]
    if extra:
        args += [*extra, "--overwrite"]
    result = run_script(args, timeout=60)
    assert result.returncode == 2
    assert expected in result.stderr and len(result.stderr.strip().splitlines()) == 1
    assert (tmp_path / "results.json").read_text() == "{}"
    assert not (tmp_path / "demos.db").exists()
    assert not (tmp_path / "train_library.db").exists()


def test_dagger_on_skills_labels_the_learners_states_on_synthetic_references() -> None:
    """DAgger runs on IAS-PenSkill-v0 with a library of synthetic skills: after the
    expert's iteration the learner acts, and every state it visited is labelled."""
    from ias_gym.learning.dagger import dagger
    from ias_gym.learning.randomised_dynamics import NOMINAL
    from ias_gym.skills.synthetic import synthetic_references

    refs = synthetic_references(4, [np.full(10, 1.5)], "ias4f", 0.01, 0.3, seed=2)
    kwargs: dict[str, Any] = {"references": tuple(refs), "duration": 0.3}
    run = dagger(
        ENV_ID,
        2,
        2,
        seed=3,
        beta_decay=0.0,
        randomisation=NOMINAL,
        env_kwargs=kwargs,
        epochs=2,
        progress=False,
    )
    first, second = run.history
    assert first.expert_fraction == 1.0 and second.expert_fraction < 1.0
    assert second.env_steps > 0 and first.labels_added + second.labels_added == len(run.dataset)
    env = gym.make(ENV_ID, **kwargs)
    obs, _ = env.reset(seed=0)
    action = run.model.predict(obs, deterministic=True)[0]
    assert action.shape == env.action_space.shape and np.all(np.isfinite(action))
    env.close()


def test_script_runs_dagger_on_human_and_synthetic_skills(tmp_path: Path) -> None:
    """The script end to end with DAgger and synthetic skills, at a tiny budget: the
    learner acted in the second iteration (no gate), the run is described, the policy
    loads."""
    import json

    out = tmp_path / "run"
    args = [
        *("--train-db", str(shipped_skill_db()), "--skills", "lift_hold,tilt_left"),
        *("--heldout-skills", "tilt_left", "--heldout-persons", "1", "--heldout-seed", "1"),
        *("--set", "development", "--n-demos", "1", "--dagger-iterations", "2"),
        *("--episodes-per-iteration", "1", "--synthetic-skills", "3", "--epochs", "1"),
        *("--ppo-steps", "0", "--critic-warmup", "0", "--val-episodes", "0"),
        *("--takeover", "10", "--max-eval-skills", "1", "--out", str(out)),
    ]
    result = run_script(args, timeout=600)
    assert result.returncode == 0, result.stderr[-2000:]
    results = json.loads((out / "results.json").read_text())
    assert results["method"] == "dagger" and results["synthetic_skills"] == 3
    first, second = results["dagger"]["history"]
    assert first["expert_fraction"] == 1.0 and second["expert_fraction"] < 1.0
    assert results["skills"] == ["lift_hold", "tilt_left"]
    assert set(results["groups"]) <= set(GROUPS) and "train" in results["groups"]
    env = gym.make(ENV_ID)
    policy = load_policy(str(out / "bc.zip"), env)
    action = policy.predict(env.reset(seed=0)[0], deterministic=True)[0]
    assert action.shape == env.action_space.shape
    env.close()
