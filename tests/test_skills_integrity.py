"""Skill database integrity: read-only commands create nothing, every array is checksummed,
old files migrate, and `skills check` / `skills delete` deal with damaged skills."""

from __future__ import annotations

import argparse
import json
import sqlite3
import struct
from pathlib import Path

import numpy as np
import pytest
from test_skills_db import assert_identical, synthetic_skill

from ias_gym.cli.skills_commands import add_skills_commands
from ias_gym.skills import SkillDB, SkillDBError, SkillNotFoundError
from ias_gym.skills.db import DEMO_ARRAYS, MODEL_ARRAYS, SCHEMA_VERSION


def run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="ias-gym")
    add_skills_commands(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["skills", *argv])
    code: int = args.run(args)
    return code


def make_db(path: Path, n: int = 3) -> list[int]:
    with SkillDB(path) as db:
        return [db.add(synthetic_skill(k, T=20)) for k in range(n)]


def flip_bit_in_file(path: Path, value: float, bit: int = 62) -> float:
    """Flip one bit of the float64 ``value`` where it sits in the file (bit rot), return
    the value the file then holds there. The page stays valid SQLite."""
    raw = bytearray(path.read_bytes())
    needle = struct.pack("<d", value)
    at = raw.find(needle)
    assert at >= 0 and raw.find(needle, at + 1) < 0, "value not unique in the file"
    (as_int,) = struct.unpack("<Q", needle)
    flipped = struct.pack("<Q", as_int ^ (1 << bit))
    raw[at : at + 8] = flipped
    path.write_bytes(bytes(raw))
    return float(struct.unpack("<d", flipped)[0])


# ---------------------------------------------------------------------------- read-only
READ_COMMANDS = {
    "list": ["list"],
    "show": ["show", "--id", "1"],
    "export": ["export", "--dataset-id", "ias/nothing-v0"],
    "check": ["check"],
    "delete": ["delete", "--id", "1"],
    "migrate": ["migrate"],
}


