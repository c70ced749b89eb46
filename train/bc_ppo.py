"""Behaviour cloning, then PPO fine-tuning of the cloned policy (SB3), saved as ``FILE.zip``.

    python train/bc_ppo.py --env IAS-PenSlide-v0 --db out/slide_dart.db --record \\
        --episodes 50 --steps 100000 --out out/bc_ppo_slide.zip

The cloned policy (:func:`ias_gym.learning.cloning.behaviour_clone`: actor fitted to the
demonstrations, exploration noise set to the cloning residual, critic fitted to the
demonstrations' returns) is saved to ``--bc-out`` first and then fine-tuned with PPO's small
steps (:func:`ias_gym.learning.finetune.fine_tune`,
:data:`~ias_gym.learning.finetune.FINE_TUNE_PPO`; the actor frozen for the first
``--critic-warmup`` steps). The deterministic policy is validated on ``--val-episodes``
held-out seeds every ``--val-freq`` steps and the best one seen (the cloned one included) is
saved to ``--out``. Both load with ``ias-gym evaluate --env ID --policy FILE.zip``.
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
    parser.add_argument("--out", required=True, metavar="FILE.zip", help="fine-tuned model")
    parser.add_argument(
        "--bc-out",
        default=None,
        metavar="FILE.zip",
        help="cloned model before fine-tuning (default: OUT with a _bc suffix)",
    )
    parser.add_argument("--bc-lr", type=float, default=1e-3, help="cloning: learning rate")
    parser.add_argument("--steps", type=int, default=100_000, help="PPO environment steps")
    parser.add_argument(
        "--n-envs",
        type=int,
        default=4,
        help="PPO envs; more than one run batched in worker processes (ias_gym.runtime.vector_env)",
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="worker processes (None: one per core)"
    )
    parser.add_argument(
        "--lr", type=float, default=None, help="PPO learning rate (default: FINE_TUNE_PPO's)"
    )
    parser.add_argument(
        "--critic-warmup", type=int, default=20_000, help="first PPO steps with the actor frozen"
    )
    parser.add_argument(
        "--max-minutes", type=float, default=19.0, help="stop PPO after this wall-clock time"
    )
    parser.add_argument(
        "--val-episodes",
        type=int,
        default=20,
        help="validation episodes for keeping the best policy (0: keep the last one)",
    )
    parser.add_argument("--val-seed", type=int, default=2000, help="first validation seed")
    parser.add_argument("--val-freq", type=int, default=20_000, help="validate every N steps")
    parser.add_argument("--verbose", type=int, default=0, help="SB3 verbosity (1: statistics)")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Record (optionally), clone, fine-tune, save, evaluate."""
    args = build_parser().parse_args(argv)
    out = Path(args.out)
    bc_out = Path(args.bc_out) if args.bc_out else out.with_name(f"{out.stem}_bc{out.suffix}")
    if inputs_refused(args, [out, bc_out]):
        return 2
    import torch

    from ias_gym.evaluation import report
    from ias_gym.learning.cloning import behaviour_clone
    from ias_gym.learning.finetune import KeepBestPolicy, WallClockLimit, fine_tune
    from ias_gym.learning.training_envs import make_training_env
    from ias_gym.outputs import atomic_output

    torch.set_num_threads(args.threads)
    demos = demonstrations(args)

    env = make_training_env(args.env, args.n_envs, seed=args.seed, num_workers=args.workers)
    start = time.perf_counter()
    model = behaviour_clone(
        env,
        demos.observations,
        demos.actions,
        demos.returns,
        epochs=args.epochs,
        lr=args.bc_lr,
        net_arch=net_arch(args),
        seed=args.seed,
        ppo_kwargs={} if args.lr is None else {"learning_rate": args.lr},
    )
    with atomic_output(bc_out, overwrite=args.overwrite) as tmp:
        model.save(tmp)
    print(f"saved the cloned policy to {bc_out} ({time.perf_counter() - start:.0f} s)")
    report(args.env, str(bc_out), args.eval_episodes, args.eval_seed, "cloned policy")

    start = time.perf_counter()
    model.verbose = args.verbose
    limit = WallClockLimit(60.0 * args.max_minutes)
    keep_best = None
    if args.val_episodes > 0:
        seeds = range(args.val_seed, args.val_seed + args.val_episodes)
        keep_best = KeepBestPolicy(args.env, seeds, args.val_freq)
    fine_tune(
        model, args.steps, critic_warmup=args.critic_warmup, callback=limit, keep_best=keep_best
    )
    if keep_best is not None:
        for steps, success, mean_return in keep_best.history:
            print(f"validation at {steps} steps: success {success:.0%}, return {mean_return:.1f}")
        print(f"keeping the policy of step {keep_best.best_steps}")
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        model.save(tmp)
    seconds = time.perf_counter() - start
    stopped = ", stopped by --max-minutes" if limit.stopped else ""
    print(
        f"saved the fine-tuned policy to {out} ({model.num_timesteps} steps, {seconds:.0f} s"
        f"{stopped})"
    )
    env.close()
    report(args.env, str(out), args.eval_episodes, args.eval_seed, "fine-tuned policy")
    return 0


if __name__ == "__main__":
    sys.exit(main())
