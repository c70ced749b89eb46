"""Behaviour cloning from a skill database into an SB3 PPO model (``FILE.zip``).

    python train/bc.py --env IAS-PenSlide-v0 --db out/slide_dart.db --record \\
        --episodes 50 --epochs 100 --out out/bc_slide.zip

``--record`` first records ``--episodes`` expert demonstrations with noise injection
(DART, ``--noise``) into ``--db``; without it the database's existing demonstrations of
the task are used (``ias-gym skills record`` stores clean ones). The saved model loads with
``ias-gym evaluate --env ID --policy FILE.zip``.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="environment id")
    parser.add_argument("--db", required=True, metavar="PATH", help="skill database")
    parser.add_argument("--out", required=True, metavar="FILE.zip", help="model to write")
    parser.add_argument(
        "--episodes", type=int, default=50, help="demonstrations to record and/or use (at most)"
    )
    parser.add_argument(
        "--record",
        action="store_true",
        help="first record --episodes noise-injected expert demonstrations into --db",
    )
    parser.add_argument(
        "--noise",
        type=float,
        default=0.001,
        help="std of the noise injected while recording [normalised torque]",
    )
    parser.add_argument(
        "--record-seed", type=int, default=0, help="reset seed of the first recorded episode"
    )
    parser.add_argument(
        "--source",
        default=None,
        help="use skills whose source starts with this (default: the recorded source, or "
        "'expert' without --record)",
    )
    parser.add_argument("--epochs", type=int, default=100, help="passes over the data")
    parser.add_argument("--batch-size", type=int, default=256, help="minibatch size")
    parser.add_argument("--lr", type=float, default=1e-3, help="initial learning rate (Adam)")
    parser.add_argument(
        "--net-arch", default="256,256", help="hidden layer sizes of actor and critic"
    )
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument(
        "--eval-episodes", type=int, default=20, help="evaluate the result (0: skip)"
    )
    parser.add_argument(
        "--eval-seed", type=int, default=1000, help="seed of the first evaluation episode"
    )
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Record (optionally), clone, save, evaluate."""
    args = build_parser().parse_args(argv)
    import gymnasium as gym
    import torch

    from ias_gym.baselines.bc import behaviour_clone, load_demonstrations, record_noisy_expert
    from ias_gym.evaluation import report

    torch.set_num_threads(args.threads)
    source = args.source
    if args.record:
        ids = record_noisy_expert(
            args.env, args.episodes, args.db, args.noise, seed=args.record_seed
        )
        print(f"recorded {len(ids)} demonstrations into {args.db}")
        if source is None:
            source = "expert" if args.noise == 0 else f"expert+noise:{args.noise:g}"
    demos = load_demonstrations(args.db, args.env, args.episodes, source=source or "expert")
    print(f"training on {len(demos.actions)} steps of demonstrations from {args.db}")
    start = time.perf_counter()
    model = behaviour_clone(
        gym.make(args.env),
        demos.observations,
        demos.actions,
        demos.returns,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        net_arch=[int(n) for n in args.net_arch.split(",")],
        seed=args.seed,
    )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    model.save(out)
    print(f"saved the cloned policy to {out} ({time.perf_counter() - start:.0f} s)")
    report(args.env, str(out), args.eval_episodes, args.eval_seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
