"""One validator for person and glove ids, at every place where an id becomes a file name.

Before, ``gym.make("IAS-GloveGrasp-v0", person_id="/some/dir/abs")`` trained a calibration
and wrote ``/some/dir/abs-seed0.json`` (creating the folder), ``../x`` wrote next to the
cache folder, and skills, profiles and Minari datasets carried such ids on.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sqlite3
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import pytest
from test_skills_db import synthetic_skill

from ias_gym.errors import InputError
from ias_gym.glove import PersonParams
from ias_gym.glove.ids import MAX_ID_LENGTH, check_id

#: Each must be refused wherever an id enters.
HOSTILE = {
    "absolute": "{tmp}/abs",
    "parent": "../x",
    "dotdot": "..",
    "dot": ".",
    "slash": "a/b",
    "backslash": "a\\b",
    "empty": "",
    "nul": "a\x00b",
    "long": "p" * (MAX_ID_LENGTH + 1),
    "space": "p 1",
    "newline": "p1\n",
    "non-ascii": "p\u00e91",
}


def hostile(name: str, tmp_path: Path) -> str:
    return HOSTILE[name].format(tmp=tmp_path / "victim")


def files_under(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*"))


@pytest.fixture()
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty profile cache under tmp_path (XDG_CACHE_HOME), so nothing escapes it."""
    path = tmp_path / "cache"
    monkeypatch.setenv("XDG_CACHE_HOME", str(path))
    return path


# ---------------------------------------------------------------------------- the rule
@pytest.mark.parametrize("good", ["p1", "sim-glove-0", "Alice_2.v3", "x" * MAX_ID_LENGTH, "..."])
def test_valid_ids_pass_unchanged(good: str) -> None:
    assert check_id(good, "person_id") is good


@pytest.mark.parametrize("name", list(HOSTILE))
def test_check_id_names_the_value_and_the_rule(name: str, tmp_path: Path) -> None:
    value = hostile(name, tmp_path)
    with pytest.raises(InputError) as err:
        check_id(value, "glove_id")
    message = str(err.value)
    assert message.startswith("glove_id ")
    assert repr(value) in message
    assert "letters, digits, '.', '_' or '-'" in message and "not '.' or '..'" in message


def test_non_strings_are_refused() -> None:
    for value in (None, 5, b"p1", ["p1"]):
        with pytest.raises(InputError, match="person_id must be a string"):
            check_id(value)


# ---------------------------------------------------------------------------- entry points
@pytest.mark.parametrize("name", list(HOSTILE))
def test_gym_make_refuses_before_touching_any_file(name: str, tmp_path: Path, cache: Path) -> None:
    """The env config (gym.make / --env-kwargs / evaluate) refuses the id before the
    profile cache is looked at: no training, no file, no folder."""
    value = hostile(name, tmp_path)
    with pytest.raises(InputError, match="person_id"):
        gym.make("IAS-GloveGrasp-v0", person_id=value)
    assert files_under(tmp_path) == []


def test_person_params_and_the_profile_cache_refuse_hostile_ids(
    tmp_path: Path, cache: Path
) -> None:
    from ias_gym.glove.profile_cache import default_calibration

    with pytest.raises(InputError, match=r"person_id '\.\./x'"):
        PersonParams.sample("../x")
    with pytest.raises(InputError, match="person_id"):
        dataclasses.replace(PersonParams.nominal(), person_id="/etc/x")
    # A PersonParams whose id was changed behind the dataclass's back: the cache file name
    # is checked on its own.
    person = PersonParams.sample("p1")
    object.__setattr__(person, "person_id", str(tmp_path / "victim" / "abs"))
    with pytest.raises(InputError, match="person_id"):
        default_calibration(person)
    assert files_under(tmp_path) == []


def _skills(argv: list[str]) -> int:
    from ias_gym.cli.skills_commands import add_skills_commands

    parser = argparse.ArgumentParser(prog="ias-gym")
    add_skills_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    code: int = args.run(args)
    return code


@pytest.mark.parametrize("name", ["absolute", "parent", "slash", "empty"])
def test_skills_record_refuses_hostile_ids_before_creating_the_database(
    name: str, tmp_path: Path, cache: Path
) -> None:
    value = hostile(name, tmp_path)
    db = tmp_path / "out" / "skills.db"
    record = ["skills", "record", "--env", "IAS-GloveGrasp-v0", "--policy", "teleop",
              "--db", str(db), "--no-progress"]  # fmt: skip
    with pytest.raises(InputError, match="person_id"):
        _skills([*record, "--env-kwargs", json.dumps({"person_id": value})])
    with pytest.raises(InputError, match="person_id"):
        _skills([*record, "--person", value])
    assert files_under(tmp_path) == []


