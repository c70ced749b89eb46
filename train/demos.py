"""What ``train/bc.py`` and ``train/bc_ppo.py`` share: the demonstration options, the
checks before any work, and recording (optional) then loading the demonstrations from the
skill database."""

from __future__ import annotations

import argparse
from pathlib import Path
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
    parser.add_argument("--overwrite", action="store_true", help="replace existing models")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")


def check_inputs(args: argparse.Namespace, outputs: list[Path]) -> None:
    """Before any work: the env id, the model files (``.zip``, not there unless
    ``--overwrite``) and, without ``--record``, the database holds the task's demonstrations.

    Raises:
        IasGymError: the first input that cannot be used (the message names it).
    """
    from ias_gym.errors import InputError
    from ias_gym.evaluation import check_env_id
    from ias_gym.outputs import check_output_file

    check_env_id(args.env)
    if args.episodes < 1:
        raise InputError(f"--episodes must be >= 1, got {args.episodes}")
    for path in outputs:
        check_output_file(path, overwrite=args.overwrite, suffixes=(".zip",), what="model")
    if not args.record:
        from ias_gym.learning.demonstrations import load_demonstrations

        load_demonstrations(args.db, args.env, 1, source=args.source or "expert")


def inputs_refused(args: argparse.Namespace, outputs: list[Path]) -> bool:
    """:func:`check_inputs`; bad input is printed as one line on stderr (``--debug``: raised,
    with its traceback) and makes this true: the caller exits with code 2."""
    from ias_gym.cli import user_error

    try:
        check_inputs(args, outputs)
    except Exception as exc:
        return bool(user_error(exc, args.debug, prefix="error"))
    return False


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
