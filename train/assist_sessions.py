"""Where a population table's losses sit: read the sessions ``train/assist_population.py
--sessions`` kept and set two arms side by side.

Per impairment spec and drawn family, each arm's successes; then every session that one arm
wins and the other loses, with how the loser ended (where a pad came off the pen, the pose
errors against the person's unimpaired session, the lift's height). With an ablation arm
(``--without tremor`` in the table's run) beside ``assisted``, this is the trace of what one
part of the assistant saves and costs.

    python train/assist_sessions.py docs/assist_redraw_population.sessions.json \
        --arm assisted --against unassisted
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path
from typing import Any

from ias_gym.glove.impairment_spec import parse_impairment

#: What a kept session must hold (``train/assist_population.py``'s records).
KEYS = ("person", "spec", "drawn", "skill", "arm", "success")
#: How a lost session ended, in the listing.
ENDING = ("pad_off_from_s", "position_error_mm", "axis_error_deg", "lift_height_error_mm")


def load_sessions(path: str | Path) -> list[dict[str, Any]]:
    """The records of a sessions file (plain JSON: nothing executes).

    Raises:
        ValueError: the file is missing, not JSON, or not a list of session records.
    """
    p = Path(path)
    try:
        data = json.loads(p.read_text())
    except FileNotFoundError:
        raise ValueError(f"{p} does not exist (train/assist_population.py --sessions)") from None
    except (OSError, ValueError) as e:
        raise ValueError(f"{p} is not JSON: {e}") from None
    if not isinstance(data, list) or not all(
        isinstance(r, dict) and all(k in r for k in KEYS) for r in data
    ):
        raise ValueError(f"{p} is no list of session records with {', '.join(KEYS)}")
    return data


def compare(records: list[dict[str, Any]], arm: str, against: str) -> dict[str, Any]:
    """``arm`` beside ``against`` over the sessions both judged.

    Returns:
        ``{"counts": {spec: {family: {"sessions": n, arm: wins, against: wins}}},
        "won": [...], "lost": [...]}``: the sessions ``arm`` succeeds in and ``against``
        does not, and the other way round, each ``arm``'s or ``against``'s losing record.

    Raises:
        ValueError: an arm that no record has (an unknown drawn spec:
            :class:`~ias_gym.errors.InputError`, a ValueError too).
    """
    arms = {r["arm"] for r in records}
    for name in (arm, against):
        if name not in arms:
            raise ValueError(f"arm {name!r} is not in the sessions; they have {sorted(arms)}")
    pairs: dict[tuple[str, str, str], dict[str, dict[str, Any]]] = defaultdict(dict)
    for r in records:
        pairs[r["spec"], r["person"], r["skill"]][r["arm"]] = r
    counts: dict[str, dict[str, dict[str, int]]] = defaultdict(dict)
    won, lost = [], []
    for (spec, _, _), by_arm in sorted(pairs.items()):
        if arm not in by_arm or against not in by_arm:
            continue
        mine, theirs = by_arm[arm], by_arm[against]
        family = parse_impairment(str(mine["drawn"])).name
        row = counts[spec].setdefault(family, {"sessions": 0, arm: 0, against: 0})
        row["sessions"] += 1
        row[arm] += bool(mine["success"])
        row[against] += bool(theirs["success"])
        if mine["success"] and not theirs["success"]:
            won.append(theirs)
        elif theirs["success"] and not mine["success"]:
            lost.append(mine)
    return {
        "counts": {s: dict(sorted(f.items())) for s, f in counts.items()},
        "won": won,
        "lost": lost,
    }


def _ending(record: dict[str, Any]) -> str:
    def show(value: Any) -> str:
        return "-" if value is None else f"{value:.2f}" if isinstance(value, float) else str(value)

    return ", ".join(f"{k} {show(record.get(k))}" for k in ENDING)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("sessions", help="a sessions file of train/assist_population.py")
    ap.add_argument("--arm", default="assisted", help="the arm looked at")
    ap.add_argument("--against", default="unassisted", help="the arm it is set beside")
    args = ap.parse_args(argv)
    try:
        result = compare(load_sessions(args.sessions), args.arm, args.against)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    for spec, families in result["counts"].items():
        print(f"{spec}: successes of {args.arm} / {args.against} / sessions")
        for family, row in families.items():
            print(f"  {family:20s} {row[args.arm]:4d} {row[args.against]:4d} {row['sessions']:4d}")
    for title, rows, loser in (
        (f"{args.arm} succeeds, {args.against} does not", result["won"], args.against),
        (f"{args.against} succeeds, {args.arm} does not", result["lost"], args.arm),
    ):
        print(f"\n{title} ({len(rows)}; how {loser} ended):")
        for r in rows:
            print(f"  {r['spec']:14s} {r['person']} {r['skill']:12s} {r['drawn']}: {_ending(r)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
