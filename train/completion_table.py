"""Do drawn persons complete every glove skill? The population table of docs/population.md.

Draws ``--persons`` persons from the population with ``--population-seed`` (a seed no method
was tuned on makes it a held-out figure; say which with ``--set``), runs every skill once per
person unassisted with each ``--operator`` and writes

- ``OUT.json``: per operator and skill, the success rate with its 95 % Wilson interval and
  the failure reasons; and every session (person parameters included);
- ``OUT.png``: where the failures sit, each session's outcome against the person parameters
  that vary most between persons.

    python train/completion_table.py --persons 50 --population-seed 2026 --set held-out \\
        --out docs/completion_table
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
from dataclasses import asdict
from pathlib import Path

from ias_gym.glove.population import population_ids
from ias_gym.glove.skills import SKILLS
from ias_gym.rates import SET_KINDS, Rate
from ias_gym.runtime.jobs import Backend
from ias_gym.skills.completion import SessionOutcome, completion, completion_table

#: Person parameters plotted against the outcome.
PLOTTED = ("hand_scale", "range_of_motion", "amplitude", "speed", "grip_margin", "visual_delay")


def _plot(outcomes: list[SessionOutcome], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    operators = sorted({o.operator for o in outcomes})
    fig, axes = plt.subplots(
        len(operators),
        len(PLOTTED),
        figsize=(3 * len(PLOTTED), 2.6 * len(operators)),
        squeeze=False,
    )
    for row, op in enumerate(operators):
        mine = [o for o in outcomes if o.operator == op]
        for col, name in enumerate(PLOTTED):
            ax = axes[row][col]
            skills = sorted({o.skill for o in mine})
            for k, skill in enumerate(skills):
                for o in mine:
                    if o.skill != skill:
                        continue
                    ax.scatter(
                        o.params[name],
                        k,
                        c="tab:green" if o.success else "tab:red",
                        s=10 if o.success else 24,
                        marker="o" if o.success else "x",
                    )
            ax.set_yticks(
                range(len(skills)), skills if col == 0 else [""] * len(skills), fontsize=7
            )
            ax.set_xlabel(name, fontsize=8)
            if col == 0:
                ax.set_ylabel(op, fontsize=9)
    fig.suptitle("sessions by person parameter: green succeeded, red x failed", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--persons", type=int, default=50, help="persons drawn (default: %(default)s)"
    )
    parser.add_argument(
        "--population-seed", type=int, default=2026, help="seed of the draw (default: %(default)s)"
    )
    parser.add_argument(
        "--set", choices=SET_KINDS, required=True, help="development or held-out data"
    )
    parser.add_argument(
        "--operator",
        action="append",
        choices=("closed_loop", "script"),
        help="operators (default: both)",
    )
    parser.add_argument(
        "--skills", default=",".join(SKILLS), help="comma-separated skills (default: all)"
    )
    parser.add_argument(
        "--workers",
        type=int,
        default=os.cpu_count() or 1,
        help="worker processes (default: all cores)",
    )
    parser.add_argument("--out", type=Path, required=True, help="output stem: OUT.json and OUT.png")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    args = parser.parse_args(argv)
    outputs = [args.out.with_suffix(".json"), args.out.with_suffix(".png")]
    if not args.overwrite and any(p.exists() for p in outputs):
        print(f"{outputs[0]} exists; pass --overwrite to replace it", file=sys.stderr)
        return 2
    skills = [s for s in args.skills.split(",") if s]
    ids = population_ids(args.persons, args.population_seed)
    backend = Backend.from_options(args.workers)
    outcomes: list[SessionOutcome] = []
    report: dict[str, object] = {
        "set": args.set,
        "population_seed": args.population_seed,
        "persons": len(ids),
        "tables": {},
    }
    for op in args.operator or ["closed_loop", "script"]:
        mine = completion(ids, skills, op, backend=backend, progress=True)
        outcomes += mine
        table = completion_table(mine)
        report["tables"][op] = table  # type: ignore[index]
        print(
            f"\n{op} operator, {len(ids)} persons "
            f"(population seed {args.population_seed}, {args.set}):"
        )
        for skill, row in table.items():
            rate = Rate(row["successes"], row["trials"])
            fails = ", ".join(f"{k} {v}" for k, v in row["failures"].items() if v)
            print(f"  {skill:12s} {rate}  {fails}")
    report["sessions"] = [asdict(o) for o in outcomes]
    args.out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile("w", dir=args.out.parent, delete=False, suffix=".tmp") as f:
        json.dump(report, f, indent=1)
    os.chmod(f.name, 0o644)  # a temporary file is private; the table is for everyone
    os.replace(f.name, outputs[0])
    _plot(outcomes, outputs[1])
    print(f"wrote {outputs[0]} and {outputs[1]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