@pytest.mark.parametrize("command", list(READ_COMMANDS))
def test_commands_on_a_missing_path_create_nothing(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Before, `skills list --db /no/such/dir/x.db` made the folders and an empty database
    and printed "no skills"; show and export made the file too."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    path = tmp_path / "no" / "such" / "dir" / "x.db"
    with pytest.raises(SkillDBError, match=f"no skill database at {path} .nothing was created"):
        run([*READ_COMMANDS[command], "--db", str(path)])
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", list(READ_COMMANDS))
def test_commands_refuse_an_empty_file(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A 0-byte file was taken as a new database (and turned into one)."""
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    path = tmp_path / "empty.db"
    path.touch()
    with pytest.raises(SkillDBError, match=rf"{path} is empty \(0 bytes\), not a skill database"):
        run([*READ_COMMANDS[command], "--db", str(path)])
    assert path.stat().st_size == 0
    assert [p.name for p in tmp_path.iterdir()] == ["empty.db"]


def test_read_only_open_never_writes(tmp_path: Path) -> None:
    path = tmp_path / "x.db"
    with pytest.raises(SkillDBError, match="no skill database"):
        SkillDB(path, readonly=True)
    with pytest.raises(SkillDBError, match="no skill database"):
        SkillDB(path, create=False)
    assert not path.exists()

    # An SQLite file without the skill schema is refused and left as it is.
    with sqlite3.connect(path) as conn:
        conn.execute("PRAGMA user_version = 0")
        conn.execute("CREATE TABLE t (x)")
        conn.execute("DROP TABLE t")
    conn.close()
    before = path.read_bytes()
    for flags in ({"readonly": True}, {"create": False}):  # (delete, migrate: create=False)
        with pytest.raises(SkillDBError, match="without the skill schema"):
            SkillDB(path, **flags)
    assert path.read_bytes() == before

    ids = make_db(path := tmp_path / "skills.db", 2)
    with SkillDB(path, readonly=True) as db:
        assert db.ids() == ids and db.get(ids[0]).name == "skill 0"
        with pytest.raises(SkillDBError, match="open read-only"):
            db.add(synthetic_skill(5))
        with pytest.raises(SkillDBError, match="open read-only"):
            db.delete(ids[0])
    with SkillDB(path) as db:
        assert db.ids() == ids


# ---------------------------------------------------------------------------- checksums
def test_a_flipped_bit_inside_an_array_is_caught(tmp_path: Path) -> None:
    """The page stays intact, so SQLite's integrity check passes; before, the skill loaded
    with 4.8e303-like numbers in its observations."""
    path = tmp_path / "skills.db"
    ids = make_db(path)
    value = float(synthetic_skill(1, T=20).demonstration.observations[3, 2])
    rotten = flip_bit_in_file(path, value)
    assert abs(rotten) > 1e300 or abs(rotten) < 1e-300  # an exponent bit
    with SkillDB(path, readonly=True) as db:
        db.integrity_check()  # SQLite sees nothing wrong
        with pytest.raises(
            SkillDBError,
            match=rf"skill {ids[1]} in {path} is corrupt: array demo/observations does not "
            r"match its checksum.*skills delete --db .* --id 2",
        ):
            db.get(ids[1])
        for other in (ids[0], ids[2]):  # the others still load, bit-identical
            assert_identical(
                db.get(other).demonstration.observations,
                synthetic_skill(other - 1, T=20).demonstration.observations,
            )


@pytest.mark.parametrize(
    ("column", "value"),
    [("dtype", "'>f8'"), ("shape", "'[6, 21]'"), ("data", "zeroblob(length(data))")],
)
def test_edited_dtype_shape_or_bytes_fail_the_checksum(
    tmp_path: Path, column: str, value: str
) -> None:
    path = tmp_path / "skills.db"
    (skill_id,) = make_db(path, 1)
    with sqlite3.connect(path) as conn:
        conn.execute(f"UPDATE arrays SET {column} = {value} WHERE name = 'f_ext'")
    conn.close()
    with SkillDB(path) as db:
        with pytest.raises(SkillDBError, match="array model/f_ext does not match its checksum"):
            db.get(skill_id)


def test_a_flipped_first_observation_copy_is_caught(tmp_path: Path) -> None:
    """The copy of the first observation (the nearest-state index) is checksummed too."""
    path = tmp_path / "skills.db"
    starts = [np.full(5, 0.25), np.full(5, 0.5)]
    with SkillDB(path) as db:
        ids = [db.add(synthetic_skill(k, T=20, obs0=s)) for k, s in enumerate(starts)]
    with sqlite3.connect(path) as conn:
        (blob,) = conn.execute("SELECT initial_observation FROM skills WHERE id = ?", (ids[1],))
        data = bytearray(blob[0])
        data[5] ^= 0x10
        conn.execute("UPDATE skills SET initial_observation = ? WHERE id = ?", (data, ids[1]))
    conn.close()
    with SkillDB(path, readonly=True) as db:
        with pytest.raises(SkillDBError, match=f"skill {ids[1]} .* initial_observation"):
            db.nearest_initial_state(np.full(5, 0.5))
        with pytest.raises(SkillDBError, match="initial_observation does not match"):
            db.check_skill(ids[1])
        db.check_skill(ids[0])


def test_check_command_reports_every_skill_and_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "skills.db"
    ids = make_db(path, 4)
    assert run(["check", "--db", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == [f"skill {i}: OK" for i in ids] + [f"checked {path}: all OK"]

    flip_bit_in_file(path, float(synthetic_skill(2, T=20).model.c[4, 7]))
    with sqlite3.connect(path) as conn:  # skill 4 loses an array (a partial write elsewhere)
        conn.execute("DELETE FROM arrays WHERE skill_id = ? AND name = 'rewards'", (ids[3],))
    conn.close()
    before = path.read_bytes()
    assert run(["check", "--db", str(path)]) == 2
    out = capsys.readouterr().out.splitlines()
    assert out[0] == f"skill {ids[0]}: OK" and out[1] == f"skill {ids[1]}: OK"
    assert out[2].startswith(f"skill {ids[2]}: ") and "array model/c does not match" in out[2]
    assert out[3].startswith(f"skill {ids[3]}: ") and "missing demo arrays ['rewards']" in out[3]
    assert out[4] == f"checked {path}: 2 corrupt"

    assert run(["check", "--db", str(path), "--json"]) == 2
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(r["id"], r["ok"]) for r in rows] == [(1, True), (2, True), (3, False), (4, False)]
    assert rows[0]["error"] is None and "model/c" in rows[2]["error"]
    assert path.read_bytes() == before  # check is read-only


def test_show_and_export_refuse_a_corrupt_skill(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("minari")
    datasets = tmp_path / "datasets"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(datasets))
    path = tmp_path / "skills.db"
    ids = make_db(path, 2)
    flip_bit_in_file(path, float(synthetic_skill(1, T=20).demonstration.rewards[5]))
    with pytest.raises(SkillDBError, match=f"skill {ids[1]} .* demo/rewards does not match"):
        run(["show", "--db", str(path), "--id", str(ids[1])])
    with pytest.raises(SkillDBError, match="demo/rewards does not match"):
        run(["export", "--db", str(path), "--dataset-id", "ias/rotten-v0"])
    assert not (datasets / "ias" / "rotten-v0").exists()


# ---------------------------------------------------------------------------- migration
def make_version_1(path: Path) -> list[int]:
    """A database as schema version 1 wrote it: no checksum columns."""
    ids = make_db(path, 3)
    with sqlite3.connect(path) as conn:
        conn.execute("ALTER TABLE skills DROP COLUMN person_params")
        conn.execute("ALTER TABLE arrays DROP COLUMN checksum")
        conn.execute("ALTER TABLE skills DROP COLUMN initial_observation_checksum")
        conn.execute("PRAGMA user_version = 1")
    conn.close()
    return ids


def test_version_1_is_listed_read_only_but_its_arrays_need_a_migration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "v1.db"
    ids = make_version_1(path)
    before = path.read_bytes()
    assert run(["list", "--db", str(path), "--json"]) == 0
    assert [s["id"] for s in json.loads(capsys.readouterr().out)] == ids
    remedy = rf"schema version 1.*`ias-gym skills migrate --db {path}`"
    with pytest.raises(SkillDBError, match=remedy):
        run(["show", "--db", str(path), "--id", str(ids[0])])
    assert run(["check", "--db", str(path)]) == 2
    assert "skills migrate" in capsys.readouterr().out
    assert path.read_bytes() == before  # read-only commands changed nothing

    assert run(["migrate", "--db", str(path)]) == 0
    assert "from schema version 1 to 3 (3 skills;" in capsys.readouterr().out
    with SkillDB(path, readonly=True) as db:
        assert db.schema_version == SCHEMA_VERSION == 3
        for skill_id in ids:
            db.check_skill(skill_id)
    with sqlite3.connect(path) as conn:
        missing = conn.execute("SELECT count(*) FROM arrays WHERE checksum IS NULL").fetchone()
        arrays = conn.execute("SELECT count(*) FROM arrays").fetchone()
    conn.close()
    assert missing == (0,) and arrays == (3 * (len(DEMO_ARRAYS) + len(MODEL_ARRAYS) + 5),)
    assert run(["migrate", "--db", str(path)]) == 0
    assert "nothing to do" in capsys.readouterr().out


def test_opening_version_1_for_writing_migrates_and_then_detects_rot(tmp_path: Path) -> None:
    path = tmp_path / "v1.db"
    ids = make_version_1(path)
    with SkillDB(path) as db:
        assert db.schema_version == SCHEMA_VERSION
        new = db.add(synthetic_skill(7, T=20))
        assert_identical(
            db.get(ids[2]).model.f_int, synthetic_skill(2, T=20).model.f_int
        )  # the migrated skills load, bit-identical
    flip_bit_in_file(path, float(synthetic_skill(0, T=20).model.pen_omega[2, 1]))
    with SkillDB(path, readonly=True) as db:
        with pytest.raises(SkillDBError, match="model/pen_omega does not match"):
            db.get(ids[0])
        db.check_skill(new)


# ---------------------------------------------------------------------------- delete
def test_delete_command_removes_a_skill_and_lists_ids_on_a_miss(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "skills.db"
    ids = make_db(path, 3)
    assert run(["delete", "--db", str(path), "--id", str(ids[1])]) == 0
    assert f"deleted skill {ids[1]} (skill 1) from {path}; 2 skills left" in (
        capsys.readouterr().out
    )
    with sqlite3.connect(path) as conn:  # its arrays went with it
        assert conn.execute(
            "SELECT count(*) FROM arrays WHERE skill_id = ?", (ids[1],)
        ).fetchone() == (0,)
    conn.close()
    with pytest.raises(
        SkillNotFoundError, match=f"no skill with id 9 in {path}; its ids are 1, 3$"
    ):
        run(["delete", "--db", str(path), "--id", "9"])
    with SkillDB(path) as db:
        assert db.ids() == [ids[0], ids[2]]


def test_unknown_id_in_a_large_database_gives_the_range(tmp_path: Path) -> None:
    path = tmp_path / "skills.db"
    with SkillDB(path) as db:
        skill = synthetic_skill(0, T=2)
        for _ in range(25):
            db.add(skill)
        with pytest.raises(SkillNotFoundError, match="it holds 25 skills with ids 1-25"):
            db.delete(99)


def test_delete_removes_incomplete_and_corrupt_skills(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Before, an incomplete skill could only be removed from Python."""
    path = tmp_path / "skills.db"
    ids = make_db(path, 3)
    with sqlite3.connect(path) as conn:
        conn.execute("DELETE FROM arrays WHERE skill_id = ? AND part = 'model'", (ids[0],))
        conn.execute("UPDATE skills SET env_kwargs = '{broken' WHERE id = ?", (ids[0],))
    conn.close()
    flip_bit_in_file(path, float(synthetic_skill(1, T=20).demonstration.observations[1, 1]))
    assert run(["check", "--db", str(path)]) == 2
    capsys.readouterr()
    for skill_id in ids[:2]:
        assert run(["delete", "--db", str(path), "--id", str(skill_id)]) == 0
    assert run(["check", "--db", str(path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"checked {path}: all OK"