@pytest.mark.parametrize("name", ["absolute", "parent", "dotdot", "nul"])
def test_skill_rows_refuse_hostile_person_ids(name: str, tmp_path: Path) -> None:
    from ias_gym.skills import SkillDB

    value = hostile(name, tmp_path)
    good = synthetic_skill(0)
    with SkillDB(tmp_path / "skills.db") as db:
        with pytest.raises(InputError, match="person_id"):
            db.add(dataclasses.replace(good, person_id=value))
        with pytest.raises(InputError, match="env_kwargs person_id"):
            db.add(dataclasses.replace(good, env_kwargs={"person_id": value}))
        assert len(db) == 0


def test_export_refuses_a_stored_hostile_person_id(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A database written elsewhere (here: edited) whose env kwargs name a hostile person:
    the Minari export refuses it before it builds the env or writes the dataset."""
    pytest.importorskip("minari")
    from ias_gym.skills import SkillDB, export_minari

    datasets = tmp_path / "datasets"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(datasets))
    path = tmp_path / "skills.db"
    skill = dataclasses.replace(
        synthetic_skill(0), task="IAS-GloveGrasp-v0", env_kwargs={"person_id": "p1"}
    )
    with SkillDB(path) as db:
        db.add(skill)
    evil = str(tmp_path / "victim" / "evil")
    with sqlite3.connect(path) as conn:
        conn.execute("UPDATE skills SET env_kwargs = ?", (json.dumps({"person_id": evil}),))
    conn.close()
    with pytest.raises(InputError, match="person_id"):
        export_minari(path, "ias/evil-v0")
    assert not (tmp_path / "victim").exists() and not datasets.exists()
    assert files_under(cache) == []


def test_recover_environment_of_a_hostile_minari_dataset(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A downloaded dataset whose env spec carries a hostile person id: recovering the env
    raises before any calibration is trained or file written."""
    minari = pytest.importorskip("minari")
    from gymnasium import spaces
    from minari.data_collector.episode_buffer import EpisodeBuffer

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    buffer = EpisodeBuffer(
        id=0,
        observations=np.zeros((2, 39)),
        actions=np.zeros((1, 10), dtype=np.float32),
        rewards=[0.0],
        terminations=[False],
        truncations=[True],
        infos={},
    )
    with pytest.warns(UserWarning):  # minari asks for author, env spec, ...
        dataset = minari.create_dataset_from_buffers(
            "ias/hostile-v0",
            buffer=[buffer],
            observation_space=spaces.Box(-np.inf, np.inf, (39,), np.float64),
            action_space=spaces.Box(-1.0, 1.0, (10,), np.float32),
        )
    evil = str(tmp_path / "victim" / "abs")
    spec: Any = dataclasses.replace(gym.spec("IAS-GloveGrasp-v0"), kwargs={"person_id": evil})
    dataset.storage.update_metadata({"env_spec": spec.to_json()})
    loaded = minari.load_dataset("ias/hostile-v0")
    assert loaded.env_spec.kwargs["person_id"] == evil
    with pytest.raises(InputError, match="person_id"):
        loaded.recover_environment()
    assert not (tmp_path / "victim").exists() and files_under(cache) == []


@pytest.mark.parametrize("name", ["absolute", "parent", "backslash", "long", "dot"])
def test_calibrate_refuses_hostile_person_and_glove_ids(name: str, tmp_path: Path) -> None:
    from ias_gym.cli.glove_commands import add_glove_commands

    parser = argparse.ArgumentParser(prog="ias-gym")
    add_glove_commands(parser.add_subparsers(dest="command", required=True))
    value = hostile(name, tmp_path)
    out = tmp_path / "out"
    for option, argv in (
        ("--person", ["--person", value]),
        ("--glove-id", ["--person", "p1", "--glove-id", value]),
    ):
        args = parser.parse_args(["calibrate", *argv, "--out", str(out), "--max-iter", "1"])
        with pytest.raises(InputError, match=option):
            args.run(args)
    assert files_under(tmp_path) == []
