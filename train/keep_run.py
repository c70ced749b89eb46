"""Keep a run of ``ias-gym robustness --json`` or ``ias-gym evaluate --json`` as a docs
result file.

Reads the run's JSON lines from stdin and writes them (robustness: every class's line;
evaluate: its last line), with the command that made them and
whether its seeds were development or held-out data, to ``--out`` (atomically; an existing
file only with ``--overwrite``). The docs build turns it into a table
(``docs/_scripts/result_tables.py``):

    ias-gym robustness --env IAS-PenRotate-Shadow-v0 --episodes 100 --seed S --workers 2 \\
        --json | python train/keep_run.py robustness --env IAS-PenRotate-Shadow-v0 --seed S \\
        --episodes 100 --set held-out --out docs/robustness_shadow.json
"""

from __future__ import annotations

import argparse
import json
import sys

from ias_gym.outputs import atomic_output, check_output_file


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("command", choices=["robustness", "evaluate"], help="the run's command")
    parser.add_argument("--env", required=True, help="the run's --env")
    parser.add_argument("--policy", default="expert", help="the run's --policy")
    parser.add_argument("--seed", type=int, required=True, help="the run's --seed")
    parser.add_argument("--episodes", type=int, required=True, help="the run's --episodes")
    parser.add_argument("--set", choices=["development", "held-out"], required=True)
    parser.add_argument("--out", required=True, help="the result file (.json)")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    args = parser.parse_args()
    out = check_output_file(args.out, overwrite=args.overwrite, suffixes=(".json",), what="--out")
    lines = [json.loads(line) for line in sys.stdin if line.strip().startswith("{")]
    if args.command == "robustness":
        rows = lines
        if not rows or rows[-1].get("disturbance") != "all":
            sys.exit("stdin: not a complete `ias-gym robustness --json` run (no summary line)")
    else:
        rows = lines[-1:]
        if not rows or rows[0].get("episodes") != args.episodes or rows[0].get("env") != args.env:
            sys.exit(
                f"stdin: not an `ias-gym evaluate --json` run of {args.env}, {args.episodes} "
                "episodes"
            )
    command = (
        f"ias-gym {args.command} --env {args.env} --policy {args.policy} "
        f"--episodes {args.episodes} --seed {args.seed} --json"
    )
    result = {
        "env": args.env,
        "policy": args.policy,
        "seed": args.seed,
        "episodes": args.episodes,
        "set": args.set,
        "command": command,
        "rows": rows,
    }
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(result, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
