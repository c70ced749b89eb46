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
    env_kwargs_argument,
    non_negative_int,
    overwrite_argument,
    parse_env_kwargs,
    positive_int,
)


def _evaluate(args: argparse.Namespace) -> int:
    from ias_gym.evaluation import evaluate_spec

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
        description="Evaluate a policy over N seeded episodes (seeds S, S+1, ...). Task "
        "errors are printed with their unit in the name (_mm, _deg, _pct, _N).",
        formatter_class=HelpFormatter,
    )
    evaluate.add_argument("--env", required=True, metavar="ID", help="e.g. IAS-PenSlide-v0")
    evaluate.add_argument(
        "--policy",
        default="expert",
        metavar="expert|teleop|random|PATH",
        help="the grip-transform expert (pen tasks), zero action (glove envs: the glove "
        "alone drives the hand), uniform random actions, or a saved SB3 model (.zip, "
        "loaded without running code from it)",
    )
    evaluate.add_argument(
        "--trust-pickle",
        action="store_true",
        help="load a model file with SB3's own load, which unpickles it and so runs code "
        "stored in it: only for files you trust",
    )
    evaluate.add_argument(
        "--episodes", type=positive_int, default=10, metavar="N", help="number of episodes"
    )
    evaluate.add_argument(
        "--seed", type=non_negative_int, default=0, metavar="S", help="seed of the first episode"
    )
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
