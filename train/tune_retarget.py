"""Tune the retargeting transfer baseline's press depth and servo on development persons.

    python train/transfer_table.py --build-db out/dev3141_8.db --episodes 1 \\
        --persons P1,...,P8     # the first 8 persons, sorted, of population_ids(24, 3141)
    python train/tune_retarget.py --db out/dev3141_8.db --persons 8 \\
        --depths 1,2,3,4.5,6 --omegas 100 --hands all --out-json out/retarget_tuning.json

The retargeting baseline (:class:`ias_gym.baselines.retarget.RetargetPolicy`) has no grasp
model; its free choices are how far the keypoints are pressed into the pen (``depth``, mm
here) and the joint servo's natural frequency (``omega``, rad/s; damping ratio
``--zeta``). Each pair runs the first successful session of every skill class of the first
``--persons`` persons of ``--db`` (development persons: never those of a held-out table)
on every hand, and the script prints per hand and pair the success rate of the transfer
test and its three terms (held, tracked, margin kept) with 95 % intervals, the mean RMS
position error and the mean margin error. ``DEPTH_BY_HAND`` and ``RetargetGains.omega``
are set from this table by hand (the table goes into the CHANGELOG).
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
    parser.add_argument("--depths", default="1,2,3,4.5,6", help="press depths [mm], comma list")
    parser.add_argument("--omegas", default="100", help="servo frequencies [rad/s], comma list")
    parser.add_argument("--zeta", type=float, default=1.0, help="servo damping ratio [-]")
    parser.add_argument("--hands", default="all", help="comma-separated hands, or all")
    parser.add_argument("--out-json", help="every run, one JSON object per line")
    args = parser.parse_args(argv)

    from ias_gym.baselines.retarget import RetargetGains
    from ias_gym.outputs import check_output_file
    from ias_gym.skills.transfer import transfer_reference
    from ias_gym.skills.transfer_run import run_transfer
    from ias_gym.skills.workspace import hand_names

    out = None
    if args.out_json:
        out = check_output_file(args.out_json, suffixes=(".json", ".jsonl"), what="--out-json")
    hands = hand_names() if args.hands == "all" else args.hands.split(",")
    depths = [float(x) for x in args.depths.split(",")]
    omegas = [float(x) for x in args.omegas.split(",")]
    skills = development_skills(args.db, args.persons)
    rows = []
    pairs = [(w, d) for w in omegas for d in depths]
    jobs = [(h, w, d, sk) for h in hands for w, d in pairs for sk in skills]
    for hand, omega, depth, skill in tqdm(jobs, desc="retarget runs", unit="run"):
        gains = dataclasses.replace(
            RetargetGains(), omega=omega, zeta=args.zeta, depth=depth / 1000.0
        )
        run, _ = run_transfer(transfer_reference(skill, hand), hand, "retarget", gains=gains)
        rows.append({**run.to_json(), "depth_mm": depth, "omega": omega, "zeta": args.zeta})
    print(f"{len(skills)} skills of {len({s.person_id for s in skills})} persons")
    summarise(rows, hands, ["omega", "depth_mm"])
    write_rows(out, rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
