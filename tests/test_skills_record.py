"""Recording skills from the expert, the skill model's physics, Minari export and the CLI."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

from ias_gym.cli.skills_commands import add_skills_commands
from ias_gym.errors import IasGymError, InputError
from ias_gym.skills import (
    SkillDB,
    export_minari,
)
from ias_gym.skills.record import record_skills_spec

ENV_ID = "IAS-PenRotate-v0"
DURATION = 0.3  # [s] = 30 steps of 10 ms
STEPS = 30
#: A 0.3 s PenRotate episode judges tracking from 0.2 s on (settle_time < duration).
ENV_KWARGS = {"duration": DURATION, "settle_time": 0.2}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[int]]:
    path = tmp_path_factory.mktemp("skills") / "skills.db"
    ids = record_skills_spec(
        ENV_ID, "expert", 2, path, seed=3, progress=False, env_kwargs=ENV_KWARGS
    )
    return path, ids


def test_record_stores_one_skill_per_episode(recorded: tuple[Path, list[int]]) -> None:
    path, ids = recorded
    assert len(ids) == 2
    with SkillDB(path) as db:
        summaries = db.list_skills(task=ENV_ID)
        assert [s.id for s in summaries] == ids
        for episode, summary in enumerate(summaries):
            assert (summary.source, summary.seed) == ("expert", 3 + episode)
            assert summary.env_kwargs == ENV_KWARGS
            assert summary.length == STEPS and summary.is_success
            assert summary.duration == pytest.approx(DURATION)
            demo = db.get(summary.id).demonstration
            assert demo.observations.shape == (STEPS + 1, 55)
            assert demo.actions.shape == (STEPS, 12) and demo.actions.dtype == np.float32
            assert demo.rewards.shape == demo.terminations.shape == (STEPS,)
            assert demo.truncations[-1] and not demo.truncations[:-1].any()
            assert summary.episode_return == pytest.approx(float(demo.rewards.sum()))
            # Numeric infos: one row for the reset and one per step; bools stay bools.
            assert demo.infos["is_success"].dtype == np.bool_
            assert demo.infos["is_success"][-1] and not demo.infos["is_success"][0]
            assert demo.infos["max_contact_gap"].shape == (STEPS + 1, 4)
            np.testing.assert_allclose(demo.infos["time"], 0.01 * np.arange(STEPS + 1))
            total = sum(demo.infos[k][1:] for k in demo.infos if k.startswith("reward_"))
            np.testing.assert_allclose(total, demo.rewards)
        # Different seeds, different initial states: each start is nearest to itself.
        for summary in summaries:
            start = db.get(summary.id).demonstration.observations[0]
            assert db.nearest_initial_state(start, task=ENV_ID)[0][0].id == summary.id


def test_skill_model_is_the_grip_transform_along_the_episode(
    recorded: tuple[Path, list[int]],
) -> None:
    path, ids = recorded
    weight = gym.make(ENV_ID).unwrapped.physics.pen_mass() * 9.81  # type: ignore[attr-defined]
    with SkillDB(path) as db:
        model = db.get(ids[0]).model
    S = STEPS + 1
    assert model.c.shape == model.c_h.shape == (S, 12)
    assert model.f_int.shape == model.f_ext.shape == (S, 6)
    np.testing.assert_allclose(np.diff(model.time), 0.01)
    all_touch = model.touching.all(axis=1)
    # The expert holds the pen with four fingers (a top finger may lift for one sample
    # while the grasp settles).
    assert all_touch.mean() >= 0.9
    assert not model.sliding.any()  # PenRotate slides no finger
    # c = c_p + c_h (eq. 4) with c_p orthogonal to c_h, and c_h = N f_int with N orthonormal
    # (eq. 7): |c_h| = |f_int|. f_int is finite, 6 per step, while all four fingers touch.
    np.testing.assert_allclose(model.c_p + model.c_h, model.c, atol=1e-15)
    np.testing.assert_allclose(np.einsum("ij,ij->i", model.c_p, model.c_h), 0.0, atol=1e-12)
    np.testing.assert_allclose(
        np.linalg.norm(model.c_h, axis=1), np.linalg.norm(model.f_int, axis=1), rtol=1e-9
    )
    assert np.isfinite(model.f_int[all_touch]).all()
    assert np.abs(model.f_int).max() > 0.01  # the grasp squeezes: internal forces exist
    # Once the grasp has settled (50 ms), f_ext = W c holds the pen up (docs/NOTES.md:
    # W c = [0, +mg, 0, 0, 0, 0]) and every finger pushes.
    settled = model.time >= 0.05
    np.testing.assert_allclose(model.f_ext[settled, 1], weight, rtol=0.05)
    assert model.c[settled][:, 0::3].min() > 0
    assert np.abs(model.pen_position).max() < 0.005  # the pen stays within 5 mm


def test_export_minari_loads_and_recovers_the_env(
    recorded: tuple[Path, list[int]], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import minari

    from ias_gym.skills import minari_export

    path, _ = recorded
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    monkeypatch.setattr(minari_export, "CHUNK_EPISODES", 1)  # create, then append
    dataset_id = "ias/pen-rotate-expert-v0"
    out = export_minari(path, dataset_id, task=ENV_ID)
    assert out == tmp_path / "datasets" / "ias" / "pen-rotate-expert-v0"
    dataset = minari.load_dataset(dataset_id)
    assert dataset.total_episodes == 2 and dataset.total_steps == 2 * STEPS
    episode = next(dataset.iterate_episodes())
    assert episode.observations.shape == (STEPS + 1, 55)
    assert episode.actions.shape == (STEPS, 12)
    with SkillDB(path) as db:
        first = db.list_skills()[0]
        np.testing.assert_array_equal(
            episode.observations, db.get(first.id).demonstration.observations
        )
    env = dataset.recover_environment()
    assert env.spec is not None and env.spec.id == ENV_ID
    assert env.unwrapped.config.duration == DURATION
    obs, _ = env.reset(seed=0)
    assert obs.shape == (55,)
    env.close()

    with pytest.raises(FileExistsError, match="exists already"):
        export_minari(path, dataset_id)
    with pytest.raises(ValueError, match="no skills of task 'IAS-PenSlide-v0'"):
        export_minari(path, "ias/none-v0", task="IAS-PenSlide-v0")

    def fail(*args: object) -> None:
        raise OSError("disk full")

    monkeypatch.setattr(minari.MinariDataset, "update_dataset_from_buffer", fail)
    with pytest.raises(OSError, match="disk full"):
        export_minari(path, "ias/broken-v0")
    assert not (tmp_path / "datasets" / "ias" / "broken-v0").exists()  # no half dataset


def test_export_without_minari_says_which_extra(
    recorded: tuple[Path, list[int]], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "minari", None)  # import minari -> ImportError
    with pytest.raises(ImportError, match=r"pip install 'ias-gym\[datasets\]'"):
        export_minari(recorded[0], "ias/x-v0")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="ias-gym")
    commands = parser.add_subparsers(dest="command", required=True)
    add_skills_commands(commands)
    return parser


def _run(argv: list[str]) -> int:
    args = _parser().parse_args(argv)
    code: int = args.run(args)
    return code


def test_cli_record_list_show_export(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    db = str(tmp_path / "cli.db")
    kwargs = json.dumps({"duration": 0.1, "settle_time": 0.0})
    assert _run(["skills", "record", "--env", ENV_ID, "--episodes", "2", "--db", db,
                 "--seed", "5", "--env-kwargs", kwargs, "--no-progress"]) == 0  # fmt: skip
    assert f"stored 2 skills (ids 1, 2) in {db}" in capsys.readouterr().out

    assert _run(["skills", "list", "--db", db, "--task", ENV_ID, "--json"]) == 0
    listed = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert [s["id"] for s in listed] == [1, 2]
    assert set(listed[0]) == {
        "id", "name", "task", "source", "is_success", "return", "length", "created"
    }  # fmt: skip
    assert listed[0]["task"] == ENV_ID and listed[0]["length"] == 10
    assert _run(["skills", "list", "--db", db]) == 0
    assert f"2 skills in {db}" in capsys.readouterr().out

    assert _run(["skills", "show", "--db", db, "--id", "2"]) == 0
    text = capsys.readouterr().out
    assert "skill 2:" in text and "finger 4: touching 100%" in text and "f_int[6]" in text
    assert _run(["skills", "show", "--db", db, "--id", "2", "--json"]) == 0
    shown = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert shown["model"]["duration"] == pytest.approx(0.1)
    assert len(shown["model"]["f_int_range"]) == 6 and shown["seed"] == 6

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    assert _run(["skills", "export", "--db", db, "--format", "minari",
                 "--dataset-id", "ias/cli-v0", "--task", ENV_ID]) == 0  # fmt: skip
    assert str(tmp_path / "datasets" / "ias" / "cli-v0") in capsys.readouterr().out

    # Errors: the package's own error type with the message (the ias-gym command prints
    # it as one line).
    with pytest.raises(IasGymError, match="no skill with id 99"):
        _run(["skills", "show", "--db", db, "--id", "99"])
    bad = tmp_path / "bad.db"
    bad.write_bytes(b"\x00garbage" * 100)
    with pytest.raises(IasGymError, match=f"{bad} is not a skill database or is corrupt"):
        _run(["skills", "list", "--db", str(bad)])
    with pytest.raises(InputError, match="--env-kwargs must be a JSON object"):
        _run(["skills", "record", "--env", ENV_ID, "--db", db, "--env-kwargs", "[1]"])


@pytest.mark.parametrize(
    "command",
    [[], ["record"], ["list"], ["show"], ["export"], ["check"], ["delete"], ["migrate"]],
)
def test_cli_help(command: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        _parser().parse_args(["skills", *command, "--help"])
    assert done.value.code == 0
    assert "usage: ias-gym skills" in capsys.readouterr().out


class _StartFrom(gym.Wrapper):  # type: ignore[type-arg]
    """Resets from given options (a perturbed start) whatever the caller passes."""

    def __init__(self, env: gym.Env, options: dict | None) -> None:  # type: ignore[type-arg]
        super().__init__(env)
        self._options = options

    def reset(self, **kwargs):  # type: ignore[no-untyped-def]
        return self.env.reset(seed=kwargs.get("seed"), options=self._options)


@pytest.mark.closed_loop
def test_recorded_expert_holds_the_pen_from_nearby_starts() -> None:
    """The recorded expert's skill model (success, four fingers touching, the fingers carrying
    the pen's weight, the pen within 5 mm) holds from seed 3 and starts 1e-9 from it."""
    from ias_gym.baselines.policies import load_policy
    from ias_gym.skills.record import record_episode
    from tests.closed_loop import perturbed_starts

    env = gym.make(ENV_ID, **ENV_KWARGS)
    weight = env.unwrapped.physics.pen_mass() * 9.81  # type: ignore[attr-defined]
    for options in perturbed_starts(env, seed=3):
        wrapped = _StartFrom(env, options)
        policy = load_policy("expert", wrapped)  # a fresh controller for each episode
        skill = record_episode(wrapped, policy, seed=3, source="expert")
        model = skill.model
        assert skill.is_success
        assert model.touching.all(axis=1).mean() >= 0.9
        settled = model.time >= 0.05
        np.testing.assert_allclose(model.f_ext[settled, 1], weight, rtol=0.05)
        assert np.abs(model.pen_position).max() < 0.005
