"""``ias-gym evaluate``: run a policy on an environment and print its scores.

:mod:`ias_gym.evaluation` (gymnasium, MuJoCo) is imported when the command runs, so
``ias-gym --help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ias_gym.cli.args import (
    HelpFormatter,
    backend_from_args,
    env_kwargs_argument,
    overwrite_argument,
    parallel_arguments,
    parse_env_kwargs,
    policy_arguments,
)


def _evaluate(args: argparse.Namespace) -> int:
    from ias_gym.evaluation import evaluate_spec

    backend = backend_from_args(args)  # a missing Ray extra fails before any work
    result = evaluate_spec(
        args.env,
        policy=args.policy,
        episodes=args.episodes,
        seed=args.seed,
        video=None if args.video is None else Path(args.video),
        progress=not args.json,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        overwrite=args.overwrite,
        trust_pickle=args.trust_pickle,
        backend=backend,
    )
    summary = result.summary()
    if args.video is not None:
        summary["video"] = str(args.video)
    if args.json:
        print(json.dumps(summary))
    else:
        width = max(len(k) for k in summary)
        for key, value in summary.items():
            print(
                f"{key:<{width}}  {value:.6g}"
                if isinstance(value, float)
                else f"{key:<{width}}  {value}"
            )
    return 0


def add_evaluate_command(subparsers: argparse._SubParsersAction[Any]) -> None:
    """Add ``evaluate``.

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; the parser sets
            ``run`` (``args -> exit code``) as its default.
    """
    evaluate = subparsers.add_parser(
        "evaluate",
        help="run a policy on an environment: success rate, return, task errors",
        description="Evaluate a policy over N seeded episodes (seeds S, S+1, ...), here or "
        "on local worker processes (--workers) or Ray (--ray), with the same results. Task "
        "errors are printed with their unit in the name (_mm, _deg, _pct, _N).",
        formatter_class=HelpFormatter,
    )
    evaluate.add_argument("--env", required=True, metavar="ID", help="e.g. IAS-PenSlide-v0")
    policy_arguments(evaluate, episodes=10)
    parallel_arguments(evaluate)
    evaluate.add_argument(
        "--json", action="store_true", help="print one JSON object as the last line"
    )
    evaluate.add_argument(
        "--video",
        metavar="FILE",
        help="write an MP4 of the first episode (its directory must exist; checked first)",
    )
    overwrite_argument(evaluate)
    env_kwargs_argument(evaluate)
    evaluate.set_defaults(run=_evaluate)
