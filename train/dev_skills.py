"""The development skills a transfer baseline is tuned on: the first successful session of
every skill class of the first ``n`` persons (sorted) of a glove-session database."""

from __future__ import annotations

from pathlib import Path
from typing import Any


def development_skills(db_path: str | Path, n_persons: int) -> list[Any]:
    """The skills (``SkillDB.get``), one per person and skill class, in the database's order."""
    from ias_gym.skills.db import SkillDB

    with SkillDB(Path(db_path), readonly=True) as db:
        summaries = [s for s in db.list_skills(success=True) if s.person_id]
        persons = sorted({s.person_id for s in summaries})[:n_persons]
        chosen: dict[tuple[str, str], int] = {}
        for s in summaries:
            key = (str(s.person_id), str(s.name))
            if s.person_id in persons and key not in chosen:
                chosen[key] = int(s.id)
        return [db.get(i) for i in chosen.values()]
