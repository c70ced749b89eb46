"""Fit the grip-transform expert's friction floor on development persons, cross-validated.

A transferred skill's squeeze is the hand's own internal forces scaled to the demonstrated
grasp margin (:func:`~ias_gym.grasp.grasp_margin.scale_to_margin`). Near a margin of 1 a
finger may be asked for a few hundredths of a newton; on a hand whose joints have dry
friction that is below what the finger can set (its force resolution,
:func:`~ias_gym.baselines.grip_transform_terms.force_resolution`): the finger's joints stick,
it drifts off the pen and the contact opens. ``ControllerGains.friction_floor`` raises the
squeeze until every finger carries that share of its resolution (0: off; a hand without
joint friction is unchanged at any share).

Every successful glove session of each ``--db`` (development persons) is executed by the
expert on each of ``--hands``, nominal, at every share of ``--grid``. A share is chosen by the
success over all these runs (ties: the first in the grid); ``--folds`` groups of persons
cross-validate the choice (each fold's share is chosen on the other folds and judged on the
fold's persons, with a 95 % Wilson interval). Writes ``--out`` (JSON: the success of every
share per hand, the folds and the chosen share).

    python train/fit_friction_floor.py --db out/leap/dev858.db --db out/leap/dev836.db \\
        --hands leap,shadow --out out/leap/friction_floor.json
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ias_gym.baselines.grip_transform_control import ControllerGains
from ias_gym.errors import InputError
from ias_gym.outputs import atomic_output, check_output_file
from ias_gym.rates import Rate
from ias_gym.runtime.jobs import Backend, run_jobs
from ias_gym.skills import SkillDB
from ias_gym.skills.transfer import hand_names, transfer_reference
from ias_gym.skills.transfer_run import run_transfer

#: The shares searched (``--grid``).
GRID = (0.0, 0.25, 0.4, 0.5, 0.6, 0.75)


@dataclass(frozen=True)
class RunJob:
    """A picklable job: ``(db, skill id, hand) -> success at every share``."""

    grid: tuple[float, ...]

    def __call__(self, item: tuple[str, int, str]) -> list[bool]:
        db, skill_id, hand = item
        with SkillDB(db, readonly=True) as handle:
            skill = handle.get(skill_id)
        reference = transfer_reference(skill, hand)
        out = []
        for share in self.grid:
            gains = dataclasses.replace(ControllerGains(), friction_floor=share)
            run, _ = run_transfer(reference, hand, "gt", gains=gains)
            out.append(bool(run.success))
        return out


def best_share(success: np.ndarray) -> int:
    """The index of the share with the most successes (``success``: runs x shares; ties:
    the first in the grid's order)."""
    return int(np.argmax(success.sum(axis=0)))


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--db", action="append", required=True, help="development sessions")
    ap.add_argument("--hands", default="leap,shadow", help="comma-separated robot hands")
    ap.add_argument("--grid", default=",".join(map(str, GRID)), help="shares tried")
    ap.add_argument("--folds", type=int, default=5, help="groups of persons")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--out", required=True, help="the result (JSON)")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = ap.parse_args(argv)
    try:
        grid = tuple(float(v) for v in args.grid.split(","))
        hands = [h.strip() for h in args.hands.split(",")]
        unknown = sorted(set(hands) - set(hand_names()))
        if unknown:
            raise InputError(f"--hands {','.join(unknown)}: choose from {', '.join(hand_names())}")
        if args.folds < 2:
            raise InputError(f"--folds {args.folds}: at least 2")
        out = Path(args.out)
        check_output_file(out, overwrite=args.overwrite)
        items: list[tuple[str, int, str]] = []
        persons: list[str] = []
        for db in args.db:
            if not Path(db).is_file():
                raise InputError(f"--db {db} does not exist")
            with SkillDB(db, readonly=True) as handle:
                for summary in handle.list_skills(success=True):
                    for hand in hands:
                        items.append((db, summary.id, hand))
                        persons.append(str(summary.person_id))
    except (InputError, ValueError) as exc:
        print(f"fit_friction_floor.py: error: {exc}", file=sys.stderr)
        return 2
    runs = run_jobs(
        RunJob(grid), items, Backend.from_options(args.workers), desc="transfers", progress=True
    )
    success = np.array(runs, dtype=bool)  # runs x shares
    names = sorted(set(persons))
    fold_of = {p: i % args.folds for i, p in enumerate(names)}
    fold = np.array([fold_of[p] for p in persons])
    folds = []
    for k in range(args.folds):
        chosen = best_share(success[fold != k])
        mine = success[fold == k, chosen]
        folds.append({"share": grid[chosen], **Rate(int(mine.sum()), len(mine)).to_dict()})
    cv = (int(sum(f["successes"] for f in folds)), int(sum(f["trials"] for f in folds)))
    chosen = best_share(success)
    per_hand: dict[str, dict[str, dict[str, int]]] = {}
    for (_db, _skill_id, hand), row in zip(items, success, strict=True):
        per_hand.setdefault(hand, {})
        for share, ok in zip(grid, row, strict=True):
            cell = per_hand[hand].setdefault(str(share), {"successes": 0, "trials": 0})
            cell["successes"] += int(ok)
            cell["trials"] += 1
    result = {
        "set": "development",
        "dbs": args.db,
        "persons": len(names),
        "hands": hands,
        "grid": list(grid),
        "by_hand_and_share": per_hand,
        "folds": folds,
        "cross_validated": Rate(*cv).to_dict(),
        "chosen_share": grid[chosen],
    }
    with atomic_output(out) as tmp:
        Path(tmp).write_text(json.dumps(result, indent=1) + "\n")
    for hand, cells in per_hand.items():
        print(hand, {s: f"{c['successes']}/{c['trials']}" for s, c in cells.items()})
    print(f"cross-validated {Rate(*cv)}; chosen share {grid[chosen]}; wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
