"""Fit one gain of the grip-transform expert on development persons, cross-validated.

Every successful glove session of each ``--db`` (development persons) is transferred by the
expert (:func:`~ias_gym.skills.transfer_run.run_transfer`, method ``gt``) onto each of
``--hands``, under each class of ``--disturbances``, at every value of ``--grid`` for the
:class:`~ias_gym.baselines.grip_transform_control.ControllerGains` field ``--gain`` (the
other gains the hand's :func:`~ias_gym.skills.transfer_run.transfer_gains`). A value is
chosen by the success over all these runs (ties: the first in the grid); ``--folds`` groups
of persons cross-validate the choice (each fold's value is chosen on the other folds and
judged on the fold's persons, with a 95 % Wilson interval). With ``--per-hand`` each hand's
value is also chosen and cross-validated on its own runs. Writes ``--out`` (JSON: the
success of every value per hand and disturbance, the folds and the chosen value, and per
hand with ``--per-hand``).

The gains fitted so (docs/controller.md): ``friction_floor`` (the squeeze a finger with
sticking joints can set), ``ki`` (the integral of the pen's position error),
``slip_speed`` (the tips' slide that shows the pen's friction; 1 m/s: never),
``approach_speed`` (how fast a tip off the pen closes on it again), ``margin_floor`` (the
least margin a skill's squeeze is held at; 1.0: the demonstration's alone) and
``plateau_time`` (how long a tip's ratio sits at its ceiling before it reads the friction;
0: never)::

    python train/transfer_table.py --build-db dev858.db --population 30 \\
        --population-seed 858556502
    python train/transfer_table.py --build-db dev836.db --population 30 \\
        --population-seed 836632711
    python train/fit_gain.py --gain friction_floor --grid 0,0.25,0.4,0.5,0.6,0.75 \\
        --db dev858.db --db dev836.db --hands leap,shadow --out friction_floor.json
    python train/fit_gain.py --gain ki --grid 0,500,1000,2000 --db dev858.db --per-hand \\
        --hands ias4f,ias3f,shadow,leap --disturbances nominal,friction_x0.7,mass_x1.3 \\
        --out ki.json
    python train/fit_gain.py --gain slip_speed --grid 1.0,0.005 --db dev858.db --per-hand \\
        --hands ias4f,ias3f,shadow,leap \\
        --disturbances nominal,friction_x0.7,mass_x1.3,observation_noise --out slip.json
    python train/fit_gain.py --gain approach_speed --grid 0,0.01,0.03 --db dev858.db \
        --per-hand --hands ias4f,ias3f,shadow,leap \
        --disturbances nominal,friction_x0.7,mass_x1.3,observation_noise --out approach.json
    python train/fit_gain.py --gain margin_floor --grid 1.0,1.1,1.2,1.3 --db dev1268.db \
        --per-hand --hands ias4f,ias3f,shadow,leap \
        --disturbances nominal,friction_x0.7,mass_x1.3 --out margin_floor.json
    python train/fit_gain.py --gain plateau_time --grid 0,0.05,0.08 --db dev1268.db \\
        --per-hand --hands ias4f,ias3f,shadow,leap \\
        --disturbances nominal,friction_x0.7,mass_x1.3,observation_noise --out plateau.json
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
from typing import Any

import numpy as np

from ias_gym.baselines.grip_transform_control import ControllerGains
from ias_gym.errors import InputError
from ias_gym.outputs import atomic_output, check_output_file
from ias_gym.rates import Rate
from ias_gym.robustness import DISTURBANCES, check_classes
from ias_gym.runtime.jobs import Backend, run_jobs
from ias_gym.skills import SkillDB
from ias_gym.skills.transfer import transfer_reference
from ias_gym.skills.transfer_run import run_transfer, transfer_gains
from ias_gym.skills.workspace import hand_names

#: The gains this script can fit: the float fields of ``ControllerGains``.
GAINS = tuple(f.name for f in dataclasses.fields(ControllerGains) if isinstance(f.default, float))


@dataclass(frozen=True)
class RunJob:
    """A picklable job: ``(db, skill id, hand, disturbance) -> success at every value``."""

    gain: str
    grid: tuple[float, ...]

    def __call__(self, item: tuple[str, int, str, str]) -> list[bool]:
        db, skill_id, hand, disturbance = item
        with SkillDB(db, readonly=True) as handle:
            skill = handle.get(skill_id)
        reference = transfer_reference(skill, hand)
        out = []
        for value in self.grid:
            field: dict[str, Any] = {self.gain: value}
            gains = dataclasses.replace(transfer_gains(hand), **field)
            run, _ = run_transfer(reference, hand, "gt", gains=gains, **DISTURBANCES[disturbance])
            out.append(bool(run.success))
        return out


def best_value(success: np.ndarray) -> int:
    """The index of the value with the most successes (``success``: runs x values; ties:
    the first in the grid's order)."""
    return int(np.argmax(success.sum(axis=0)))


def cross_validate(
    success: np.ndarray, fold: np.ndarray, folds: int, grid: tuple[float, ...]
) -> dict[str, Any]:
    """The value chosen on all runs, and on each fold's complement judged on the fold.

    Args:
        success: runs x values; fold: ``(runs,)`` each run's group of persons.
    """
    judged: list[dict[str, Any]] = []
    for k in range(folds):
        chosen = best_value(success[fold != k])
        mine = success[fold == k, chosen]
        judged.append({"value": grid[chosen], **Rate(int(mine.sum()), len(mine)).to_dict()})
    cv = Rate(sum(int(f["successes"]) for f in judged), sum(int(f["trials"]) for f in judged))
    return {
        "folds": judged,
        "cross_validated": cv.to_dict(),
        "chosen_value": grid[best_value(success)],
    }


def parse(argv: Sequence[str] | None) -> argparse.Namespace:
    """The command line."""
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("--gain", required=True, help=f"the gain fitted: {', '.join(GAINS)}")
    ap.add_argument("--grid", required=True, help="comma-separated values tried")
    ap.add_argument("--db", action="append", required=True, help="development sessions")
    ap.add_argument("--hands", default="leap,shadow", help="comma-separated robot hands")
    ap.add_argument("--disturbances", default="nominal", help="comma-separated classes")
    ap.add_argument(
        "--per-hand", action="store_true", help="also choose (and cross-validate) per hand"
    )
    ap.add_argument("--folds", type=int, default=5, help="groups of persons")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="processes")
    ap.add_argument("--out", required=True, help="the result (JSON)")
    ap.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    return ap.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> int:
    args = parse(argv)
    try:
        if args.gain not in GAINS:
            raise InputError(f"--gain {args.gain}: choose from {', '.join(GAINS)}")
        try:
            grid = tuple(float(v) for v in args.grid.split(","))
        except ValueError:
            raise InputError(f"--grid {args.grid}: give comma-separated numbers") from None
        hands = [h.strip() for h in args.hands.split(",")]
        unknown = sorted(set(hands) - set(hand_names()))
        if unknown:
            raise InputError(f"--hands {','.join(unknown)}: choose from {', '.join(hand_names())}")
        disturbances = check_classes(args.disturbances.split(","))
        if args.folds < 2:
            raise InputError(f"--folds {args.folds}: at least 2")
        out = Path(args.out)
        check_output_file(out, overwrite=args.overwrite)
        items: list[tuple[str, int, str, str]] = []
        persons: list[str] = []
        for db in args.db:
            if not Path(db).is_file():
                raise InputError(f"--db {db} does not exist")
            with SkillDB(db, readonly=True) as handle:
                for summary in handle.list_skills(success=True):
                    for hand in hands:
                        for disturbance in disturbances:
                            items.append((db, summary.id, hand, disturbance))
                            persons.append(str(summary.person_id))
    except InputError as exc:
        print(f"fit_gain.py: error: {exc}", file=sys.stderr)
        return 2
    runs = run_jobs(
        RunJob(args.gain, grid),
        items,
        Backend.from_options(args.workers),
        desc="transfers",
        progress=True,
    )
    success = np.array(runs, dtype=bool)  # runs x values
    names = sorted(set(persons))
    fold_of = {p: i % args.folds for i, p in enumerate(names)}
    fold = np.array([fold_of[p] for p in persons])
    fit = cross_validate(success, fold, args.folds, grid)
    per_hand = {}
    if args.per_hand:
        of_hand = np.array([item[2] for item in items])
        per_hand = {
            h: cross_validate(success[of_hand == h], fold[of_hand == h], args.folds, grid)
            for h in hands
        }
    cells: dict[str, dict[str, dict[str, dict[str, int]]]] = {}
    for (_db, _skill_id, hand, disturbance), row in zip(items, success, strict=True):
        by_value = cells.setdefault(hand, {}).setdefault(disturbance, {})
        for value, ok in zip(grid, row, strict=True):
            cell = by_value.setdefault(str(value), {"successes": 0, "trials": 0})
            cell["successes"] += int(ok)
            cell["trials"] += 1
    result = {
        "set": "development",
        "gain": args.gain,
        "dbs": args.db,
        "persons": len(names),
        "hands": hands,
        "disturbances": disturbances,
        "grid": list(grid),
        "by_hand_disturbance_and_value": cells,
        **fit,
        **({"per_hand": per_hand} if args.per_hand else {}),
    }
    with atomic_output(out) as tmp:
        Path(tmp).write_text(json.dumps(result, indent=1) + "\n")
    for hand, by_disturbance in cells.items():
        for disturbance, by_value in by_disturbance.items():
            counts = {v: f"{c['successes']}/{c['trials']}" for v, c in by_value.items()}
            print(hand, disturbance, counts)
    for name, one in [*per_hand.items(), ("all hands", fit)]:
        cv = one["cross_validated"]
        rate = Rate(cv["successes"], cv["trials"])
        print(f"{name}: cross-validated {rate}; chosen {args.gain} {one['chosen_value']}")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
