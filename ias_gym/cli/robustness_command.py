"""``ias-gym robustness``: a policy's success rate under each class of disturbance.

:mod:`ias_gym.robustness` (gymnasium, MuJoCo) is imported when the command runs, so
``ias-gym --help`` stays fast.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from ias_gym.cli.args import (
    HelpFormatter,
    backend_from_args,
    env_kwargs_argument,
    parallel_arguments,
    parse_env_kwargs,
    policy_arguments,
)


def _robustness(args: argparse.Namespace) -> int:
    from ias_gym.robustness import check_classes, run_robustness_spec, summary_row

    classes = check_classes(None if args.classes is None else args.classes.split(","))
    backend = backend_from_args(args)  # a missing Ray extra fails before any work
    rows = run_robustness_spec(
        args.env,
        args.policy,
        episodes=args.episodes,
        seed=args.seed,
        classes=classes,
        env_kwargs=parse_env_kwargs(args.env_kwargs),
        progress=not args.json,
        trust_pickle=args.trust_pickle,
        backend=backend,
    )
    last = summary_row(rows)
    if args.json:
        for row in rows:
            print(json.dumps(row.as_json()))
        print(json.dumps(last))
        return 0
    width = max(len(r.disturbance) for r in rows)
    print(f"{'disturbance':<{width}}  success  95 % interval  episodes")
    for row in rows:
        low, high = row.rate.interval
        interval = f"[{low:.0%}, {high:.0%}]"
        rate = f"{row.success_rate:7.0%}"
        print(f"{row.disturbance:<{width}}  {rate}  {interval:>13}  {row.episodes:8d}")
    print(
        f"{'all (minimum)':<{width}}  {last['success_rate']:7.0%}  {'':>13}  {last['episodes']:8d}"
    )
    return 0


def add_robustness_command(subparsers: argparse._SubParsersAction[Any]) -> None:
    """Add ``robustness``.

    Args:
        subparsers: the object ``parser.add_subparsers(...)`` returned; the parser sets
            ``run`` (``args -> exit code``) as its default.
    """
    robustness = subparsers.add_parser(
        "robustness",
        help="a policy's success rate under each class of disturbance (pen tasks)",
        description="Evaluate a policy on the same seeds under each disturbance class of "
        "ias_gym.robustness.DISTURBANCES (pen friction and mass scaled, a push, sensor noise, "
        "action noise and delay, internal-force reference steps). With --json: one object per "
        'class, then one with "disturbance": "all" and the minimum success rate. The '
        "episodes run here, on local worker processes (--workers) or on Ray (--ray), with "
        "the same results.",
        formatter_class=HelpFormatter,
    )
    robustness.add_argument("--env", required=True, metavar="ID", help="e.g. IAS-PenRotate-v0")
    policy_arguments(
        robustness,
        episodes=100,
        episodes_help="episodes per class",
        policies="expert|random|shipped|PATH",
        policy_help="the grip-transform expert, uniform random actions, the model shipped for "
        "the env (ias_gym/assets/policies), or a saved SB3 model (.zip, loaded without "
        "running code from it)",
    )
    parallel_arguments(robustness)
    robustness.add_argument(
        "--classes",
        metavar="A,B,...",
        help="only these classes (default: all; names in ias_gym.robustness.DISTURBANCES)",
    )
    robustness.add_argument(
        "--json", action="store_true", help="one JSON object per line, the summary last"
    )
    env_kwargs_argument(robustness)
    robustness.set_defaults(run=_robustness)
