# Over 450 lines: the database's behaviour as one unit (schema, writes, reads, crashes, migration).
"""The skill database: round trip, queries, migration, corruption, bad input, SIGKILL safety."""

from __future__ import annotations

import inspect
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ias_gym.skills.db import (
    APPLICATION_ID,
    DEMO_ARRAYS,
    MIGRATIONS,
    MODEL_ARRAYS,
    SCHEMA_VERSION,
    Demonstration,
    Skill,
    SkillDB,
    SkillDBError,
    SkillModel,
    SkillNotFoundError,
)


def synthetic_skill(
    k: int = 0,
    T: int = 6,
    obs_dim: int = 5,
    task: str = "IAS-PenRotate-v0",
    is_success: bool = True,
    obs0: Any = None,
) -> Skill:
    """A deterministic skill (from ``k``) with the dtypes a recording produces, NaN rows too.

    Its source is also run by the SIGKILL test's writer process (with the imports it needs).
    """
    rng = np.random.default_rng(k)
    S = T + 1
    observations = rng.normal(size=(S, obs_dim))
    if obs0 is not None:
        observations[0] = obs0
    terminations = np.zeros(T, dtype=bool)
    truncations = np.zeros(T, dtype=bool)
    truncations[-1] = True
    demo = Demonstration(
        observations=observations,
        actions=rng.uniform(-1, 1, size=(T, 12)).astype(np.float32),
        rewards=rng.normal(size=T),
        terminations=terminations,
        truncations=truncations,
        infos={
            "is_success": np.arange(S) == T,
            "max_contact_gap": rng.uniform(size=(S, 4)),
            "phase": np.arange(S, dtype=np.int64) % 5,
            "count": np.arange(S, dtype=np.uint8),
            "small": rng.normal(size=S).astype(np.float32),
        },
    )
    c_h = rng.normal(size=(S, 12))
    f_int = rng.normal(size=(S, 6))
    c_h[1] = np.nan  # rank W < 6 at sample 1
    f_int[1] = np.nan
    model = SkillModel(
        time=np.linspace(0.0, 0.01 * T, S),
        touching=rng.uniform(size=(S, 4)) > 0.2,
        sliding=rng.uniform(size=(S, 4)) > 0.8,
        pen_position=rng.normal(size=(S, 3)) * 1e-3,
        pen_rpy=rng.normal(size=(S, 3)) * 0.1,
        pen_velocity=rng.normal(size=(S, 3)),
        pen_omega=rng.normal(size=(S, 3)),
        c=rng.normal(size=(S, 12)),
        c_h=c_h,
        f_ext=rng.normal(size=(S, 6)),
        f_int=f_int,
    )
    return Skill(
        name=f"skill {k}",
        task=task,
        source="expert",
        demonstration=demo,
        model=model,
        is_success=is_success,
        seed=k,
        person_id=None if k % 2 else f"person-{k}",
        env_kwargs={"duration": 0.01 * T},
    )


