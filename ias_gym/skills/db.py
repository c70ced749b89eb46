"""The skill database: skills (paper sec. 3, Proposition 1) and their demonstrations in SQLite.

A *skill* is what the paper's skill acquisition produces: the time behaviour of the grip
transform G(t) (Proposition 1) together with the object motion it realises and the
demonstration it was analysed from. :class:`SkillDB` stores skills in one embedded SQLite
file (stdlib :mod:`sqlite3`, WAL journal), one transaction per write, so a process killed at
any moment leaves every stored skill complete or absent.

What a skill holds:

- :class:`SkillModel`, sampled at every observation (``T + 1`` samples for ``T`` steps):
  contact schedule (which fingertips touch, which are scheduled to slide), object trajectory
  (pen pose ``r, phi`` of eq. 25 and twist ``v, omega`` of eq. 15), the wrench intensities
  ``c`` (eq. 3), their homogeneous part ``c_h = N N^T c`` (eqs. 4, 7), the external wrench
  ``f_ext = W c`` and the internal forces ``f_int = N^T c`` (eqs. 9, 10). W itself is not
  kept: ``(f_ext, f_int) = inv(G^T) c`` is the part of G(t) a skill is replayed from.
- :class:`Demonstration`: observations (``T + 1``, including the reset and the final
  observation, as Minari stores them), actions, rewards, terminations, truncations (``T``
  each) and the numeric ``info`` entries (``T + 1`` rows each: the reset's info, then every
  step's).
- provenance: source (``"expert"``, ``"policy:<path>"``, ``"glove"``, ...), optional person
  id, creation time (UTC, ISO 8601), package version, seed and the env's keyword arguments.

Arrays are stored as raw bytes with their dtype (``numpy.dtype.str``, byte order included)
and shape in their own columns; loading uses ``numpy.frombuffer``. Nothing is pickled and
only numeric and bool dtypes are accepted, so a database file cannot run code.

Every stored array carries a checksum, ``sha256:`` + SHA-256 of its dtype, shape and raw
bytes (:func:`array_checksum`), and so does each skill's copy of its first observation.
Loading verifies it: a flipped bit inside an array (which ``PRAGMA integrity_check`` does
not see: the page is intact, only the numbers changed) raises :class:`SkillDBError` naming
the skill id and the array, instead of returning, say, 4.8e303 in an observation.
:meth:`SkillDB.check_skill` (``ias-gym skills check``) verifies a skill without using it.

Databases of schema version 1 (before checksums) are **migrated when opened for writing**
(``SkillDB(path)``, ``ias-gym skills record``, ``delete`` or ``migrate``): the migration
computes the checksums of the bytes as they are at that moment, in one transaction, so it
certifies what is stored then and detects every change after it. A read-only open
(``readonly=True``: ``ias-gym skills list``, ``show``, ``export``, ``check``) never writes,
so on a version-1 file it lists skills but refuses to load their arrays, saying to run
``ias-gym skills migrate --db PATH`` once.

Opening: ``SkillDB(path)`` opens for writing and creates a missing file (and its folder;
an empty 0-byte file becomes a new database too);
``SkillDB(path, create=False)`` opens for writing only an existing database;
``SkillDB(path, readonly=True)`` opens SQLite read-only (a ``file:...?mode=ro`` URI) and
never creates or changes the database or a folder: a missing path, a folder, an empty
(0-byte) file or an SQLite file without the skill schema is refused naming the path
(SQLite itself keeps its ``-wal``/``-shm`` index files next to a WAL database it reads).

Validation (a bad skill raises ``ValueError`` saying what is wrong, and nothing is stored):
an episode needs at least one step; lengths must agree; observations, actions and rewards
must be finite (a NaN there is a broken rollout, and it would poison nearest-state queries
and learning); ``c_h`` and ``f_int`` may be NaN, which marks samples where rank W < 6 and G
is undefined; ``info`` arrays may hold any numbers (they are diagnostics).

Opening checks the file: one that is not SQLite, is truncated or damaged in its header
raises :class:`SkillDBError` naming the path and the remedy (restore a backup or delete
it); damage deeper inside surfaces as the same error when it is read, and
:meth:`SkillDB.integrity_check` runs SQLite's full check.

Schema (``PRAGMA user_version`` is the schema version, ``PRAGMA application_id`` marks the
file as a skill database; migrations run on open for writing, each in one transaction;
version 0 is a new, empty file, and an SQLite file of another application is refused, not
changed)::

    skills(id INTEGER PRIMARY KEY AUTOINCREMENT, name, task, source, person_id, created,
           package_version, seed, env_kwargs (JSON), is_success, episode_return, length,
           duration [s], observation_dim, initial_observation (float64 bytes),
           initial_observation_checksum (version 2))
    arrays(id INTEGER PRIMARY KEY, skill_id -> skills(id) ON DELETE CASCADE,
           part ('demo' | 'info' | 'model'), name, dtype, shape (JSON), data BLOB,
           checksum (version 2), UNIQUE(skill_id, part, name))
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import sqlite3
import time
import urllib.parse
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ias_gym import __version__
from ias_gym.errors import IasGymError
from ias_gym.skills.skill import (
    DEMO_ARRAYS,
    MODEL_ARRAYS,
    SAFE_KINDS,
    Demonstration,
    Skill,
    SkillModel,
    check_storable_array,
)

#: The schema version this code writes (``PRAGMA user_version``); 2 added the checksums.
SCHEMA_VERSION = 2
#: The first schema version with array checksums.
CHECKSUM_VERSION = 2
#: ``PRAGMA application_id`` of a skill database: ASCII "IASS".
APPLICATION_ID = 0x49415353
#: Seconds a connection waits for another process's write lock before failing.
DEFAULT_TIMEOUT = 30.0
#: An unknown id's error lists the ids there are up to this many (else their range).
MAX_LISTED_IDS = 20

#: Columns of ``skills`` that make up a :class:`SkillSummary` (in its field order).
_SUMMARY_COLUMNS = (
    "id, name, task, source, person_id, created, package_version, seed, env_kwargs, "
    "is_success, episode_return, length, duration"
)


class SkillDBError(IasGymError):
    """The skill database cannot be used: not a skill database, corrupt, newer, or locked."""


class SkillNotFoundError(SkillDBError):
    """No skill with the requested id."""


def array_checksum(dtype: str, shape: str, data: bytes) -> str:
    """``"sha256:<hex>"`` of a stored array: its dtype string, shape JSON and raw bytes.

    The dtype and shape are hashed too (NUL-separated), so a changed byte order or shape
    is caught like a changed number.
    """
    digest = hashlib.sha256()
    digest.update(dtype.encode())
    digest.update(b"\0")
    digest.update(shape.encode())
    digest.update(b"\0")
    digest.update(data)
    return "sha256:" + digest.hexdigest()


def _initial_observation_checksum(data: bytes) -> str:
    return array_checksum("<f8", json.dumps([len(data) // 8]), data)


@dataclass(frozen=True)
class SkillSummary:
    """A skill's row without its arrays (what :meth:`SkillDB.list_skills` returns).

    Attributes:
        episode_return: undiscounted return of the demonstration.
        length: number of steps.
        duration: time spanned by the skill model [s].
        (the others as in :class:`Skill`)
    """

    id: int
    name: str
    task: str
    source: str
    person_id: str | None
    created: str
    package_version: str
    seed: int | None
    env_kwargs: dict[str, Any]
    is_success: bool
    episode_return: float
    length: int
    duration: float

    @classmethod
    def _from_row(cls, row: tuple[Any, ...], path: Path) -> SkillSummary:
        (id_, name, task, source, person, created, version, seed, kwargs) = row[:9]
        success, ret, length, duration = row[9:13]
        try:
            env_kwargs = json.loads(kwargs)
            if not isinstance(env_kwargs, dict):
                raise TypeError(f"a {type(env_kwargs).__name__}, not an object")
            return cls(
                id=int(id_),
                name=name,
                task=task,
                source=source,
                person_id=person,
                created=created,
                package_version=version,
                seed=seed,
                env_kwargs=env_kwargs,
                is_success=bool(success),
                episode_return=float(ret),
                length=int(length),
                duration=float(duration),
            )
        except (TypeError, ValueError) as exc:  # a damaged row: one error type, its id
            raise SkillDBError(
                f"skill {id_} in {path} is corrupt: its row does not parse ({exc}); restore "
                f"a backup, or delete the skill with `ias-gym skills delete --db {path} "
                f"--id {id_}`"
            ) from None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of every field (``return`` is the key of ``episode_return``)."""
        out = dataclasses.asdict(self)
        out["return"] = out.pop("episode_return")
        return out


