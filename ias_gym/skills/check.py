"""Verifying a skill database: SQLite's integrity check, then every skill's checksums."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ias_gym.skills.db import SkillDB, SkillDBError


def check_database(path: str | Path, report: Callable[[int, str | None], None]) -> int:
    """Verify every skill of the database at ``path`` (read-only): SQLite's integrity
    check, then every array of every skill against its checksum
    (:meth:`~ias_gym.skills.db.SkillDB.check_skill`).

    Args:
        path: the database file.
        report: called per skill with its id and ``None`` (fine) or the problem found.

    Returns:
        The number of skills with a problem.

    Raises:
        SkillDBError: the file is missing, empty, not a skill database, or damaged beyond
            single skills (``PRAGMA integrity_check`` fails; the message has its findings).
    """
    bad = 0
    with SkillDB(path, readonly=True) as db:
        db.integrity_check()
        for skill_id in db.ids():
            try:
                db.check_skill(skill_id)
            except SkillDBError as exc:
                bad += 1
                report(skill_id, str(exc))
            else:
                report(skill_id, None)
    return bad