def assert_identical(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    assert a.tobytes() == b.tobytes()  # bit-identical, NaN payloads included


def count_rows(path: Path) -> tuple[int, int]:
    with sqlite3.connect(path) as conn:
        skills = conn.execute("SELECT count(*) FROM skills").fetchone()[0]
        arrays = conn.execute("SELECT count(*) FROM arrays").fetchone()[0]
    return skills, arrays


def test_round_trip_is_bit_identical_and_keeps_provenance(tmp_path: Path) -> None:
    skill = synthetic_skill(k=4)
    with SkillDB(tmp_path / "skills.db") as db:
        skill_id = db.add(skill)
        loaded = db.get(skill_id)
        assert db.schema_version == SCHEMA_VERSION
    for name in DEMO_ARRAYS:
        assert_identical(getattr(loaded.demonstration, name), getattr(skill.demonstration, name))
    assert sorted(loaded.demonstration.infos) == sorted(skill.demonstration.infos)
    for key, value in skill.demonstration.infos.items():
        assert_identical(loaded.demonstration.infos[key], value)
    for name in MODEL_ARRAYS:
        assert_identical(getattr(loaded.model, name), getattr(skill.model, name))
    assert loaded.demonstration.observations.flags.writeable  # a copy, not a view of bytes
    assert (loaded.id, loaded.name, loaded.task, loaded.source) == (
        skill_id,
        "skill 4",
        "IAS-PenRotate-v0",
        "expert",
    )
    assert (loaded.seed, loaded.person_id, loaded.is_success) == (4, "person-4", True)
    assert loaded.env_kwargs == {"duration": 0.06}
    assert loaded.package_version == __import__("ias_gym").__version__
    assert loaded.created is not None and loaded.created.endswith("+00:00")
    assert loaded.length == 6
    np.testing.assert_array_equal(loaded.model.c_p, skill.model.c - skill.model.c_h)


def test_list_filters_by_task_and_success(tmp_path: Path) -> None:
    with SkillDB(tmp_path / "skills.db") as db:
        a = db.add(synthetic_skill(1, task="IAS-PenRotate-v0"))
        b = db.add(synthetic_skill(2, task="IAS-PenSlide-v0", is_success=False))
        c = db.add(synthetic_skill(3, task="IAS-PenRotate-v0", is_success=False))
        assert [s.id for s in db.list_skills()] == [a, b, c]
        assert [s.id for s in db.list_skills(task="IAS-PenRotate-v0")] == [a, c]
        assert [s.id for s in db.list_skills(success=True)] == [a]
        assert [s.id for s in db.list_skills("IAS-PenRotate-v0", success=False)] == [c]
        assert db.list_skills(task="nope") == []
        assert db.tasks() == ["IAS-PenRotate-v0", "IAS-PenSlide-v0"]
        assert len(db) == 3
        summary = db.summary(b)
        assert summary.length == 6 and summary.duration == pytest.approx(0.06)
        demo = synthetic_skill(2).demonstration
        assert summary.episode_return == pytest.approx(float(demo.rewards.sum()))
        assert set(summary.to_dict()) >= {"id", "return", "is_success", "created"}

        db.delete(a)
        assert [s.id for s in db.list_skills()] == [b, c]
        unknown = f"no skill with id {a} in .*ids are {b}, {c}$"
        with pytest.raises(SkillNotFoundError, match=unknown):
            db.get(a)
    # The deleted skill's arrays went with it (ON DELETE CASCADE).
    assert count_rows(tmp_path / "skills.db") == (2, 2 * (len(DEMO_ARRAYS) + len(MODEL_ARRAYS) + 5))


def test_nearest_initial_state(tmp_path: Path) -> None:
    starts = [np.zeros(5), np.full(5, 1.0), np.full(5, 3.0)]
    with SkillDB(tmp_path / "skills.db") as db:
        ids = [db.add(synthetic_skill(i, obs0=s)) for i, s in enumerate(starts)]
        db.add(synthetic_skill(9, obs_dim=7, obs0=np.full(7, 1.0)))  # other size: skipped
        db.add(synthetic_skill(8, task="other-v0", obs0=np.full(5, 1.1)))
        query = np.full(5, 1.2)
        (best, distance), *_ = db.nearest_initial_state(query, task="IAS-PenRotate-v0")
        assert best.id == ids[1]
        assert distance == pytest.approx(np.sqrt(5) * 0.2)
        found = db.nearest_initial_state(query, task="IAS-PenRotate-v0", k=5)
        assert [s.id for s, _ in found] == [ids[1], ids[0], ids[2]]
        assert [d for _, d in found] == sorted(d for _, d in found)
        assert db.nearest_initial_state(query)[0][0].task == "other-v0"  # 0.1 away
        assert db.nearest_initial_state(np.zeros(3)) == []
        with pytest.raises(ValueError, match="NaN"):
            db.nearest_initial_state(np.full(5, np.nan))


def _create_version_0_file(path: Path) -> None:
    """A database as an ias-gym before versioning left it: a valid, empty SQLite file."""
    conn = sqlite3.connect(path)
    conn.execute("PRAGMA user_version = 0")
    conn.execute("CREATE TABLE scratch (x)")  # force a real header and pages to be written
    conn.execute("DROP TABLE scratch")
    conn.commit()
    conn.close()
    assert path.stat().st_size > 0


def test_migration_from_version_0(tmp_path: Path) -> None:
    path = tmp_path / "v0.db"
    _create_version_0_file(path)
    with SkillDB(path) as db:
        assert db.schema_version == SCHEMA_VERSION
        skill_id = db.add(synthetic_skill(1))
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA application_id").fetchone()[0] == APPLICATION_ID
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    with SkillDB(path) as db:  # opening a current file migrates nothing
        assert db.get(skill_id).name == "skill 1"


def test_a_failing_migration_leaves_the_file_at_its_old_version(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "v0.db"
    _create_version_0_file(path)

    def broken(conn: sqlite3.Connection) -> None:
        MIGRATIONS_ORIGINAL(conn)
        raise RuntimeError("disk on fire")

    MIGRATIONS_ORIGINAL = MIGRATIONS[0]
    monkeypatch.setitem(MIGRATIONS, 0, broken)
    with pytest.raises(RuntimeError, match="disk on fire"):
        SkillDB(path)
    with sqlite3.connect(path) as conn:
        assert conn.execute("PRAGMA user_version").fetchone()[0] == 0
        assert conn.execute("SELECT count(*) FROM sqlite_master").fetchone()[0] == 0
    monkeypatch.setitem(MIGRATIONS, 0, MIGRATIONS_ORIGINAL)
    with SkillDB(path) as db:
        assert db.schema_version == SCHEMA_VERSION


def test_processes_opening_a_new_file_at_once_all_see_one_schema(tmp_path: Path) -> None:
    from concurrent.futures import ThreadPoolExecutor

    path = tmp_path / "shared.db"

    def open_and_add(k: int) -> int:
        with SkillDB(path) as db:
            return db.add(synthetic_skill(k))

    with ThreadPoolExecutor(8) as pool:
        ids = sorted(pool.map(open_and_add, range(8)))
    assert ids == list(range(1, 9))
    with SkillDB(path) as db:
        assert db.schema_version == SCHEMA_VERSION and len(db) == 8
        db.integrity_check()


def test_newer_and_foreign_databases_are_refused(tmp_path: Path) -> None:
    newer = tmp_path / "newer.db"
    with SkillDB(newer):
        pass
    with sqlite3.connect(newer) as conn:
        conn.execute("PRAGMA user_version = 7")
    with pytest.raises(SkillDBError, match=r"newer.db.*version 7.*upgrade ias-gym"):
        SkillDB(newer)

    foreign = tmp_path / "foreign.db"
    with sqlite3.connect(foreign) as conn:
        conn.execute("CREATE TABLE customers (name)")
    with pytest.raises(SkillDBError, match=r"foreign.db.*not a skill database.*customers"):
        SkillDB(foreign)
    with sqlite3.connect(foreign) as conn:  # and it was not touched
        assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "delete"


def test_random_bytes_are_not_a_skill_database(tmp_path: Path) -> None:
    path = tmp_path / "noise.db"
    path.write_bytes(b"not sqlite" + np.random.default_rng(0).bytes(8192))
    with pytest.raises(SkillDBError) as err:
        SkillDB(path)
    message = str(err.value)
    assert str(path) in message
    assert "not a skill database or is corrupt" in message
    assert "restore it from a backup or delete it" in message


@pytest.mark.parametrize("keep", [0.5, 0.9, 0.01])
def test_a_truncated_database_is_reported(tmp_path: Path, keep: float) -> None:
    path = tmp_path / "skills.db"
    with SkillDB(path) as db:
        for i in range(20):
            db.add(synthetic_skill(i, T=200))
    assert not Path(f"{path}-wal").exists()  # checkpointed on close: the file is everything
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(SkillDBError) as err:
        with SkillDB(path) as db:
            for summary in db.list_skills():
                db.get(summary.id)
    assert str(path) in str(err.value)
    assert "restore it from a backup or delete it" in str(err.value)


def _replace(skill: Skill, **changes: Any) -> Skill:
    import dataclasses

    demo_fields = {k: v for k, v in changes.items() if k in Demonstration.__dataclass_fields__}
    model_fields = {k[6:]: v for k, v in changes.items() if k.startswith("model_")}
    skill_fields = {
        k: v for k, v in changes.items() if k not in demo_fields and not k.startswith("model_")
    }
    return dataclasses.replace(
        skill,
        demonstration=dataclasses.replace(skill.demonstration, **demo_fields),
        model=dataclasses.replace(skill.model, **model_fields),
        **skill_fields,
    )


_GOOD = synthetic_skill(0)
_D, _M = _GOOD.demonstration, _GOOD.model
BAD_INPUTS: dict[str, tuple[dict[str, Any], str]] = {
    "empty episode": (
        {
            "observations": _D.observations[:1],
            "actions": _D.actions[:0],
            "rewards": _D.rewards[:0],
            "terminations": _D.terminations[:0],
            "truncations": _D.truncations[:0],
            "infos": {},
        },
        "empty episode",
    ),
    "observations without the final one": (
        {"observations": _D.observations[:-1]},
        r"observations must have T \+ 1 = 7 rows",
    ),
    "short rewards": ({"rewards": _D.rewards[:-1]}, r"rewards must have shape \(6,\)"),
    "NaN observation": (
        {"observations": np.where(np.arange(7)[:, None] == 3, np.nan, _D.observations)},
        r"observations contain NaN or inf \(first at index \[3, 0\]\)",
    ),
    "inf action": ({"actions": _D.actions * np.inf}, "actions contain NaN or inf"),
    "int terminations": (
        {"terminations": _D.terminations.astype(int)},
        "terminations must be a bool array",
    ),
    "early termination": (
        {"terminations": np.array([False, True, False, False, False, False])},
        "step 1 of 6 is terminal",
    ),
    "object info": (
        {"infos": {"note": np.array(["a"] * 7, dtype=object)}},
        r"infos\['note'\] has dtype object",
    ),
    "short info": ({"infos": {"x": np.zeros(6)}}, r"infos\['x'\] must have T \+ 1 = 7 rows"),
    "list instead of array": ({"rewards": [0.0] * 6}, "must be a numpy array"),
    "model one sample short": (
        {"model_time": _M.time[:-1]},
        r"model.time must have shape \(7,\)",
    ),
    "model f_int wrong width": (
        {"model_f_int": _M.f_int[:, :5]},
        r"model.f_int must have shape \(7, 6\)",
    ),
    "NaN contact force": ({"model_c": _M.c * np.nan}, "model.c contains NaN"),
    "time going back": ({"model_time": _M.time[::-1].copy()}, "increase strictly"),
    "empty name": ({"name": " "}, "skill name must be a non-empty string"),
    "env kwargs not JSON": ({"env_kwargs": {"f": object()}}, "JSON-serialisable"),
}


@pytest.mark.parametrize("case", list(BAD_INPUTS))
def test_bad_input_is_refused_and_stores_nothing(tmp_path: Path, case: str) -> None:
    changes, message = BAD_INPUTS[case]
    path = tmp_path / "skills.db"
    with SkillDB(path) as db:
        with pytest.raises(ValueError, match=message):
            db.add(_replace(_GOOD, **changes))
        assert len(db) == 0
    assert count_rows(path) == (0, 0)


def test_a_write_failing_midway_is_rolled_back(tmp_path: Path) -> None:
    path = tmp_path / "skills.db"
    with SkillDB(path) as db:
        db.add(synthetic_skill(1))
    with sqlite3.connect(path) as conn:  # the database refuses the 'c_h' array
        conn.execute(
            "CREATE TRIGGER refuse BEFORE INSERT ON arrays WHEN NEW.name = 'c_h' "
            "BEGIN SELECT RAISE(ABORT, 'refused by test'); END"
        )
    with SkillDB(path) as db:
        with pytest.raises(SkillDBError, match="refused by test"):
            db.add(synthetic_skill(2))
        assert [s.name for s in db.list_skills()] == ["skill 1"]
    assert count_rows(path) == (1, len(DEMO_ARRAYS) + len(MODEL_ARRAYS) + 5)


def test_closed_database_and_directory_path(tmp_path: Path) -> None:
    db = SkillDB(tmp_path / "skills.db")
    db.close()
    db.close()
    with pytest.raises(SkillDBError, match="closed"):
        db.list_skills()
    with pytest.raises(SkillDBError, match="is a directory"):
        SkillDB(tmp_path)


# ---------------------------------------------------------------------------- SIGKILL
# The writer imports ias_gym once (0.9 s), then forks a fresh writer process per line on
# stdin; each writer opens the DB and adds skills until the test SIGKILLs it, and the parent
# reports how it ended.
_WRITER = """
from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np

from ias_gym.skills.db import Demonstration, Skill, SkillDB, SkillModel

{source}

skill = synthetic_skill(k=0, T=100, obs_dim=55)
for _ in sys.stdin:
    pid = os.fork()
    if pid == 0:
        with SkillDB(sys.argv[1]) as db:
            print("ready", os.getpid(), flush=True)
            while True:
                db.add(skill)
    _, status = os.waitpid(pid, 0)
    print("signal", os.WTERMSIG(status) if os.WIFSIGNALED(status) else -1, flush=True)
"""

KILLS = 15


def test_sigkill_while_writing_never_leaves_a_broken_skill(tmp_path: Path) -> None:
    path = tmp_path / "skills.db"
    script = tmp_path / "writer.py"
    script.write_text(_WRITER.format(source=textwrap.dedent(inspect.getsource(synthetic_skill))))
    expected = synthetic_skill(k=0, T=100, obs_dim=55)
    rng = np.random.default_rng(1234)
    counts: list[int] = []
    checked: set[int] = set()

    def check_skill(db: SkillDB, summary: Any) -> None:
        skill = db.get(summary.id)
        demo = skill.demonstration
        assert demo.length == summary.length == 100
        assert len(demo.observations) == len(skill.model.time) == 101
        for name in ("observations", "actions"):
            assert_identical(getattr(demo, name), getattr(expected.demonstration, name))
        assert_identical(skill.model.f_int, expected.model.f_int)

    # The writer imports the ias_gym under test (not another installed copy).
    package_root = str(Path(__import__("ias_gym").__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": package_root}
    with subprocess.Popen(
        [sys.executable, str(script), str(path)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    ) as zygote:
        assert zygote.stdin is not None and zygote.stdout is not None
        for _ in range(KILLS):
            zygote.stdin.write("go\n")
            zygote.stdin.flush()
            line = zygote.stdout.readline().split()
            assert line[:1] == ["ready"], zygote.stderr.read() if zygote.stderr else ""
            time.sleep(float(rng.uniform(0.0, 0.25)))  # somewhere inside its stream of writes
            os.kill(int(line[1]), signal.SIGKILL)
            assert zygote.stdout.readline().split() == ["signal", str(int(signal.SIGKILL))]

            with SkillDB(path) as db:
                db.integrity_check()
                assert db.conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
                summaries = db.list_skills()
                # each skill is read back whole once, after the kill that followed its commit
                # (the PRAGMA checks every page of the file after every kill)
                for summary in summaries:
                    if summary.id not in checked:
                        check_skill(db, summary)
                        checked.add(summary.id)
            counts.append(len(summaries))
        zygote.stdin.close()
    assert counts[-1] > KILLS  # the writers did write, and committed skills survived
    assert counts == sorted(counts)
