"""Tune the kinematic transfer baseline's squeeze on development persons' glove skills.

    python train/tune_kinematic.py --db out/repeats.db --persons 8 \\
        --squeezes 0.3,0.5,0.75,1,1.5,2.5 --hands all --out-json out/kinematic_tuning.json

The kinematic baseline (:class:`ias_gym.baselines.kinematic.KinematicPolicy`) has no grasp
model; its one free choice is the fixed normal force per tip. Each squeeze runs the first
successful session of every skill class of the first ``--persons`` persons of ``--db``
(development persons: never those of a held-out table) on every hand, and the script
prints per hand and squeeze the success rate of the transfer test and its three terms
(held, tracked, margin kept) with 95 % intervals. ``KinematicGains.squeeze`` is set from
this table by hand: the squeeze with the most successes on every hand, ties broken by the
lower margin error (the table goes into the CHANGELOG).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence

from dev_skills import development_skills, summarise, write_rows
from tqdm import tqdm


def main(argv: Sequence[str] | None = None) -> int:
    """Run the sweep and print the table."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--db", required=True, help="development persons' glove sessions")
    parser.add_argument("--persons", type=int, default=8, help="how many of its persons")
    parser.add_argument("--squeezes", default="0.3,0.5,0.75,1,1.5,2.5", help="[N], comma list")
    parser.add_argument("--hands", default="all", help="comma-separated hands, or all")
    parser.add_argument("--out-json", help="every run, one JSON object per line")
    args = parser.parse_args(argv)

    from ias_gym.baselines.kinematic import KinematicGains
    from ias_gym.outputs import check_output_file
    from ias_gym.skills.transfer import transfer_reference
    from ias_gym.skills.transfer_run import run_transfer
    from ias_gym.skills.workspace import hand_names

    out = None
    if args.out_json:
        out = check_output_file(args.out_json, suffixes=(".json", ".jsonl"), what="--out-json")
    hands = hand_names() if args.hands == "all" else args.hands.split(",")
    squeezes = [float(x) for x in args.squeezes.split(",")]
    skills = development_skills(args.db, args.persons)
    rows = []
    jobs = [(h, q, sk) for h in hands for q in squeezes for sk in skills]
    for hand, squeeze, skill in tqdm(jobs, desc="kinematic runs", unit="run"):
        gains = dataclasses.replace(KinematicGains(), squeeze=squeeze)
        run, _ = run_transfer(transfer_reference(skill, hand), hand, "kinematic", gains=gains)
        rows.append({**run.to_json(), "squeeze_N": squeeze})
    print(f"{len(skills)} skills of {len({s.person_id for s in skills})} persons")
    summarise(rows, hands, ["squeeze_N"])
    write_rows(out, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