# ---------------------------------------------------------------------------- the database
class SkillDB:
    """An embedded SQLite skill database in one file.

    Use it as a context manager (``with SkillDB(path) as db: ...``) or call :meth:`close`.
    Several processes may read and write the same file (WAL journal; a writer waits up to
    ``timeout`` seconds for another one). Every write is one transaction.

    Args:
        path: the database file.
        timeout: seconds to wait for another process's write lock [s].
        readonly: open SQLite read-only (``mode=ro``): nothing is created, migrated or
            written; :meth:`add` and :meth:`delete` raise. The file must exist and be a
            skill database.
        create: (for writing) create a missing file and its missing parent folders; with
            ``False`` the database must exist (as with ``readonly``).

    Raises:
        SkillDBError: the path is missing (read-only or ``create=False``), a folder or an
            empty file (read-only or ``create=False``); the file is not a skill database or
            is corrupt (the message says the path and what to do), was written by a newer
            ias-gym, or cannot be opened.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        timeout: float = DEFAULT_TIMEOUT,
        readonly: bool = False,
        create: bool = True,
    ) -> None:
        self.path = Path(path)
        self.readonly = bool(readonly)
        self._conn: sqlite3.Connection | None = None
        if self.path.is_dir():
            raise SkillDBError(f"{self.path} is a directory; pass the path of a database file")
        if self.readonly or not create:
            self._check_existing_file()
        else:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        with self._errors("open"):
            if self.readonly:
                conn = sqlite3.connect(
                    _readonly_uri(self.path), uri=True, timeout=timeout, isolation_level=None
                )
            else:
                conn = sqlite3.connect(self.path, timeout=timeout, isolation_level=None)
        self._conn = conn
        try:
            with self._errors("open"):
                # Reading the header first: a file that is not SQLite or is truncated fails here.
                version = self._pragma("user_version")
                if version > 0:
                    self._check_application_id()
                if version > SCHEMA_VERSION:
                    raise SkillDBError(
                        f"{self.path} has skill-database schema version {version}, newer than "
                        f"this ias-gym supports ({SCHEMA_VERSION}); upgrade ias-gym to open it"
                    )
                if version == 0:
                    self._check_empty()  # before touching the file (again inside _migrate)
                    if self.readonly or not create:  # only a new file gets the schema
                        raise SkillDBError(
                            f"{self.path} is an SQLite file without the skill schema, not a "
                            "skill database (nothing was changed); pass another path"
                        )
                if not self.readonly:
                    conn.execute("PRAGMA foreign_keys = ON")
                    # FULL: a committed skill survives power loss too, not only a killed process.
                    conn.execute("PRAGMA synchronous = FULL")
                    self._use_wal(timeout)
                    self._migrate()
                self._checksums = self._pragma("user_version") >= CHECKSUM_VERSION
        except BaseException:
            conn.close()
            self._conn = None
            raise

    def _check_existing_file(self) -> None:
        """Refuse a missing or empty file without creating anything (read-only opens)."""
        try:
            size = self.path.stat().st_size
        except FileNotFoundError:
            raise SkillDBError(
                f"no skill database at {self.path} (nothing was created); check the path, "
                "or record skills into it with `ias-gym skills record --db PATH`"
            ) from None
        except OSError as exc:
            raise SkillDBError(f"cannot open skill database {self.path}: {exc.strerror}") from None
        if size == 0:
            raise SkillDBError(
                f"{self.path} is empty (0 bytes), not a skill database; check the path (a "
                "new database is made by `ias-gym skills record --db PATH`)"
            )

    # ------------------------------------------------------------------ plumbing
    @property
    def conn(self) -> sqlite3.Connection:
        """The open connection (raises SkillDBError after :meth:`close`)."""
        if self._conn is None:
            raise SkillDBError(f"skill database {self.path} is closed")
        return self._conn

    def _pragma(self, name: str) -> int:
        return int(self.conn.execute(f"PRAGMA {name}").fetchone()[0])

    def _errors(self, action: str) -> _ErrorTranslation:
        return _ErrorTranslation(self.path, action)

    def _check_application_id(self) -> None:
        """A file with a schema version must carry the skill database's application id."""
        app_id = self._pragma("application_id")
        if app_id != APPLICATION_ID:
            raise SkillDBError(
                f"{self.path} is an SQLite database of another application (application_id "
                f"{app_id:#x}), not a skill database; pass another path"
            )

    def _check_empty(self) -> None:
        """A version-0 file must be empty: tables there belong to another application."""
        tables = [
            r[0]
            for r in self.conn.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table' "
                "AND name NOT LIKE 'sqlite_%' ORDER BY name"
            )
        ]
        # Read after the tables: a concurrent migration that created them has set it too.
        if tables and self._pragma("user_version") == 0:
            raise SkillDBError(
                f"{self.path} is an SQLite database but not a skill database (it has "
                f"tables {tables} and no skill schema version); pass another path"
            )

    def _use_wal(self, timeout: float) -> None:
        """Switch the file to the WAL journal (persistent; a no-op once done).

        The switch needs the file to itself and SQLite does not wait for that with the busy
        timeout, so it is retried while other connections (another process creating the
        same new file) are busy, for up to ``timeout`` seconds.
        """
        if str(self.conn.execute("PRAGMA journal_mode").fetchone()[0]).lower() == "wal":
            return
        deadline = time.monotonic() + timeout
        while True:
            try:
                mode = self.conn.execute("PRAGMA journal_mode = WAL").fetchone()[0]
                break
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) or time.monotonic() > deadline:
                    raise
                time.sleep(0.005)
        if str(mode).lower() != "wal":
            raise SkillDBError(f"{self.path}: cannot switch to the WAL journal (got {mode})")

    def _migrate(self) -> None:
        """Bring the schema to :data:`SCHEMA_VERSION`, one transaction per version step."""
        while True:
            version = self._pragma("user_version")
            if version >= SCHEMA_VERSION:
                return
            with self._transaction():
                # Another process may have migrated between our read and the write lock.
                version = self._pragma("user_version")
                if version >= SCHEMA_VERSION:
                    return
                if version == 0:
                    self._check_empty()
                MIGRATIONS[version](self.conn)
                self.conn.execute(f"PRAGMA user_version = {version + 1}")

    def _transaction(self, mode: str = "IMMEDIATE") -> _Transaction:
        return _Transaction(self.conn, mode)

    @property
    def schema_version(self) -> int:
        """The schema version of the open file."""
        with self._errors("read"):
            return self._pragma("user_version")

    def close(self) -> None:
        """Close the connection (idempotent)."""
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def __enter__(self) -> SkillDB:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __del__(self) -> None:
        conn = getattr(self, "_conn", None)
        if conn is not None:
            conn.close()

    def __repr__(self) -> str:
        state = "open" if self._conn is not None else "closed"
        return f"SkillDB({str(self.path)!r}, {state})"

    # ------------------------------------------------------------------ writes
    def add(self, skill: Skill) -> int:
        """Store a skill and its arrays in one transaction.

        Returns:
            The new skill's id.

        Raises:
            ValueError: the skill is invalid (nothing is stored; the message says why).
            SkillDBError: the database cannot be written (or was opened read-only).
        """
        self._check_writable()
        skill.validate()
        demo, model = skill.demonstration, skill.model
        rows: list[tuple[str, str, NDArray[Any]]] = [
            ("demo", name, getattr(demo, name)) for name in DEMO_ARRAYS
        ]
        rows += [("info", key, value) for key, value in sorted(demo.infos.items())]
        rows += [("model", name, getattr(model, name)) for name in MODEL_ARRAYS]
        encoded = [(part, name, *_encode(value)) for part, name, value in rows]
        first = np.ascontiguousarray(demo.observations[0], dtype="<f8").ravel()
        record = (
            skill.name,
            skill.task,
            skill.source,
            skill.person_id,
            skill.created or datetime.now(timezone.utc).isoformat(timespec="seconds"),
            skill.package_version or __version__,
            None if skill.seed is None else int(skill.seed),
            json.dumps(dict(skill.env_kwargs), sort_keys=True),
            int(bool(skill.is_success)),
            demo.episode_return,
            demo.length,
            model.duration,
            int(first.size),
            first.tobytes(),
            _initial_observation_checksum(first.tobytes()),
        )
        with self._errors("write"), self._transaction():
            cur = self.conn.execute(
                "INSERT INTO skills (name, task, source, person_id, created, package_version, "
                "seed, env_kwargs, is_success, episode_return, length, duration, "
                "observation_dim, initial_observation, initial_observation_checksum) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                record,
            )
            skill_id = cur.lastrowid
            assert skill_id is not None
            self.conn.executemany(
                "INSERT INTO arrays (skill_id, part, name, dtype, shape, data, checksum) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                [(skill_id, *row) for row in encoded],
            )
        return int(skill_id)

    def delete(self, skill_id: int) -> str:
        """Delete a skill and its arrays (one transaction), whatever state its arrays are in
        (incomplete or corrupt skills too).

        Returns:
            The deleted skill's name.

        Raises:
            SkillNotFoundError: no skill has this id (the message lists the ids there are).
            SkillDBError: the database was opened read-only or cannot be written.
        """
        self._check_writable()
        with self._errors("write"), self._transaction():
            row = self.conn.execute(
                "SELECT name FROM skills WHERE id = ?", (int(skill_id),)
            ).fetchone()
            if row is None:
                raise self._not_found(skill_id)
            self.conn.execute("DELETE FROM skills WHERE id = ?", (int(skill_id),))
        return str(row[0])

    # ------------------------------------------------------------------ reads
    def _check_writable(self) -> None:
        if self.readonly:
            raise SkillDBError(f"skill database {self.path} is open read-only; open it with "
                               "SkillDB(path) to write")  # fmt: skip

    def _not_found(self, skill_id: int) -> SkillNotFoundError:
        ids = [int(r[0]) for r in self.conn.execute("SELECT id FROM skills ORDER BY id")]
        if not ids:
            have = "it holds no skills"
        elif len(ids) <= MAX_LISTED_IDS:
            have = f"its ids are {', '.join(map(str, ids))}"
        else:
            have = f"it holds {len(ids)} skills with ids {ids[0]}-{ids[-1]}"
        return SkillNotFoundError(f"no skill with id {skill_id} in {self.path}; {have}")

    def list_skills(
        self, task: str | None = None, success: bool | None = None
    ) -> list[SkillSummary]:
        """The stored skills, by id.

        Args:
            task: only skills of this env id.
            success: only successful (``True``) or failed (``False``) ones; ``None``: all.
        """
        query = f"SELECT {_SUMMARY_COLUMNS} FROM skills"
        where, params = _filters(task, success)
        with self._errors("read"):
            rows = self.conn.execute(f"{query}{where} ORDER BY id", params).fetchall()
        return [SkillSummary._from_row(r, self.path) for r in rows]

    def ids(self) -> list[int]:
        """The stored skills' ids, ascending (reads no other column: works on damaged rows)."""
        with self._errors("read"):
            return [int(r[0]) for r in self.conn.execute("SELECT id FROM skills ORDER BY id")]

    def tasks(self) -> list[str]:
        """The distinct task ids, sorted."""
        with self._errors("read"):
            return [r[0] for r in self.conn.execute("SELECT DISTINCT task FROM skills ORDER BY 1")]

    def __len__(self) -> int:
        with self._errors("read"):
            return int(self.conn.execute("SELECT count(*) FROM skills").fetchone()[0])

    def summary(self, skill_id: int) -> SkillSummary:
        """One skill's row without its arrays.

        Raises:
            SkillNotFoundError: no skill has this id.
        """
        with self._errors("read"):
            row = self.conn.execute(
                f"SELECT {_SUMMARY_COLUMNS} FROM skills WHERE id = ?", (int(skill_id),)
            ).fetchone()
            if row is None:
                raise self._not_found(skill_id)
        return SkillSummary._from_row(row, self.path)

    def get(self, skill_id: int) -> Skill:
        """Load a skill with its demonstration and model (arrays bit-identical, dtypes kept).

        Every array's checksum is verified before it is used.

        Raises:
            SkillNotFoundError: no skill has this id.
            SkillDBError: the stored arrays are incomplete, inconsistent or do not match
                their checksums (the message names the skill and the array), or the file
                predates checksums and was opened read-only (the message says how to
                migrate it).
        """
        checksum = "checksum" if self._checksums else "NULL"
        with self._errors("read"), self._transaction("DEFERRED"):  # one consistent snapshot
            row = self.conn.execute(
                f"SELECT {_SUMMARY_COLUMNS} FROM skills WHERE id = ?", (int(skill_id),)
            ).fetchone()
            if row is None:
                raise self._not_found(skill_id)
            arrays = self.conn.execute(
                f"SELECT part, name, dtype, shape, data, {checksum} FROM arrays WHERE skill_id = ?",
                (int(skill_id),),
            ).fetchall()
        summary = SkillSummary._from_row(row, self.path)
        parts: dict[str, dict[str, NDArray[Any]]] = {"demo": {}, "info": {}, "model": {}}
        for part, name, dtype, shape, data, digest in arrays:
            what = f"{part}/{name}"
            self._verify(skill_id, what, dtype, shape, data, digest)
            parts[part][name] = _decode(self.path, skill_id, what, dtype, shape, data)
        for part, names in (("demo", DEMO_ARRAYS), ("model", MODEL_ARRAYS)):
            missing = sorted(set(names) - set(parts[part]))
            if missing:
                raise SkillDBError(
                    f"skill {skill_id} in {self.path} is incomplete (missing {part} arrays "
                    f"{missing}); {self._delete_hint(skill_id)}"
                )
        skill = Skill(
            name=summary.name,
            task=summary.task,
            source=summary.source,
            demonstration=Demonstration(**parts["demo"], infos=parts["info"]),
            model=SkillModel(**parts["model"]),
            is_success=summary.is_success,
            seed=summary.seed,
            person_id=summary.person_id,
            env_kwargs=summary.env_kwargs,
            id=summary.id,
            created=summary.created,
            package_version=summary.package_version,
        )
        if skill.length != summary.length:
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is inconsistent: {skill.length} actions "
                f"stored, {summary.length} recorded; {self._delete_hint(skill_id)}"
            )
        return skill

    def _delete_hint(self, skill_id: int) -> str:
        return (
            f"restore a backup, or delete the skill with `ias-gym skills delete --db "
            f"{self.path} --id {skill_id}`"
        )

    def _verify(
        self, skill_id: int, what: str, dtype: str, shape: str, data: bytes, digest: str | None
    ) -> None:
        """Raise SkillDBError unless the array's bytes match its stored checksum."""
        if digest is None:
            if not self._checksums:
                raise SkillDBError(
                    f"{self.path} has schema version {self.schema_version}, written before "
                    "arrays had checksums, and was opened read-only; add them once with "
                    f"`ias-gym skills migrate --db {self.path}` (any open for writing does)"
                )
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is corrupt: array {what} has no checksum; "
                f"{self._delete_hint(skill_id)}"
            )
        try:
            actual = array_checksum(dtype, shape, data)
        except (AttributeError, TypeError):  # not text / bytes: a damaged row
            actual = None
        if actual != digest:
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is corrupt: array {what} does not match its "
                f"checksum (its stored bytes changed since it was written); "
                f"{self._delete_hint(skill_id)}"
            )

    def check_skill(self, skill_id: int) -> None:
        """Verify one skill completely without returning it: every array against its
        checksum, complete and consistent (:meth:`get`), its first-observation copy (the
        nearest-state index) against its checksum and the demonstration, and the skill's
        fields (:meth:`Skill.validate`).

        Raises:
            SkillNotFoundError: no skill has this id.
            SkillDBError: the first problem found (naming the skill and the array).
        """
        skill = self.get(skill_id)
        checksum = "initial_observation_checksum" if self._checksums else "NULL"
        with self._errors("read"):
            first, digest = self.conn.execute(
                f"SELECT initial_observation, {checksum} FROM skills WHERE id = ?",
                (int(skill_id),),
            ).fetchone()
        shape = json.dumps([len(first) // 8])
        self._verify(skill_id, "initial_observation", "<f8", shape, first, digest)
        expected = np.ascontiguousarray(skill.demonstration.observations[0], dtype="<f8")
        if first != expected.ravel().tobytes():
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is inconsistent: initial_observation differs "
                f"from the first stored observation; {self._delete_hint(skill_id)}"
            )
        try:
            skill.validate()
        except ValueError as exc:
            raise SkillDBError(
                f"skill {skill_id} in {self.path} is invalid: {exc}; {self._delete_hint(skill_id)}"
            ) from None

    def nearest_initial_state(
        self, observation: Any, task: str | None = None, k: int = 1
    ) -> list[tuple[SkillSummary, float]]:
        """The skills whose demonstration starts closest to ``observation``.

        Distance is Euclidean between ``observation`` and each demonstration's first
        observation (flattened); skills whose observations have another size are skipped.

        Args:
            observation: an observation of the task's env.
            task: only skills of this env id.
            k: how many to return.

        Returns:
            Up to ``k`` pairs ``(summary, distance)``, nearest first; empty if none match.

        Raises:
            ValueError: ``observation`` is not finite, or ``k < 1``.
            SkillDBError: a candidate's stored first observation does not match its
                checksum (naming the skill).
        """
        obs = np.asarray(observation, dtype=np.float64).ravel()
        if not np.all(np.isfinite(obs)):
            raise ValueError("observation contains NaN or inf")
        if k < 1:
            raise ValueError(f"k must be >= 1, got {k}")
        where, params = _filters(task, None)
        where += (" AND " if where else " WHERE ") + "observation_dim = ?"
        checksum = "initial_observation_checksum" if self._checksums else "NULL"
        with self._errors("read"):
            rows = self.conn.execute(
                f"SELECT {_SUMMARY_COLUMNS}, initial_observation, {checksum} FROM skills"
                f"{where} ORDER BY id",
                (*params, obs.size),
            ).fetchall()
        if not rows:
            return []
        shape = json.dumps([obs.size])
        for r in rows:
            self._verify(int(r[0]), "initial_observation", "<f8", shape, r[-2], r[-1])
        starts = np.stack([np.frombuffer(r[-2], dtype="<f8") for r in rows])
        distance = np.linalg.norm(starts - obs, axis=1)
        order = np.argsort(distance, kind="stable")[:k]
        return [
            (SkillSummary._from_row(rows[i][:-2], self.path), float(distance[i])) for i in order
        ]

    def integrity_check(self) -> None:
        """Run SQLite's full ``PRAGMA integrity_check``.

        Raises:
            SkillDBError: the file is damaged (the message has SQLite's findings).
        """
        with self._errors("check"):
            result = [r[0] for r in self.conn.execute("PRAGMA integrity_check")]
        if result != ["ok"]:
            raise SkillDBError(
                f"{self.path} is corrupt ({'; '.join(result[:5])}); restore it from a backup "
                "or delete it"
            )


# ---------------------------------------------------------------------------- migrations
def _migrate_0_to_1(conn: sqlite3.Connection) -> None:
    """Version 0 is an empty (new) file: create the version-1 schema."""
    conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
    conn.execute(
        """CREATE TABLE skills (
            id INTEGER PRIMARY KEY AUTOINCREMENT,
            name TEXT NOT NULL,
            task TEXT NOT NULL,
            source TEXT NOT NULL,
            person_id TEXT,
            created TEXT NOT NULL,
            package_version TEXT NOT NULL,
            seed INTEGER,
            env_kwargs TEXT NOT NULL DEFAULT '{}',
            is_success INTEGER NOT NULL CHECK (is_success IN (0, 1)),
            episode_return REAL NOT NULL,
            length INTEGER NOT NULL CHECK (length >= 1),
            duration REAL NOT NULL,
            observation_dim INTEGER NOT NULL,
            initial_observation BLOB NOT NULL
        )"""
    )
    conn.execute("CREATE INDEX skills_by_task ON skills (task, is_success)")
    conn.execute(
        """CREATE TABLE arrays (
            id INTEGER PRIMARY KEY,
            skill_id INTEGER NOT NULL REFERENCES skills (id) ON DELETE CASCADE,
            part TEXT NOT NULL CHECK (part IN ('demo', 'info', 'model')),
            name TEXT NOT NULL,
            dtype TEXT NOT NULL,
            shape TEXT NOT NULL,
            data BLOB NOT NULL,
            UNIQUE (skill_id, part, name)
        )"""
    )


def _migrate_1_to_2(conn: sqlite3.Connection) -> None:
    """Version 2 adds a checksum to every array and to each skill's first observation.

    The rows there are get theirs from their bytes as they are now (one row at a time, so
    a large file is not held in memory).
    """
    conn.execute("ALTER TABLE arrays ADD COLUMN checksum TEXT")
    conn.execute("ALTER TABLE skills ADD COLUMN initial_observation_checksum TEXT")
    for (row_id,) in conn.execute("SELECT id FROM arrays ORDER BY id").fetchall():
        dtype, shape, data = conn.execute(
            "SELECT dtype, shape, data FROM arrays WHERE id = ?", (row_id,)
        ).fetchone()
        conn.execute(
            "UPDATE arrays SET checksum = ? WHERE id = ?",
            (array_checksum(dtype, shape, data), row_id),
        )
    for (row_id,) in conn.execute("SELECT id FROM skills ORDER BY id").fetchall():
        (first,) = conn.execute(
            "SELECT initial_observation FROM skills WHERE id = ?", (row_id,)
        ).fetchone()
        conn.execute(
            "UPDATE skills SET initial_observation_checksum = ? WHERE id = ?",
            (_initial_observation_checksum(first), row_id),
        )


#: ``MIGRATIONS[v]`` turns a version-``v`` database into version ``v + 1`` (inside a
#: transaction that also sets ``user_version``).
MIGRATIONS: dict[int, Callable[[sqlite3.Connection], None]] = {
    0: _migrate_0_to_1,
    1: _migrate_1_to_2,
}


# ---------------------------------------------------------------------------- helpers
class _Transaction:
    """``BEGIN ... COMMIT``, rolled back on any exception (KeyboardInterrupt included)."""

    def __init__(self, conn: sqlite3.Connection, mode: str) -> None:
        self.conn, self.mode = conn, mode

    def __enter__(self) -> None:
        self.conn.execute(f"BEGIN {self.mode}")

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc_type is None:
            self.conn.execute("COMMIT")
        elif self.conn.in_transaction:
            self.conn.execute("ROLLBACK")


class _ErrorTranslation:
    """Turns ``sqlite3`` errors into :class:`SkillDBError` naming the file and a remedy."""

    def __init__(self, path: Path, action: str) -> None:
        self.path, self.action = path, action

    def __enter__(self) -> None:
        return None

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if exc is None or not isinstance(exc, sqlite3.Error):
            return
        code = getattr(exc, "sqlite_errorname", "")
        text = str(exc)
        if code in ("SQLITE_NOTADB", "SQLITE_CORRUPT") or (
            not isinstance(exc, sqlite3.OperationalError)
            and isinstance(exc, sqlite3.DatabaseError)
            and ("not a database" in text or "malformed" in text)
        ):
            raise SkillDBError(
                f"{self.path} is not a skill database or is corrupt ({text}); restore it "
                "from a backup or delete it to start a new one"
            ) from exc
        if "locked" in text or "busy" in text:
            raise SkillDBError(
                f"cannot {self.action} {self.path}: {text} (another process holds the write "
                "lock); retry, or raise SkillDB(timeout=...)"
            ) from exc
        raise SkillDBError(f"cannot {self.action} skill database {self.path}: {text}") from exc


def _readonly_uri(path: Path) -> str:
    """SQLite's read-only URI of ``path`` (percent-encoded: ``?`` and ``#`` are data)."""
    return f"file:{urllib.parse.quote(str(path.absolute()))}?mode=ro"


def _encode(value: NDArray[Any]) -> tuple[str, str, bytes, str]:
    """``(dtype, shape, bytes, checksum)`` of an array: C order, byte order kept in the
    dtype string."""
    check_storable_array("array", value)
    data = np.ascontiguousarray(value)
    dtype, shape, raw = data.dtype.str, json.dumps(list(data.shape)), data.tobytes()
    return dtype, shape, raw, array_checksum(dtype, shape, raw)


def _decode(
    path: Path, skill_id: int, what: str, dtype: str, shape: str, data: bytes
) -> NDArray[Any]:
    try:
        dt = np.dtype(dtype)
        dims = tuple(int(d) for d in json.loads(shape))
    except (TypeError, ValueError) as exc:
        raise SkillDBError(f"skill {skill_id} in {path}: {what} has a bad dtype/shape") from exc
    if dt.kind not in SAFE_KINDS:
        raise SkillDBError(f"skill {skill_id} in {path}: {what} has unsafe dtype {dtype!r}")
    expected = dt.itemsize * math.prod(dims)
    if len(data) != expected:
        raise SkillDBError(
            f"skill {skill_id} in {path} is corrupt: {what} holds {len(data)} bytes, "
            f"{dtype}{list(dims)} needs {expected}; delete the skill or restore a backup"
        )
    return np.frombuffer(data, dtype=dt).reshape(dims).copy()


def _filters(task: str | None, success: bool | None) -> tuple[str, tuple[Any, ...]]:
    clauses: list[str] = []
    params: list[Any] = []
    if task is not None:
        clauses.append("task = ?")
        params.append(task)
    if success is not None:
        clauses.append("is_success = ?")
        params.append(int(success))
    return ((" WHERE " + " AND ".join(clauses)) if clauses else ""), tuple(params)
