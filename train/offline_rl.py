"""Offline RL on a Minari dataset: one algorithm, several training seeds, one JSON.

    python train/offline_rl.py --env IAS-PenSlide-v0 --dataset-id ias/pen-slide/expert-dart-v0 \\
        --algo iql --seeds 0,1,2 --steps 10000 --eval-episodes 50 --eval-seed S \\
        --set held-out --json out/offline/penslide_iql.json

The dataset is read with ``minari.load_dataset`` (``MINARI_DATASETS_PATH``) and checked
against ``--env`` (:func:`ias_gym.learning.offline.load_offline_dataset`). For each training
seed the algorithm is trained for ``--steps`` gradient steps (``sb3_bc``, the package's own
behaviour cloning: epochs) and evaluated once on ``--eval-episodes`` episodes from
``--eval-seed``; the expert and the random policy are evaluated on the same seeds
(:mod:`ias_gym.evaluation`, as ``ias-gym evaluate``) for the normalised score (random = 0,
expert = 100). Writes the JSON atomically; refuses to replace it without ``--overwrite``.
No model file is written (d3rlpy saves by pickle). Make the dataset with
``train/bc.py --record`` and :func:`ias_gym.skills.minari_export.export_minari`
(docs/results-offline.md has the commands).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from collections.abc import Sequence
from typing import Any

SET_KINDS = ("development", "held-out")


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="environment id")
    parser.add_argument("--dataset-id", required=True, help="Minari dataset id")
    parser.add_argument(
        "--algo", required=True, choices=("bc", "iql", "cql", "sb3_bc"), help="algorithm"
    )
    parser.add_argument("--seeds", default="0,1,2", help="training seeds, comma-separated")
    parser.add_argument(
        "--steps", type=int, default=10000, help="gradient steps per run (sb3_bc: epochs)"
    )
    parser.add_argument("--eval-episodes", type=int, default=50, help="evaluation episodes")
    parser.add_argument("--eval-seed", type=int, required=True, help="first evaluation seed")
    parser.add_argument(
        "--set",
        choices=SET_KINDS,
        required=True,
        help="whether the evaluation seeds are development or held-out data",
    )
    parser.add_argument("--json", required=True, metavar="OUT.json", help="results file")
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --json")
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    return parser


def command(argv: Sequence[str]) -> str:
    """The command line that reproduces this run."""
    return " ".join(["python", "train/offline_rl.py", *argv])


def run(args: argparse.Namespace, argv: Sequence[str]) -> dict[str, Any]:
    """Load, then train and evaluate once per seed; the results as JSON-ready values."""
    from ias_gym.evaluation import evaluate_spec
    from ias_gym.learning import offline

    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    data = offline.load_offline_dataset(args.dataset_id, args.env)
    print(
        f"{args.dataset_id}: {data.episodes} episodes, {data.transitions} transitions "
        f"({data.terminated_episodes} episodes terminated)"
    )
    reference = {}
    for name in ("random", "expert"):
        summary = evaluate_spec(
            args.env, name, args.eval_episodes, seed=args.eval_seed, progress=True
        ).summary()
        reference[name] = {
            "success_rate": summary["success_rate"],
            "mean_return": summary["mean_return"],
        }
    ref = (reference["random"]["mean_return"], reference["expert"]["mean_return"])
    runs: list[dict[str, Any]] = []
    for seed in seeds:
        trained = offline.train_offline(data, args.algo, args.steps, seed, threads=args.threads)
        score = offline.evaluate_offline(
            trained.policy,
            args.env,
            args.eval_episodes,
            args.eval_seed,
            ref,
            name=f"{args.algo} seed {seed}",
        )
        print(
            f"{args.algo} seed {seed}: success {score.success_rate:.0%}, normalised score "
            f"{score.normalised_score:.1f} ({trained.seconds:.0f} s training)",
            flush=True,
        )
        runs.append(
            {
                "seed": seed,
                "gradient_steps": trained.steps,
                "train_seconds": trained.seconds,
                "success_rate": score.success_rate,
                "mean_return": score.mean_return,
                "normalised_score": score.normalised_score,
                "episode_returns": score.returns,
            }
        )
    success = offline.mean_std([r["success_rate"] for r in runs])
    normalised = offline.mean_std([r["normalised_score"] for r in runs])
    return {
        "env": args.env,
        "dataset_id": args.dataset_id,
        "dataset_episodes": data.episodes,
        "dataset_transitions": data.transitions,
        "algorithm": args.algo,
        "steps": args.steps,
        "steps_unit": "epochs" if args.algo == "sb3_bc" else "gradient steps",
        "config": trained.config,
        "set": args.set,
        "eval_seeds": [args.eval_seed, args.eval_seed + args.eval_episodes - 1],
        "eval_episodes": args.eval_episodes,
        "reference": reference,
        "runs": runs,
        "success_rate_mean": success[0],
        "success_rate_std": success[1],
        "normalised_score_mean": normalised[0],
        "normalised_score_std": normalised[1],
        "std_kind": "population standard deviation over the training seeds",
        "torch_threads": args.threads,
        "machine": f"{platform.machine()}, {platform.system()}",
        "command": command(argv),
    }


def main(argv: Sequence[str] | None = None) -> int:
    """Check the inputs, run, write the JSON; exit 2 with one line on bad input."""
    argv = list(sys.argv[1:] if argv is None else argv)
    args = build_parser().parse_args(argv)
    from ias_gym.errors import IasGymError, InputError
    from ias_gym.outputs import atomic_output, check_output_file

    try:  # before any work
        if args.steps < 1 or args.eval_episodes < 1 or args.eval_seed < 0:
            raise InputError("--steps and --eval-episodes must be >= 1, --eval-seed >= 0")
        seeds = [s for s in args.seeds.split(",") if s.strip()]
        if not seeds or not all(s.strip().isdigit() for s in seeds):
            raise InputError(f"--seeds must be non-negative integers, got {args.seeds!r}")
        out = check_output_file(
            args.json, overwrite=args.overwrite, suffixes=(".json",), what="--json"
        )
        start = time.perf_counter()
        results = run(args, argv)
    except IasGymError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    results["wall_seconds"] = time.perf_counter() - start
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        tmp.write_text(json.dumps(results, indent=1) + "\n")
    print(
        f"{args.algo} on {args.dataset_id}: success {results['success_rate_mean']:.2f} +- "
        f"{results['success_rate_std']:.2f}, normalised score "
        f"{results['normalised_score_mean']:.1f} +- {results['normalised_score_std']:.1f} "
        f"over seeds {args.seeds}; written to {out}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
