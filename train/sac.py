"""SAC from scratch (SB3) on an ``IAS-*`` task, saved as ``FILE.zip``.

    python train/sac.py --env IAS-PenSlide-v0 --steps 100000 --out out/sac_slide.zip

Actor and critics are tanh MLPs ``--net-arch`` behind a fixed observation normalisation
from random-action rollouts, as in ``train/ppo.py``; SB3's defaults otherwise (one gradient
step per environment step): nothing of the expert is used. The model loads with
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
    parser.add_argument("--out", required=True, metavar="FILE.zip", help="model to write")
    parser.add_argument("--steps", type=int, default=100_000, help="environment steps")
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument(
        "--net-arch", default="256,256", help="hidden layer sizes of actor and critic"
    )
    parser.add_argument(
        "--log-std-init",
        type=float,
        default=-3.0,
        help="initial log std of the actions before tanh (SB3's default)",
    )
    parser.add_argument("--lr", type=float, default=3e-4, help="learning rate")
    parser.add_argument("--buffer-size", type=int, default=1_000_000, help="replay buffer")
    parser.add_argument(
        "--stats-steps", type=int, default=2000, help="random steps for the normalisation"
    )
    parser.add_argument(
        "--max-minutes", type=float, default=19.0, help="stop training after this wall-clock time"
    )
    parser.add_argument("--eval-episodes", type=int, default=20, help="evaluation (0: skip)")
    parser.add_argument("--eval-seed", type=int, default=1000, help="first evaluation seed")
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument("--verbose", type=int, default=0, help="SB3 verbosity (1: statistics)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Train, save, evaluate."""
    args = build_parser().parse_args(argv)
    import torch
    from stable_baselines3 import SAC

    from ias_gym.baselines.bc import (
        GAMMA,
        WallClockLimit,
        make_vec_env,
        policy_kwargs,
        rollout_statistics,
    )
    from ias_gym.evaluation import evaluate

    torch.set_num_threads(args.threads)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    mean, std = rollout_statistics(args.env, args.stats_steps, seed=args.seed)
    env = make_vec_env(args.env, 1, seed=args.seed)
    model = SAC(
        "MlpPolicy",
        env,
        learning_rate=args.lr,
        buffer_size=args.buffer_size,
        gamma=GAMMA,
        policy_kwargs=policy_kwargs(
            mean, std, [int(n) for n in args.net_arch.split(",")], args.log_std_init
        ),
        seed=args.seed,
        device="cpu",
        verbose=args.verbose,
    )
    start = time.perf_counter()
    limit = WallClockLimit(60.0 * args.max_minutes)
    model.learn(total_timesteps=args.steps, callback=limit, progress_bar=True)
    model.save(out)
    env.close()
    stopped = ", stopped by --max-minutes" if limit.stopped else ""
    print(
        f"saved {out} ({model.num_timesteps} steps, {time.perf_counter() - start:.0f} s{stopped})"
    )
    if args.eval_episodes > 0:
        summary = evaluate(
            args.env, str(out), args.eval_episodes, seed=args.eval_seed, progress=True
        ).summary()
        print(
            f"{args.env}: success {summary['success_rate']:.0%} over {args.eval_episodes} "
            f"episodes, mean return {summary['mean_return']:.1f}"
        )
    print(f"evaluate with: ias-gym evaluate --env {args.env} --policy {out} --episodes 100")
    return 0


if __name__ == "__main__":
    sys.exit(main())
