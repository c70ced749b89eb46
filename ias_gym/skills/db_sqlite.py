"""The SQLite plumbing of the skill database: its error types, a transaction that rolls back
on any exception, the translation of ``sqlite3`` errors into :class:`SkillDBError`, and the
read-only URI (split out of :mod:`ias_gym.skills.db`, which re-exports the public names)."""

from __future__ import annotations

import sqlite3
import urllib.parse
from pathlib import Path
from types import TracebackType

from ias_gym.errors import IasGymError, SkillDBError, SkillNotFoundError  # noqa: F401 - defined there, raised here


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
