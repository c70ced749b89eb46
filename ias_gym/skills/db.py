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
           initial_observation_checksum (version 2), person_params (JSON, version 3))
    arrays(id INTEGER PRIMARY KEY, skill_id -> skills(id) ON DELETE CASCADE,
           part ('demo' | 'info' | 'model'), name, dtype, shape (JSON), data BLOB,
           checksum (version 2), UNIQUE(skill_id, part, name))

Where the code lives: this module opens, migrates and writes (:class:`SkillDB`);
:mod:`~ias_gym.skills.db_queries` the reads (``SkillDB``'s mixin),
:mod:`~ias_gym.skills.db_arrays` the array bytes with their checksums,
:mod:`~ias_gym.skills.db_schema` the schema version and the migrations,
:mod:`~ias_gym.skills.db_sqlite` the errors and the SQLite plumbing.
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Mapping
from datetime import datetime, timezone
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ias_gym import __version__
from ias_gym.skills.db_arrays import _encode, _initial_observation_checksum, array_checksum
from ias_gym.skills.db_queries import MAX_LISTED_IDS, SkillQueries, SkillSummary
from ias_gym.skills.db_schema import (
    APPLICATION_ID,
    CHECKSUM_VERSION,
    MIGRATIONS,
    PERSON_VERSION,
    SCHEMA_VERSION,
)
from ias_gym.skills.db_sqlite import (
    SkillDBError,
    SkillNotFoundError,
    _ErrorTranslation,
    _readonly_uri,
    _Transaction,
)
from ias_gym.skills.skill import (
    DEMO_ARRAYS,
    MODEL_ARRAYS,
    Demonstration,
    Skill,
    SkillModel,
    check_person_params,
    check_storable_array,
)

# The names other modules and the tests import from here (the code lives in db_*.py).
__all__ = [
    "APPLICATION_ID",
    "CHECKSUM_VERSION",
    "DEFAULT_TIMEOUT",
    "DEMO_ARRAYS",
    "MAX_LISTED_IDS",
    "MIGRATIONS",
    "MODEL_ARRAYS",
    "PERSON_VERSION",
    "SCHEMA_VERSION",
    "Demonstration",
    "Skill",
    "SkillDB",
    "SkillDBError",
    "SkillModel",
    "SkillNotFoundError",
    "SkillSummary",
    "array_checksum",
]

#: Seconds a connection waits for another process's write lock before failing.
DEFAULT_TIMEOUT = 30.0


# ---------------------------------------------------------------------------- the database
class SkillDB(SkillQueries):
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
                self._person_params = self._pragma("user_version") >= PERSON_VERSION
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
            _person_json(skill.person_params),
        )
        with self._errors("write"), self._transaction():
            cur = self.conn.execute(
                "INSERT INTO skills (name, task, source, person_id, created, package_version, "
                "seed, env_kwargs, is_success, episode_return, length, duration, "
                "observation_dim, initial_observation, initial_observation_checksum, "
                "person_params) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
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

    def describe(
        self,
        skill_id: int,
        *,
        infos: Mapping[str, NDArray[Any]] | None = None,
        person_params: Mapping[str, float] | None = None,
    ) -> None:
        """Add what a skill stored before lacks, in one transaction: demonstration ``infos``
        it does not have yet (an info it has is never replaced) and, where it has none, its
        person's parameters (:func:`ias_gym.skills.glove_session.describe_session` computes
        them; ``ias-gym skills migrate`` runs it).

        Raises:
            SkillNotFoundError: no skill has this id.
            ValueError: an info of the wrong length, or invalid parameters (nothing stored).
            SkillDBError: the skill has the info or the parameters already, or the database
                is read-only.
        """
        self._check_writable()
        summary = self.summary(skill_id)
        new = dict(infos or {})
        for key, value in new.items():
            check_storable_array(f"infos[{key!r}]", value)
            if len(value) != summary.length + 1:
                raise ValueError(
                    f"infos[{key!r}] must have {summary.length + 1} rows (reset + one per "
                    f"step) for skill {skill_id}, got shape {value.shape}"
                )
        if person_params is not None:
            check_person_params(person_params)
            if summary.person_params is not None:
                raise SkillDBError(f"skill {skill_id} in {self.path} has its person_params")
        encoded = [("info", key, *_encode(value)) for key, value in sorted(new.items())]
        with self._errors("write"), self._transaction():
            have = {
                r[0]
                for r in self.conn.execute(
                    "SELECT name FROM arrays WHERE skill_id = ? AND part = 'info'", (skill_id,)
                )
            }
            if have & new.keys():
                raise SkillDBError(
                    f"skill {skill_id} in {self.path} has the infos {sorted(have & new.keys())}"
                )
            self.conn.executemany(
                "INSERT INTO arrays (skill_id, part, name, dtype, shape, data, checksum) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                [(int(skill_id), *row) for row in encoded],
            )
            if person_params is not None:
                self.conn.execute(
                    "UPDATE skills SET person_params = ? WHERE id = ?",
                    (_person_json(person_params), int(skill_id)),
                )

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


def _person_json(params: Mapping[str, float] | None) -> str | None:
    """A person's parameters as stored (sorted JSON of numbers), or None."""
    if params is None:
        return None
    return json.dumps(check_person_params(params), sort_keys=True, allow_nan=False)
