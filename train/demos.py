"""What ``train/bc.py`` and ``train/bc_ppo.py`` share: the demonstration options, and
recording (optional) then loading the demonstrations from the skill database."""

from __future__ import annotations

import argparse
from typing import Any


def add_demonstration_options(parser: argparse.ArgumentParser) -> None:
    """``--env --db --episodes --record --noise --record-seed --source --epochs --net-arch
    --seed --eval-episodes --eval-seed --threads``."""
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="environment id")
    parser.add_argument("--db", required=True, metavar="PATH", help="skill database")
    parser.add_argument(
        "--episodes", type=int, default=50, help="demonstrations to record and/or use (at most)"
    )
    parser.add_argument(
        "--record",
        action="store_true",
        help="first record --episodes noise-injected expert demonstrations into --db",
    )
    parser.add_argument(
        "--noise", type=float, default=0.001, help="std of the injected noise [normalised torque]"
    )
    parser.add_argument("--record-seed", type=int, default=0, help="seed of the first recording")
    parser.add_argument(
        "--source",
        default=None,
        help="use skills whose source starts with this (default: the recorded source, or "
        "'expert' without --record)",
    )
    parser.add_argument("--epochs", type=int, default=100, help="cloning: passes over the data")
    parser.add_argument(
        "--net-arch", default="256,256", help="hidden layer sizes of actor and critic"
    )
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument("--eval-episodes", type=int, default=20, help="evaluation (0: skip)")
    parser.add_argument("--eval-seed", type=int, default=1000, help="first evaluation seed")
    parser.add_argument("--threads", type=int, default=1, help="torch threads")


def demonstrations(args: argparse.Namespace) -> Any:
    """Record ``--episodes`` noise-injected expert demonstrations if ``--record``, then load
    the task's demonstrations of ``--source``
    (:func:`ias_gym.learning.demonstrations.load_demonstrations`).
    """
    from ias_gym.learning.dart import record_noisy_expert
    from ias_gym.learning.demonstrations import load_demonstrations

    source = args.source
    if args.record:
        ids = record_noisy_expert(
            args.env, args.episodes, args.db, args.noise, seed=args.record_seed
        )
        print(f"recorded {len(ids)} demonstrations into {args.db}")
        if source is None:
            source = "expert" if args.noise == 0 else f"expert+noise:{args.noise:g}"
    demos = load_demonstrations(args.db, args.env, args.episodes, source=source or "expert")
    print(f"cloning {len(demos.actions)} steps of demonstrations from {args.db}")
    return demos


def net_arch(args: argparse.Namespace) -> list[int]:
    """``--net-arch`` as layer sizes."""
    return [int(n) for n in args.net_arch.split(",")]
