"""Training PPO or SAC from scratch (SB3) on an ``IAS-*`` task: what ``train/ppo.py`` and
``train/sac.py`` run.

Same policy as the cloned ones (tanh MLP ``--net-arch`` behind a fixed observation
normalisation), but the normalisation comes from random-action rollouts and the weights
from SB3's initialisation: nothing of the expert is used. SAC keeps SB3's defaults
otherwise (one gradient step per environment step, one env). The model loads with
``ias-gym evaluate --env ID --policy FILE.zip``.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Sequence
from pathlib import Path


def build_parser(algo: str, description: str) -> argparse.ArgumentParser:
    """Command-line options of ``train/<algo>.py``."""
    parser = argparse.ArgumentParser(
        description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="environment id")
    parser.add_argument("--out", required=True, metavar="FILE.zip", help="model to write")
    parser.add_argument("--steps", type=int, default=100_000, help="environment steps")
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    # PPO keeps its 4 envs of before (its documented results); SAC had one.
    parser.add_argument(
        "--n-envs",
        type=int,
        default=4 if algo == "ppo" else 1,
        help="envs; more than one run batched in worker processes (ias_gym.runtime.vector_env)",
    )
    parser.add_argument(
        "--workers", type=int, default=None, help="worker processes (None: one per core)"
    )
    if algo != "ppo":
        parser.add_argument("--buffer-size", type=int, default=1_000_000, help="replay buffer")
    parser.add_argument(
        "--net-arch", default="256,256", help="hidden layer sizes of actor and critic"
    )
    parser.add_argument(
        "--log-std-init",
        type=float,
        default=-3.0,
        help="initial log std of the actions (PPO: -3 = 0.05, the size of the expert's torques; "
        "SAC: before tanh)",
    )
    parser.add_argument("--lr", type=float, default=3e-4, help="learning rate")
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
    parser.add_argument("--overwrite", action="store_true", help="replace an existing --out")
    parser.add_argument("--debug", action="store_true", help="show the traceback of an error")
    return parser


def check(args: argparse.Namespace) -> Path:
    """Before any work: the env id, the counts and the model file (``.zip``, not there unless
    ``--overwrite``); returns ``--out``.

    Raises:
        IasGymError: the first input that cannot be used (the message names it).
    """
    from ias_gym.errors import InputError
    from ias_gym.evaluation import check_env_id
    from ias_gym.outputs import check_output_file

    check_env_id(args.env)
    for name in ("steps", "n_envs", "stats_steps"):
        if getattr(args, name) < 1:
            flag = "--" + name.replace("_", "-")
            raise InputError(f"{flag} must be >= 1, got {getattr(args, name)}")
    if not (math.isfinite(args.max_minutes) and args.max_minutes > 0):
        raise InputError(f"--max-minutes must be finite and > 0, got {args.max_minutes}")
    return check_output_file(args.out, overwrite=args.overwrite, suffixes=(".zip",), what="--out")


def main(algo: str, description: str, argv: Sequence[str] | None = None) -> int:
    """Train ``algo`` ("ppo" or "sac"), save, evaluate."""
    args = build_parser(algo, description).parse_args(argv)
    from ias_gym.cli import user_error

    try:
        out = check(args)
    except Exception as exc:
        return user_error(exc, args.debug, prefix="error")
    import torch
    from stable_baselines3 import PPO, SAC

    from ias_gym.evaluation import report
    from ias_gym.learning.demonstrations import GAMMA
    from ias_gym.learning.finetune import WallClockLimit
    from ias_gym.learning.normalisation import policy_kwargs, rollout_statistics
    from ias_gym.learning.training_envs import make_training_env
    from ias_gym.outputs import atomic_output

    torch.set_num_threads(args.threads)
    mean, std = rollout_statistics(args.env, args.stats_steps, seed=args.seed)
    env = make_training_env(args.env, args.n_envs, seed=args.seed, num_workers=args.workers)
    extra = {} if algo == "ppo" else {"buffer_size": args.buffer_size}
    model = (PPO if algo == "ppo" else SAC)(
        "MlpPolicy",
        env,
        learning_rate=args.lr,
        gamma=GAMMA,
        policy_kwargs=policy_kwargs(
            mean, std, [int(n) for n in args.net_arch.split(",")], args.log_std_init
        ),
        seed=args.seed,
        device="cpu",
        verbose=args.verbose,
        **extra,
    )
    start = time.perf_counter()
    limit = WallClockLimit(60.0 * args.max_minutes)
    model.learn(total_timesteps=args.steps, callback=limit, progress_bar=True)
    seconds = time.perf_counter() - start
    with atomic_output(out, overwrite=args.overwrite) as tmp:
        model.save(tmp)
    env.close()
    stopped = ", stopped by --max-minutes" if limit.stopped else ""
    print(
        f"saved {out} ({model.num_timesteps} steps, {seconds:.0f} s, "
        f"{model.num_timesteps / seconds:.0f} steps/s with {args.n_envs} envs{stopped})"
    )
    report(args.env, str(out), args.eval_episodes, args.eval_seed)
    return 0
