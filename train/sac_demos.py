"""SAC with the expert's demonstrations in its replay buffer (RLPD's symmetric sampling),
under DAgger's randomised dynamics; evaluated on the robustness suite, held-out seeds.

    python train/sac_demos.py --env IAS-PenSlide-v0 --seed 0 --max-minutes 15 \\
        --out out/sac_demos_slide.zip

What it does (:mod:`ias_gym.learning.demo_rl` has the method and its sources):

1. ``--demo-labels`` expert pairs under the training dynamics, collected as the BC
   baseline of ``train/dagger.py`` collects them (DART noise on the executed actions);
   their transitions go into every minibatch, ``--demo-fraction`` of it;
2. the actor starts as a clone of them (``--pretrain-steps`` Adam steps of Huber's loss;
   0: from scratch), the critic learns alone for ``--critic-warmup`` env steps, and the
   actor's loss then carries TD3+BC's cloning term on the demonstrations
   (``--no-cloning-term``: SAC's loss alone, which lost the pretrained policy within 5000
   steps on development seeds);
3. SAC trains on :class:`~ias_gym.learning.randomised_dynamics.RandomisedDynamicsEnv`
   (every episode new dynamics) until ``--steps`` or ``--max-minutes`` (what DAgger's run
   took, for a comparison at the same wall-clock);
4. the policy before and after the RL phase are both evaluated on every class of the
   robustness suite from ``--eval-seed`` (held out: training seeds lie below 100000).

Writes ``--out`` (SB3 zip; ``ias-gym robustness --policy FILE.zip``), ``--out`` with
``_pretrained`` before the suffix, and ``--results`` (JSON, units in the keys).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from dagger import development_curve_point, evaluate_rows, print_table
from stable_baselines3.common.callbacks import BaseCallback


def build_parser() -> argparse.ArgumentParser:
    """Command-line options."""
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--env", default="IAS-PenSlide-v0", help="a pen task")
    parser.add_argument("--seed", type=int, default=0, help="training seed")
    parser.add_argument("--out", required=True, metavar="PATH.zip", help="SAC policy to write")
    parser.add_argument(
        "--results", default=None, metavar="PATH.json", help="results JSON (default: beside --out)"
    )
    parser.add_argument("--demo-labels", type=int, default=14_000, help="expert transitions")
    parser.add_argument(
        "--expert-noise",
        type=float,
        default=0.001,
        help="noise on the expert's executed actions (DART) [normalised torque]",
    )
    parser.add_argument(
        "--demo-fraction", type=float, default=0.5, help="share of a minibatch from the demos"
    )
    parser.add_argument(
        "--pretrain-steps", type=int, default=12_000, help="Adam steps cloning the actor (0: none)"
    )
    parser.add_argument(
        "--critic-warmup", type=int, default=5_000, help="env steps before the actor moves"
    )
    parser.add_argument(
        "--no-cloning-term",
        action="store_true",
        help="SAC's actor loss alone (else TD3+BC's cloning term on the demonstrations)",
    )
    parser.add_argument(
        "--exploration-std",
        type=float,
        default=1e-3,
        help="the Gaussian noise SAC's entropy target corresponds to [normalised torque]",
    )
    parser.add_argument("--steps", type=int, default=200_000, help="env steps (at most)")
    parser.add_argument(
        "--max-minutes", type=float, default=15.0, help="stop the RL phase after this wall-clock"
    )
    parser.add_argument("--gradient-steps", type=int, default=1, help="updates per env step")
    parser.add_argument("--lr", type=float, default=3e-4, help="learning rate of SAC")
    parser.add_argument(
        "--curve-every",
        type=int,
        default=0,
        help="env steps between points of the learning curve (0: none)",
    )
    parser.add_argument(
        "--curve-episodes", type=int, default=20, help="development episodes per curve point"
    )
    parser.add_argument("--no-randomisation", action="store_true", help="nominal dynamics only")
    parser.add_argument(
        "--eval-episodes", type=int, default=50, help="held-out episodes per class (0: skip)"
    )
    parser.add_argument("--eval-seed", type=int, default=100_000, help="first held-out seed")
    parser.add_argument("--workers", type=int, default=1, help="evaluation worker processes")
    parser.add_argument("--threads", type=int, default=1, help="torch threads")
    parser.add_argument("--overwrite", action="store_true", help="replace existing outputs")
    return parser


def pretrained_path(out: Path) -> Path:
    """The zip of the actor before the RL phase: ``--out`` with ``_pretrained``."""
    return out.with_name(f"{out.stem}_pretrained{out.suffix}")


def check(args: argparse.Namespace) -> list[Path]:
    """The outputs, after checking the options (raises InputError)."""
    from ias_gym.errors import InputError
    from ias_gym.learning.expert_labelling import check_pen_task
    from ias_gym.learning.randomised_dynamics import HELD_OUT_SEED_START

    check_pen_task(args.env)
    out = Path(args.out)
    if out.suffix != ".zip":
        raise InputError(f"--out must end in .zip, got {out}")
    if args.demo_labels < 1:
        raise InputError(f"--demo-labels must be >= 1, got {args.demo_labels}")
    if not 0.0 <= args.demo_fraction <= 1.0:
        raise InputError(f"--demo-fraction must be in [0, 1], got {args.demo_fraction}")
    if not (math.isfinite(args.exploration_std) and args.exploration_std > 0):
        raise InputError(f"--exploration-std must be > 0, got {args.exploration_std}")
    if min(args.pretrain_steps, args.critic_warmup, args.steps, args.curve_every) < 0:
        raise InputError("--pretrain-steps, --critic-warmup, --steps, --curve-every must be >= 0")
    if args.max_minutes <= 0 or args.curve_episodes < 1:
        raise InputError("--max-minutes must be > 0 and --curve-episodes >= 1")
    if args.eval_episodes and args.eval_seed < HELD_OUT_SEED_START:
        raise InputError(
            f"--eval-seed must be >= {HELD_OUT_SEED_START} (training seeds lie below it)"
        )
    results = Path(args.results) if args.results else out.with_suffix(".json")
    outputs = [out, pretrained_path(out), results]
    existing = [str(p) for p in outputs if p.exists()]
    if existing and not args.overwrite:
        raise InputError(f"{', '.join(existing)} exist; pass --overwrite to replace them")
    return outputs


def main(argv: Sequence[str] | None = None) -> int:
    """Collect the demos, pretrain, run SAC, evaluate before and after, write the results."""
    args = build_parser().parse_args(argv)
    from ias_gym.errors import InputError

    try:
        out, pretrained, results_path = check(args)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    import torch
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.monitor import Monitor

    from ias_gym.learning.dagger import cloning_epochs
    from ias_gym.learning.demo_rl import (
        CriticWarmup,
        add_cloning_term,
        episode_transitions,
        make_sac,
        pretrain_actor,
    )
    from ias_gym.learning.expert_labelling import expert_dataset
    from ias_gym.learning.finetune import WallClockLimit
    from ias_gym.learning.randomised_dynamics import (
        DEFAULT_RANDOMISATION,
        NOMINAL,
        RandomisedDynamicsEnv,
    )

    torch.set_num_threads(args.threads)
    randomisation = NOMINAL if args.no_randomisation else DEFAULT_RANDOMISATION
    timings: dict[str, float] = {}
    start = time.perf_counter()
    data, episodes = expert_dataset(
        args.env,
        args.demo_labels,
        args.seed,
        randomisation=randomisation,
        expert_noise=args.expert_noise,
    )
    demos = episode_transitions(episodes)
    timings["demonstrations"] = time.perf_counter() - start

    # the agent's episodes: another run of draws than the demonstrations'
    env = Monitor(RandomisedDynamicsEnv(args.env, args.seed + RL_RUN, randomisation))
    model = make_sac(
        env,
        demos,
        seed=args.seed,
        demo_fraction=args.demo_fraction,
        exploration_std=args.exploration_std,
        gradient_steps=args.gradient_steps,
        lr=args.lr,
    )
    start = time.perf_counter()
    if args.pretrain_steps:
        epochs = cloning_epochs(len(data), 10**9, 256, args.pretrain_steps)
        pretrain_actor(model, data.observations, data.actions, epochs, seed=args.seed)
    timings["pretrain"] = time.perf_counter() - start
    out.parent.mkdir(parents=True, exist_ok=True)
    model.save(pretrained)
    if not args.no_cloning_term:
        add_cloning_term(model, data.observations, data.actions, seed=args.seed)

    curve = CurvePoints(
        args, randomisation, timings["demonstrations"] + timings["pretrain"], len(demos)
    )
    if args.curve_every:
        curve.point(model, 0)
    start = time.perf_counter()
    limit = WallClockLimit(60.0 * args.max_minutes)
    callbacks = [CriticWarmup(args.critic_warmup), limit]
    model.learn(
        total_timesteps=args.steps,
        callback=CallbackList([*callbacks, curve] if args.curve_every else callbacks),
        progress_bar=True,
    )
    timings["rl"] = time.perf_counter() - start - curve.evaluation_s
    model.save(out)
    env.close()
    print(
        f"saved {out} ({model.num_timesteps} env steps, {timings['rl']:.0f} s of RL"
        f"{', stopped by --max-minutes' if limit.stopped else ''})",
        flush=True,
    )

    evaluation: dict[str, Any] = {}
    if args.eval_episodes:
        for name, path in (("pretrained", pretrained), ("sac_demos", out)):
            evaluation[name] = evaluate_rows(
                args.env, path, args.eval_episodes, args.eval_seed, args.workers
            )
        print_table(evaluation)

    report = {
        "env": args.env,
        "learner": "sac_demos",
        "method": "SAC with demonstrations in the replay buffer (RLPD's symmetric sampling), "
        "actor pretrained by cloning, randomised dynamics",
        "train_seed": args.seed,
        "demo_labels": len(data),
        "demo_transitions": len(demos),
        "expert_noise": args.expert_noise,
        "demo_fraction": args.demo_fraction,
        "pretrain_steps": args.pretrain_steps,
        "critic_warmup_steps": args.critic_warmup,
        "cloning_term": not args.no_cloning_term,
        "exploration_std": args.exploration_std,
        "gradient_steps_per_env_step": args.gradient_steps,
        "lr": args.lr,
        "env_steps": int(model.num_timesteps),
        "stopped_by_wall_clock": limit.stopped,
        "randomisation": "nominal" if args.no_randomisation else "default",
        "development_curve": curve.points,
        "evaluation_set": "held-out",
        "evaluation_first_seed": args.eval_seed,
        "evaluation_episodes_per_class": args.eval_episodes,
        "evaluation": evaluation,
        "wall_time_s": timings,
        "torch_threads": args.threads,
    }
    results_path.parent.mkdir(parents=True, exist_ok=True)
    tmp = results_path.with_name(f".{results_path.name}.tmp")
    tmp.write_text(json.dumps(report, indent=2) + "\n")
    tmp.replace(results_path)
    print(f"wrote {results_path}")
    return 0


#: Offset of the run seed that draws the agent's training episodes (not the demos' draws).
RL_RUN = 500_000


class CurvePoints(BaseCallback):
    """Every ``--curve-every`` env steps, the deterministic policy on ``--curve-episodes``
    development episodes (``train/dagger.py``'s :func:`development_curve_point`), with the
    env steps and the training wall-clock so far (the demonstrations' steps and time and the
    pretraining's time included, these evaluations not)."""

    def __init__(
        self, args: argparse.Namespace, randomisation: Any, offset_s: float, offset_steps: int
    ) -> None:
        super().__init__()
        self.args, self.randomisation = args, randomisation
        self.offset_s, self.offset_steps, self.evaluation_s = offset_s, offset_steps, 0.0
        self.start = time.perf_counter()
        self.points: list[dict[str, Any]] = []

    def point(self, model: Any, steps: int) -> None:
        """Judge ``model`` now and record the point."""
        begin = time.perf_counter()
        rate = development_curve_point(
            self.args.env, model, self.args.seed, self.args.curve_episodes, self.randomisation
        )
        self.points.append(
            {
                "env_steps": self.offset_steps + steps,
                "wall_time_s": self.offset_s + begin - self.start - self.evaluation_s,
                **rate,
            }
        )
        self.evaluation_s += time.perf_counter() - begin
        print(f"  {steps} steps: development success {rate['success_rate']:.2f}", flush=True)

    def _on_step(self) -> bool:
        if self.num_timesteps % self.args.curve_every == 0:
            self.point(self.model, self.num_timesteps)
        return True


if __name__ == "__main__":
    sys.exit(main())
