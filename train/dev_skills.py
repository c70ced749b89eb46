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
        persons = sorted({s.person_id or "" for s in summaries})[:n_persons]
        chosen: dict[tuple[str, str], int] = {}
        for s in summaries:
            key = (str(s.person_id), str(s.name))
            if s.person_id in persons and key not in chosen:
                chosen[key] = int(s.id)
        return [db.get(i) for i in chosen.values()]


def summarise(rows: list[dict[str, Any]], hands: list[str], setting: list[str]) -> None:
    """Print success [95 % interval], the test's terms and the mean errors per hand and
    value of the ``setting`` keys (the swept gains), over the rows of ``run.to_json()``."""
    from ias_gym.rates import Rate

    print(
        f"{'hand':<7} {' '.join(f'{k:>9}' for k in setting)}  success            held  "
        "tracked  margin kept  pos RMS  margin err"
    )
    values = sorted({tuple(r[k] for k in setting) for r in rows})
    for hand in hands:
        for value in values:
            group = [r for r in rows if r["hand"] == hand and tuple(r[k] for k in setting) == value]
            rate = Rate(sum(r["success"] for r in group), len(group))
            terms = [sum(r[k] for r in group) for k in ("held", "tracked", "margin_kept")]
            errors = [r["margin_err_rel"] for r in group if r["margin_err_rel"] is not None]
            pos = [r["pos_rms_mm"] for r in group if r["pos_rms_mm"] is not None]
            print(
                f"{hand:<7} {' '.join(f'{v:9.2f}' for v in value)}  {rate.value:4.0%} "
                f"[{rate.interval[0]:.0%}, {rate.interval[1]:.0%}]  {terms[0]:4d}  {terms[1]:7d}  "
                f"{terms[2]:11d}  {sum(pos) / max(len(pos), 1):7.2f}  "
                f"{sum(errors) / max(len(errors), 1):10.2f}"
            )


def write_rows(out: Path | None, rows: list[dict[str, Any]]) -> None:
    """Every run as one JSON line into ``out`` (atomically), if given."""
    import json

    from ias_gym.outputs import atomic_output

    if out is not None:
        with atomic_output(out) as path:
            path.write_text("".join(json.dumps(r) + "\n" for r in rows), encoding="utf-8")
