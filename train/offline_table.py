"""Collect runs of ``train/offline_rl.py`` into the offline-RL results file of the docs.

    python train/offline_table.py out/offline/*.json --out docs/offline_rl_results.json

Each input is one (dataset, algorithm) cell over its training seeds; the output keeps them
all with their commands, beside CORL's published D4RL ``pen-human-v1`` scores as a
reference row (another env and dataset: for the scale, not for comparison). The docs render
the table from it (``docs/_scripts/result_tables.py``). Refuses to replace ``--out`` without
``--overwrite``; exit 2 with one line on bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from typing import Any

#: CORL's D4RL pen-human-v1 "last scores" (normalised, mean +- std over seeds), the table of
#: its README: the reference row.
CORL_PEN_HUMAN = {
    "source": "CORL (Tarasov et al. 2023), README, D4RL Adroit, last scores",
    "dataset": "pen-human-v1",
    "normalised_score": {
        "bc": [71.03, 6.26],
        "iql": [78.49, 8.21],
        "cql": [13.71, 16.98],
        "awac": [81.12, 13.47],
    },
}
REQUIRED = ("env", "dataset_id", "algorithm", "runs", "command", "set", "eval_seeds")


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("runs", nargs="+", help="JSON files of train/offline_rl.py")
    parser.add_argument("--out", default="docs/offline_rl_results.json", help="results file")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    return parser


def collect(paths: Sequence[str]) -> dict[str, Any]:
    """The cells of ``paths`` and the reference row.

    Raises:
        InputError: a file that is not a run of ``train/offline_rl.py``, or two runs of one
            cell.
    """
    from ias_gym.errors import InputError

    cells: list[dict[str, Any]] = []
    seen: set[tuple[str, str]] = set()
    for path in paths:
        try:
            cell = json.loads(open(path).read())
        except (OSError, ValueError) as exc:
            raise InputError(f"{path}: not a readable JSON file ({exc})") from None
        if not isinstance(cell, dict) or not all(k in cell for k in REQUIRED):
            raise InputError(f"{path} is not a run of train/offline_rl.py")
        key = (cell["dataset_id"], cell["algorithm"])
        if key in seen:
            raise InputError(f"{path}: a second run of {key[1]} on {key[0]}")
        seen.add(key)
        cells.append(cell)
    return {
        "units": {
            "success_rate": "fraction of evaluation episodes with the env's is_success [0, 1]",
            "normalised_score": "100 (R - R_random) / (R_expert - R_random), R the mean return "
            "on the evaluation seeds",
        },
        "cells": cells,
        "reference": CORL_PEN_HUMAN,
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Collect and write; exit 2 with one line on bad input."""
    args = build_parser().parse_args(argv)
    from ias_gym.errors import IasGymError
    from ias_gym.outputs import atomic_output, check_output_file

    try:
        out = check_output_file(
            args.out, overwrite=args.overwrite, suffixes=(".json",), what="--out"
        )
        results = collect(args.runs)
    except IasGymError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(results, indent=1) + "\n")
    print(f"{len(results['cells'])} cells written to {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
