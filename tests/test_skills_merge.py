"""``ias-gym skills merge``: shard databases joined into one new file, atomically, every array
verified on the way, nothing overwritten without ``--overwrite``."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from ias_gym.cli import main
from ias_gym.errors import InputError
from ias_gym.skills.db import DEMO_ARRAYS, MODEL_ARRAYS, Skill, SkillDB
from ias_gym.skills.db_merge import merge_databases
from tests.test_skills_db import assert_identical, synthetic_skill


def _shard(path: Path, ks: list[int]) -> Path:
    with SkillDB(path) as db:
        for k in ks:
            db.add(synthetic_skill(k, T=4 + k))
    return path


def _stored(path: Path) -> list[Skill]:
    with SkillDB(path, readonly=True) as db:
        return [db.get(i) for i in db.ids()]


def _assert_same_skill(a: Skill, b: Skill) -> None:
    for name in ("name", "task", "source", "is_success", "seed", "person_id", "created"):
        assert getattr(a, name) == getattr(b, name), name
    assert a.package_version == b.package_version and dict(a.env_kwargs) == dict(b.env_kwargs)
    for name in DEMO_ARRAYS:
        assert_identical(getattr(a.demonstration, name), getattr(b.demonstration, name))
    assert a.demonstration.infos.keys() == b.demonstration.infos.keys()
    for key, value in a.demonstration.infos.items():
        assert_identical(value, b.demonstration.infos[key])
    for name in MODEL_ARRAYS:
        assert_identical(getattr(a.model, name), getattr(b.model, name))


def test_merge_keeps_every_skill_in_order_bit_for_bit(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _shard(tmp_path / "a.db", [0, 1])
    b = _shard(tmp_path / "b.db", [2, 3, 4])
    out = tmp_path / "all.db"
    assert main(["skills", "merge", "--out", str(out), str(b), str(a)]) == 0
    assert f"wrote 5 skills to {out} (3 from {b}, 2 from {a})" in capsys.readouterr().out
    merged, sources = _stored(out), _stored(b) + _stored(a)
    assert [s.seed for s in merged] == [2, 3, 4, 0, 1]  # the inputs' order
    assert [s.id for s in merged] == [1, 2, 3, 4, 5]  # new ids
    for got, want in zip(merged, sources, strict=True):
        _assert_same_skill(got, want)
    assert not list(tmp_path.glob(".*"))  # no temporary file (or its -wal, -shm) left
    assert sorted(p.name for p in tmp_path.glob("*.db")) == ["a.db", "all.db", "b.db"]
    wal = tmp_path / "all.db-wal"  # the merge's writer closed: no log to apply
    assert not wal.exists() or wal.stat().st_size == 0


def test_merge_refuses_to_overwrite_without_the_flag(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _shard(tmp_path / "a.db", [0])
    b = _shard(tmp_path / "b.db", [1])
    out = _shard(tmp_path / "out.db", [7, 8, 9])
    assert main(["skills", "merge", "--out", str(out), str(a), str(b)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ias-gym: error: ") and "already exists" in err and "--overwrite" in err
    assert [s.seed for s in _stored(out)] == [7, 8, 9]  # untouched
    assert main(["skills", "merge", "--out", str(out), str(a), str(b), "--overwrite"]) == 0
    assert [s.seed for s in _stored(out)] == [0, 1]
    # the output may be one of the inputs: they are read completely before it is replaced
    assert merge_databases(out, [out, _shard(tmp_path / "c.db", [5])], overwrite=True) == [2, 1]
    assert [s.seed for s in _stored(out)] == [0, 1, 5]
    with SkillDB(out) as writer:  # open elsewhere, its log not yet checkpointed
        writer.add(synthetic_skill(6))
        with pytest.raises(InputError, match="write-ahead log"):
            merge_databases(out, [a], overwrite=True)
    assert [s.seed for s in _stored(out)] == [0, 1, 5, 6]


def test_a_corrupt_shard_stops_the_merge_and_writes_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _shard(tmp_path / "a.db", [0])
    b = _shard(tmp_path / "b.db", [1, 2])
    with sqlite3.connect(b) as conn:  # one flipped bit inside skill 2's rewards
        (blob,) = conn.execute(
            "SELECT data FROM arrays WHERE skill_id = 2 AND name = 'rewards'"
        ).fetchone()
        data = bytearray(blob)
        data[3] ^= 0x10
        conn.execute(
            "UPDATE arrays SET data = ? WHERE skill_id = 2 AND name = 'rewards'", (bytes(data),)
        )
    out = tmp_path / "all.db"
    assert main(["skills", "merge", "--out", str(out), str(a), str(b)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "skill 2" in err[0] and "rewards" in err[0], err
    assert not out.exists()
    assert not list(tmp_path.glob(".*")) and not list(tmp_path.glob("all*"))


def test_bad_inputs_are_refused_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    a = _shard(tmp_path / "a.db", [0])
    out = tmp_path / "all.db"
    cases = [
        ([str(a), str(tmp_path / "." / "a.db")], "given twice"),
        ([str(a), str(tmp_path / "missing.db")], "no skill database at"),
    ]
    for dbs, message in cases:
        assert main(["skills", "merge", "--out", str(out), *dbs]) == 2
        assert message in capsys.readouterr().err
        assert not out.exists()
    with pytest.raises(SystemExit):  # argparse: at least one input
        main(["skills", "merge", "--out", str(out)])
    assert not out.exists()
