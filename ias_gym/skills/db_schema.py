"""The skill database's schema: its version, its application id and the migrations.

``PRAGMA user_version`` is the schema version, ``PRAGMA application_id`` marks the file as a
skill database; :class:`~ias_gym.skills.db.SkillDB` runs :data:`MIGRATIONS` on open for
writing, each step in one transaction (the schema itself is described in
:mod:`ias_gym.skills.db`).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Callable

from ias_gym.skills.db_arrays import _initial_observation_checksum, array_checksum

#: The schema version this code writes (``PRAGMA user_version``); 2 added the checksums, 3 the
#: person's parameters.
SCHEMA_VERSION = 3
#: The first schema version with array checksums.
CHECKSUM_VERSION = 2
#: The first schema version with a skill's ``person_params`` (JSON, NULL where not known).
PERSON_VERSION = 3
#: ``PRAGMA application_id`` of a skill database: ASCII "IASS".
APPLICATION_ID = 0x49415353


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


def _migrate_2_to_3(conn: sqlite3.Connection) -> None:
    """Version 3 adds the demonstrating person's parameters (a JSON object of numbers, NULL
    where they are not known: every skill stored before; ``ias-gym skills migrate`` fills
    them in for the simulated persons' glove sessions)."""
    conn.execute("ALTER TABLE skills ADD COLUMN person_params TEXT")


#: ``MIGRATIONS[v]`` turns a version-``v`` database into version ``v + 1`` (inside a
#: transaction that also sets ``user_version``).
MIGRATIONS: dict[int, Callable[[sqlite3.Connection], None]] = {
    0: _migrate_0_to_1,
    1: _migrate_1_to_2,
    2: _migrate_2_to_3,
}
