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

from demos import add_demonstration_options, demonstrations, inputs_refused, net_arch


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_demonstration_options(parser)
    parser.add_argument("--out", required=True, metavar="FILE.zip", help="model to write")
    parser.add_argument("--batch-size", type=int, default=256, help="minibatch size")
    parser.add_argument("--lr", type=float, default=1e-3, help="initial learning rate (Adam)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Record (optionally), clone, save, evaluate."""
    args = build_parser().parse_args(argv)
    out = Path(args.out)
    if inputs_refused(args, [out]):
        return 2
    import gymnasium as gym
    import torch

    from ias_gym.evaluation import report
    from ias_gym.learning.cloning import behaviour_clone
    from ias_gym.outputs import atomic_output

    torch.set_num_threads(args.threads)
    demos = demonstrations(args)
    start = time.perf_counter()
    model = behaviour_clone(
        gym.make(args.env),
        demos.observations,
        demos.actions,
        demos.returns,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        net_arch=net_arch(args),
        seed=args.seed,
    )
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        model.save(tmp)
    print(f"saved the cloned policy to {out} ({time.perf_counter() - start:.0f} s)")
    report(args.env, str(out), args.eval_episodes, args.eval_seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
