"""Run every benchmark in this folder, one after another, each result kept as
``OUT/NAME.json`` (``make bench``: ``--out docs/benchmarks --overwrite``; the docs build
renders those files into the benchmarks page)."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

BENCHES = (
    "bench_internal_forces.py",
    "bench_envs.py",
    "bench_vector.py",
    "bench_controller.py",
    "bench_glove.py",
    "bench_glove_loop.py",
    "bench_glove_speed.py",
    "bench_shadow_adroit.py",
)


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--out", default="docs/benchmarks", help="folder of the result files")
    parser.add_argument("--overwrite", action="store_true", help="replace earlier results")
    parser.add_argument("--only", nargs="+", choices=BENCHES, help="run only these")
    args = parser.parse_args()
    out = Path(args.out)
    if not out.is_dir():
        parser.exit(2, f"run_all.py: --out {out} is not a folder; create it or pass another\n")
    names = args.only or BENCHES
    existing = [n for n in names if (out / n).with_suffix(".json").exists()]
    if existing and not args.overwrite:
        parser.exit(
            2, f"run_all.py: {out} has results of {', '.join(existing)}; pass --overwrite\n"
        )
    here = Path(__file__).parent
    failed = []
    for name in names:
        print(f"\n== {name}", flush=True)
        command = [
            sys.executable,
            str(here / name),
            "--json",
            str((out / name).with_suffix(".json")),
        ]
        done = subprocess.run([*command, *(["--overwrite"] if args.overwrite else [])])
        if done.returncode != 0:
            failed.append(f"{name} (exit {done.returncode})")
    if failed:
        print(f"goals missed or errors: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
